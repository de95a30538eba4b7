//! A reader that stops reading: the proxy keeps a bounded number of frames, and of bytes, for
//! it, then cuts it off with `lagged` and resyncs it from storage, while the others go on
//! undisturbed.

use futures_util::StreamExt;
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage, decode_server, encode_client,
};
use penmesh_e2e::{TIMEOUT, TestProxy, TestSession, spawn_proxy_with};
use penmesh_proxy::Frame;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio_util::sync::PollSender;
use uuid::Uuid;

use crate::helpers::{Participant, View, expected_view, samples_for};

const QUEUE: usize = 64;

/// A participant that says hello and then reads nothing: its socket side is a channel that
/// nobody reads (the real connection loop, with no TCP buffers to hide the backlog). Returns
/// what the client sends on, what it would read, and the connection's task.
pub(crate) async fn join_slow_reader(
    proxy: &TestProxy,
    session: &TestSession,
) -> (mpsc::Sender<Frame>, mpsc::Receiver<Frame>, JoinHandle<()>) {
    let guard = proxy.state.join_session(session.session).expect("room in the session");
    let (to_server, from_client) = mpsc::channel::<Frame>(4);
    let (to_client, from_server) = mpsc::channel::<Frame>(1);
    let stream = futures_util::stream::unfold(from_client, |mut rx| async move {
        rx.recv().await.map(|f| (Ok::<_, std::convert::Infallible>(f), rx))
    })
    .boxed();
    let slow = tokio::spawn(penmesh_proxy::serve(
        proxy.state.clone(),
        session.session,
        guard,
        PollSender::new(to_client),
        stream,
    ));
    let hello = ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: "slow".into(),
        name: Some("slow".into()),
        resume: vec![],
        key: None,
    });
    to_server.send(Frame::Binary(encode_client(&hello))).await.unwrap();
    (to_server, from_server, slow)
}

#[tokio::test]
async fn a_slow_reader_is_cut_off_with_lagged_and_resynced_while_the_others_keep_up() {
    // Arrange: a fast reader, a drawer, and a slow reader.
    let proxy = spawn_proxy_with(|c| c.outgoing_queue = QUEUE).await;
    let session = proxy.create_session().await;
    let mut fast = Participant::join(&proxy, &session, "fast").await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let (to_server, mut from_server, slow) = join_slow_reader(&proxy, &session).await;

    // Act: far more events than the slow reader's queues hold; the fast reader reads along.
    const STROKES: usize = 20;
    let strokes: Vec<_> = (0..STROKES).map(|k| (Uuid::new_v4(), samples_for(k, 200))).collect();
    let mut n_fast_events = 0;
    tokio::join!(
        async {
            for (stroke, samples) in &strokes {
                // Paced: a batch per event, enough events to overflow the slow reader.
                drawer.draw_paced(*stroke, samples, 4).await;
            }
        },
        async {
            while fast.view.n_done() < STROKES {
                if is_peer_event(&fast.recv().await) {
                    n_fast_events += 1;
                }
            }
        }
    );

    // Assert: the fast reader got everything while the slow one read nothing, and the proxy
    // kept no more than its queue bound of frames for the slow one.
    assert!(n_fast_events > 4 * QUEUE, "only {n_fast_events} events: not enough to overflow");
    let (backlog, capacity) = proxy.state.fanout.backlog(session.session);
    assert!(backlog <= capacity && capacity <= QUEUE, "fan-out backlog {backlog} of {capacity}");
    let mut view = View::default();
    let mut before_lagged = 0;
    loop {
        let msg = next_message(&mut from_server).await;
        view.apply(&msg);
        if matches!(&msg, ServerMessage::Error(e) if e.code == ErrorCode::Lagged) {
            break;
        }
        before_lagged += 1;
    }
    assert!(
        before_lagged <= QUEUE + 4,
        "{before_lagged} frames were kept for a reader that read nothing (queue {QUEUE})"
    );
    // The resync brings what it lacks, with no repeat (the view checks), then `Synced`.
    while view.n_done() < STROKES || view.n_synced < 2 {
        let msg = next_message(&mut from_server).await;
        view.apply(&msg);
    }
    assert_eq!(view.n_lagged, 1);
    let expected = expected_view(&strokes, &[]);
    for (id, (samples, done, _)) in &expected {
        assert_eq!(&view.strokes[id].retained, samples);
        assert!(*done && view.strokes[id].done);
    }
    drop(to_server);
    tokio::time::timeout(TIMEOUT, slow).await.expect("the slow connection ends").unwrap();
}

const QUEUE_BYTES: usize = 64 * 1024;

/// The frames a watcher does not read are bounded in bytes too, not only in number: a watcher
/// that reads nothing while every sample of the strokes it watches is retained (far fewer
/// frames than `--outgoing-queue`, far more bytes than `--outgoing-queue-bytes`) is cut off
/// with `lagged` once the bytes are queued, then resynced with everything; what the drawer
/// was acknowledged is stored.
#[tokio::test]
async fn a_watcher_that_never_reads_holds_no_more_than_the_outgoing_bytes() {
    let proxy = spawn_proxy_with(|c| c.outgoing_queue_bytes = QUEUE_BYTES).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let (to_server, mut from_server, slow) = join_slow_reader(&proxy, &session).await;

    // About 85 KB of frames (a third more than the bound) in 400 frames.
    const STROKES: usize = 100;
    let strokes: Vec<_> = (0..STROKES).map(|k| (Uuid::new_v4(), zigzag(k, 400))).collect();
    for (stroke, samples) in &strokes {
        drawer.draw(*stroke, samples, 200).await;
    }

    // What was queued for the watcher before `lagged`: the queue's bytes and one frame more,
    // the frame its socket took (the channel holds one) and the one on its way there.
    let mut view = View::default();
    let (mut bytes, mut n_frames, mut largest) = (0, 0, 0);
    loop {
        let (size, msg) = next_sized(&mut from_server).await;
        view.apply(&msg);
        if matches!(&msg, ServerMessage::Error(e) if e.code == ErrorCode::Lagged) {
            break;
        }
        assert!(
            view.n_done() < STROKES,
            "{n_frames} frames of {bytes} bytes, every stroke, and no `lagged`: all kept"
        );
        (bytes, n_frames, largest) = (bytes + size, n_frames + 1, largest.max(size));
    }
    assert!(
        bytes <= QUEUE_BYTES + 3 * largest,
        "{n_frames} frames of {bytes} bytes (the largest {largest}) were kept for a watcher that \
         read nothing (bound {QUEUE_BYTES} bytes)"
    );
    // The resync brings what it lacks, with no repeat (the view checks), then `Synced`. (The
    // events that came while it waited for the watcher may have lagged once more.)
    while view.n_done() < STROKES || view.n_synced < 1 + view.n_lagged {
        let msg = next_message(&mut from_server).await;
        view.apply(&msg);
    }
    for (id, (samples, done, _)) in &expected_view(&strokes, &[]) {
        assert_eq!(&view.strokes[id].retained, samples);
        assert!(*done && view.strokes[id].done);
    }
    for (stroke, samples) in &strokes {
        assert_eq!(&proxy.raw_samples(&session, *stroke).await, samples);
    }
    drop(to_server);
    tokio::time::timeout(TIMEOUT, slow).await.expect("the slow connection ends").unwrap();
}

/// Stroke number `k` as a zigzag on the codec's grid: ACUTS retains every sample.
fn zigzag(k: usize, n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let y = if i % 2 == 0 { 0.0 } else { 50.0 };
            Sample::new(1000.0 * k as f64 + 4.0 * i as f64, y, i as f64, 0.5)
        })
        .collect()
}

fn is_peer_event(msg: &ServerMessage) -> bool {
    matches!(
        msg,
        ServerMessage::PeerStrokeBegin(_)
            | ServerMessage::PeerRetained(_)
            | ServerMessage::PeerStrokeDone(_)
            | ServerMessage::PeerStrokes(_)
    )
}

pub(crate) async fn next_message(rx: &mut mpsc::Receiver<Frame>) -> ServerMessage {
    next_sized(rx).await.1
}

/// The next message and the size of its frame.
async fn next_sized(rx: &mut mpsc::Receiver<Frame>) -> (usize, ServerMessage) {
    loop {
        match tokio::time::timeout(TIMEOUT, rx.recv()).await.expect("a frame in time") {
            Some(Frame::Binary(bytes)) => {
                return (bytes.len(), decode_server(&bytes, usize::MAX).unwrap());
            }
            // The heartbeat of a connection that has been silent: not a protocol message.
            Some(Frame::Ping(_)) => continue,
            other => panic!("expected a binary frame, got {other:?}"),
        }
    }
}
