//! The cost of a move (`docs/performance.md`, "Moving a stroke"), ignored: run it with
//!
//! ```text
//! cargo test -p penmesh-e2e --test sessions -- --ignored --nocapture move_latency
//! PENMESH_TEST_POSTGRES_URL=postgres://postgres@127.0.0.1:5432/test \
//!     cargo test -p penmesh-e2e --test sessions -- --ignored --nocapture move_latency
//! ```
//!
//! The drawer moves its stroke 100 times at a gizmo's pace (one `SetPlacement` every 16 ms);
//! a watcher (on the other replica with PostgreSQL) times each `PeerPlacement` from the send
//! of its `SetPlacement`, and counts the bytes of each frame on the wire.

use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use penmesh::Placement;
use penmesh::protocol::{ClientMessage, ServerMessage, SetPlacement, decode_server, encode_client};
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

use crate::helpers::{Participant, one_or_two_replicas, samples_for};

const MOVES: usize = 100;
const PACE: Duration = Duration::from_millis(16);

/// Move `i`: a turn about z by `i` degrees and a shift of `i` along x (the shift tells the
/// moves apart).
fn move_number(i: usize) -> Placement {
    let (s, c) = (i as f64).to_radians().sin_cos();
    Placement::new([c, s, 0.0, 0.0, -s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, i as f64, 0.5, 3.0, 1.0])
        .unwrap()
}

/// WebSocket framing of a frame of `n` payload bytes: 2 header bytes (up to 125), 4 more for
/// the client's mask.
fn on_the_wire(n: usize, masked: bool) -> usize {
    let header = if n <= 125 {
        2
    } else if n <= 65535 {
        4
    } else {
        10
    };
    n + header + if masked { 4 } else { 0 }
}

#[tokio::test]
#[ignore = "a measurement: run it on demand, see docs/performance.md"]
async fn move_latency() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let stroke = Uuid::new_v4();
    drawer.draw(stroke, &samples_for(0, 100), 16).await;
    watcher.wait_for(|v| v.strokes.get(&stroke).is_some_and(|s| s.done)).await;

    let watching = tokio::spawn(async move {
        let mut arrived = Vec::with_capacity(MOVES);
        while arrived.len() < MOVES {
            let frame = tokio::time::timeout(Duration::from_secs(10), watcher.ws.ws.next())
                .await
                .expect("a move in time")
                .unwrap()
                .unwrap();
            let Message::Binary(bytes) = frame else { continue };
            if let ServerMessage::PeerPlacement(p) = decode_server(&bytes, usize::MAX).unwrap() {
                arrived.push((p.placement.matrix()[12] as usize, Instant::now(), bytes.len()));
            }
        }
        arrived
    });
    let mut sent = Vec::with_capacity(MOVES);
    let mut up_bytes = 0;
    let mut tick = tokio::time::interval(PACE);
    for i in 0..MOVES {
        tick.tick().await;
        let frame = encode_client(&ClientMessage::SetPlacement(SetPlacement {
            stroke,
            placement: move_number(i),
        }));
        up_bytes = frame.len();
        sent.push(Instant::now());
        drawer.ws.ws.send(Message::Binary(frame.into())).await.unwrap();
    }
    let arrived = watching.await.unwrap();
    let mut latencies: Vec<f64> = arrived
        .iter()
        .map(|(i, at, _)| at.duration_since(sent[*i]).as_secs_f64() * 1000.0)
        .collect();
    latencies.sort_by(f64::total_cmp);
    let at = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
    let down_bytes = arrived[0].2;
    let setup = if proxies.len() == 2 {
        "two replicas (PostgreSQL), across"
    } else {
        "one replica (SQLite)"
    };
    println!(
        "{setup}: {MOVES} moves, latency p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms; \
         set_placement {up_bytes} B (+framing: {} B on the wire), \
         peer_placement {down_bytes} B ({} B on the wire)",
        at(0.5),
        at(0.99),
        latencies[latencies.len() - 1],
        on_the_wire(up_bytes, true),
        on_the_wire(down_bytes, false),
    );
    assert_eq!(arrived.len(), MOVES);
    assert!(on_the_wire(down_bytes, false) <= 200 && on_the_wire(up_bytes, true) <= 200);
    assert!(at(0.99) <= 200.0, "p99 {} ms", at(0.99));
}
