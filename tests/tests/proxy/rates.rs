//! The rate limits of a token holder's requests (`proxy/src/rate.rs`, issue 49): a session's
//! duplicates tell its watchers their retained samples no faster than the watchers' queues
//! take them (item 11: every watcher stays connected and is told every copy), and a
//! participant's moves and solid changes have a rate (item 3): past it HTTP answers 429 naming
//! the limit, and the WebSocket paces the moves, losing none.

use std::collections::HashSet;
use std::time::{Duration, Instant};

use penmesh::protocol::{ClientMessage, ErrorCode, KEY_HEADER, ServerMessage, SetPlacement};
use penmesh::{Placement, Sample};
use penmesh_e2e::{
    Incoming, TestProxy, TestSession, WsClient, count_rows, draw_stroke, spawn_proxy_with,
    stroke_samples,
};
use serde_json::{Value, json};
use uuid::Uuid;

/// A done stroke of `samples` drawn by `session`'s participant, on a connection of its own.
async fn done_stroke(proxy: &TestProxy, session: &TestSession, samples: &[Sample]) -> Uuid {
    let mut ws = proxy.connect(session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    draw_stroke(&mut ws, stroke, samples, 500).await;
    stroke
}

/// A zigzag of `n` samples 6 px across: ACUTS retains every one.
fn zigzag(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let y = if i % 2 == 0 { -3.0 } else { 3.0 };
            penmesh::protocol::quantize_sample(&Sample::new(i as f64 * 1.5, y, i as f64 * 5.0, 0.5))
        })
        .collect()
}

/// The identity moved `dx` along x.
fn moved_by(dx: f64) -> Placement {
    let mut m = *Placement::IDENTITY.matrix();
    m[12] = dx;
    Placement::new(m).unwrap()
}

fn matrix_json(dx: f64) -> Value {
    json!({ "matrix": moved_by(dx).matrix() })
}

/// What a watcher saw: the strokes it holds done, its `lagged` errors, whether it was dropped.
#[derive(Debug, Default)]
struct Watched {
    done: HashSet<Uuid>,
    lagged: usize,
    dropped: bool,
}

/// Reads `ws` until it holds `n` strokes done, or it is dropped.
async fn watch(mut ws: WsClient, n: usize) -> Watched {
    let mut seen = Watched::default();
    while seen.done.len() < n {
        match ws.next_any().await {
            Incoming::Message(ServerMessage::PeerStrokeDone(done)) => {
                seen.done.insert(done.stroke);
            }
            Incoming::Message(ServerMessage::PeerStrokes(whole)) => {
                seen.done.extend(whole.strokes.iter().filter(|s| s.done).map(|s| s.stroke));
            }
            Incoming::Message(ServerMessage::Error(e)) if e.code == ErrorCode::Lagged => {
                seen.lagged += 1;
            }
            Incoming::Message(_) => {}
            Incoming::Closed(_) => {
                seen.dropped = true;
                break;
            }
        }
    }
    seen
}

/// (Item 11) A stroke that retains more than half what a watcher's queue holds, duplicated by
/// one client as fast as it can (4 at a time, each refusal tried again after its
/// `Retry-After`), while three watchers read: every watcher is told every copy, none lags or
/// is dropped. Before the rate, the copies came two to a commit, each with all its samples,
/// and the watchers lagged again and again until they were dropped.
#[tokio::test]
async fn a_sessions_duplicates_come_no_faster_than_its_watchers_take_them() {
    // A watcher's queue holds 8,192 samples, the bucket as many: one copy at a time (two do
    // not fit), a copy every 0.6 s.
    let proxy = spawn_proxy_with(|c| {
        c.outgoing_queue_bytes = 256 * 1024;
        c.duplicate_samples_per_second = 8_192;
    })
    .await;
    let session = proxy.create_session().await;
    let source = done_stroke(&proxy, &session, &zigzag(5_000)).await;
    let n_retained = proxy.stroke_info(&session, source).await["n_retained"].as_u64().unwrap();
    assert!(n_retained > 4_096, "two copies pass what a queue holds: {n_retained}");

    const COPIES: usize = 16;
    let mut watchers = Vec::new();
    for _ in 0..3 {
        let mut ws = proxy.connect(&session.stranger()).await;
        ws.hello(vec![]).await;
        watchers.push(tokio::spawn(watch(ws, COPIES + 1)));
    }

    let next = std::sync::atomic::AtomicUsize::new(0);
    let refusals = tokio::sync::Mutex::new(Vec::new());
    let duplicator = || async {
        while next.fetch_add(1, std::sync::atomic::Ordering::Relaxed) < COPIES {
            let body = json!({ "stroke": Uuid::new_v4(), "placement": matrix_json(10.0) });
            loop {
                let response = proxy
                    .http
                    .post(proxy.url(&format!("/v1/strokes/{source}/duplicate")))
                    .bearer_auth(&session.token)
                    .header(KEY_HEADER, &session.key)
                    .json(&body)
                    .send()
                    .await
                    .unwrap();
                let status = response.status().as_u16();
                if status == 201 {
                    break;
                }
                assert!(status == 429 || status == 503, "a duplicate answered {status}");
                let wait: u64 =
                    response.headers()["retry-after"].to_str().unwrap().parse().unwrap();
                let body: Value = response.json().await.unwrap();
                refusals.lock().await.push((status, body));
                tokio::time::sleep(Duration::from_secs(wait)).await;
            }
        }
    };
    tokio::join!(duplicator(), duplicator(), duplicator(), duplicator());

    for watcher in watchers {
        let seen = tokio::time::timeout(Duration::from_secs(30), watcher)
            .await
            .expect("each watcher is told every copy in time")
            .unwrap();
        assert!(!seen.dropped, "a watcher was dropped: {seen:?}");
        assert_eq!(seen.lagged, 0, "a watcher lagged: {seen:?}");
        assert_eq!(seen.done.len(), COPIES + 1, "{seen:?}");
    }
    let refusals = refusals.into_inner();
    let (_, limit) =
        refusals.iter().find(|(status, _)| *status == 429).expect("the rate refused some");
    assert_eq!(limit["error"], "too_many_requests", "{limit}");
    let message = limit["message"].as_str().unwrap();
    assert!(message.contains("--duplicate-samples-per-second"), "{message}");
    let copies = format!("SELECT COUNT(*) FROM strokes WHERE duplicate_of = '{source}'");
    assert_eq!(count_rows(&proxy.db, &copies).await, COPIES as i64);
}

/// `PUT /v1/strokes/{id}/placement` (or `…/solid`) of `stroke` as `who` with `body`.
async fn put(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: Uuid,
    what: &str,
    body: Value,
) -> reqwest::Response {
    proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/{what}")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .json(&body)
        .send()
        .await
        .unwrap()
}

/// The 429 of a refused request: its `Retry-After` is at least a second and its body names
/// `setting`.
async fn assert_limited(response: reqwest::Response, setting: &str) {
    assert_eq!(response.status(), 429);
    let wait: u64 = response.headers()["retry-after"].to_str().unwrap().parse().unwrap();
    assert!(wait >= 1, "Retry-After {wait}");
    let body: Value = response.json().await.unwrap();
    assert_eq!(body["error"], "too_many_requests", "{body}");
    assert!(body["message"].as_str().unwrap().contains(setting), "{body}");
}

/// (Item 3) A participant's moves past its burst: over HTTP 429 naming the limit, nothing
/// stored; another participant's are not held up; over the WebSocket they wait their turn and
/// every one is committed and answered. Solid changes likewise have a rate of their own.
#[tokio::test]
async fn moves_and_solid_changes_past_a_participants_rate_are_refused_or_paced() {
    let proxy = spawn_proxy_with(|c| {
        (c.move_burst, c.move_rate_per_second) = (5, 1);
        (c.solid_burst, c.solid_rate_per_second) = (2, 1);
    })
    .await;
    let session = proxy.create_session().await;
    let other = session.stranger();
    let stroke = done_stroke(&proxy, &session, &stroke_samples(200)).await;
    let theirs = done_stroke(&proxy, &other, &stroke_samples(200)).await;
    let placements =
        |s: Uuid| format!("SELECT COUNT(*) FROM stroke_placements WHERE stroke_id = '{s}'");

    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;

    // HTTP: the burst, then 429; nothing stored for the refused move.
    for i in 0..5 {
        assert_eq!(
            put(&proxy, &session, stroke, "placement", matrix_json(f64::from(i))).await.status(),
            204
        );
    }
    assert_limited(
        put(&proxy, &session, stroke, "placement", matrix_json(9.0)).await,
        "--move-rate-per-second",
    )
    .await;
    assert_eq!(count_rows(&proxy.db, &placements(stroke)).await, 5);
    // Another participant has a bucket of its own.
    assert_eq!(put(&proxy, &other, theirs, "placement", matrix_json(1.0)).await.status(), 204);

    // The WebSocket: 3 moves sent at once wait their turn (the bucket refills one a second),
    // and every one is committed and answered.
    let started = Instant::now();
    for i in 0..3 {
        let placement = moved_by(100.0 + f64::from(i));
        ws.send(&ClientMessage::SetPlacement(SetPlacement { stroke, placement })).await;
    }
    let mut answered = 0;
    while answered < 3 {
        match ws.recv_any().await {
            // (Not the HTTP moves', told to this connection of the drawer too.)
            ServerMessage::PeerPlacement(answer) if answer.placement.matrix()[12] >= 100.0 => {
                answered += 1
            }
            ServerMessage::Error(e) => panic!("a move was refused: {e:?}"),
            _ => {}
        }
    }
    let paced = started.elapsed();
    assert!(paced >= Duration::from_millis(2_000), "3 moves answered in {paced:?}: not paced");
    assert_eq!(count_rows(&proxy.db, &placements(stroke)).await, 5 + 3);

    // Solids: a burst of 2, then 429 naming their own limit.
    let filled = json!({ "kind": "line", "depth": 8.0 });
    for _ in 0..2 {
        assert_eq!(put(&proxy, &session, stroke, "solid", filled.clone()).await.status(), 200);
    }
    assert_limited(put(&proxy, &session, stroke, "solid", filled).await, "--solid-rate-per-second")
        .await;
}
