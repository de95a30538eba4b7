//! A reader that stops reading: the proxy keeps a bounded number of frames for it, then cuts
//! it off with `lagged` and resyncs it from storage, while the others go on undisturbed.

use futures_util::StreamExt;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage, decode_server, encode_client,
};
use penmesh_e2e::{TIMEOUT, spawn_proxy_with};
use penmesh_proxy::Frame;
use tokio::sync::mpsc;
use tokio_util::sync::PollSender;
use uuid::Uuid;

use crate::helpers::{Participant, View, expected_view, samples_for};

const QUEUE: usize = 64;

#[tokio::test]
async fn a_slow_reader_is_cut_off_with_lagged_and_resynced_while_the_others_keep_up() {
    // Arrange: a fast reader, a drawer, and a slow reader whose socket side is a channel that
    // nobody reads (the real connection loop, with no TCP buffers to hide the backlog).
    let proxy = spawn_proxy_with(|c| c.outgoing_queue = QUEUE).await;
    let session = proxy.create_session().await;
    let mut fast = Participant::join(&proxy, &session, "fast").await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let guard = proxy.state.join_session(session.session).expect("room in the session");
    let (to_server, from_client) = mpsc::channel::<Frame>(4);
    let (to_client, mut from_server) = mpsc::channel::<Frame>(1);
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

    // Act: far more events than the slow reader's queues hold; the fast reader reads along.
    const STROKES: usize = 20;
    let strokes: Vec<_> = (0..STROKES).map(|k| (Uuid::new_v4(), samples_for(k, 200))).collect();
    let mut n_fast_events = 0;
    tokio::join!(
        async {
            for (stroke, samples) in &strokes {
                drawer.draw(*stroke, samples, 4).await;
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

fn is_peer_event(msg: &ServerMessage) -> bool {
    matches!(
        msg,
        ServerMessage::PeerStrokeBegin(_)
            | ServerMessage::PeerRetained(_)
            | ServerMessage::PeerStrokeDone(_)
    )
}

async fn next_message(rx: &mut mpsc::Receiver<Frame>) -> ServerMessage {
    loop {
        match tokio::time::timeout(TIMEOUT, rx.recv()).await.expect("a frame in time") {
            Some(Frame::Binary(bytes)) => return decode_server(&bytes, usize::MAX).unwrap(),
            // The heartbeat of a connection that has been silent: not a protocol message.
            Some(Frame::Ping(_)) => continue,
            other => panic!("expected a binary frame, got {other:?}"),
        }
    }
}
