use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage, StrokeStatus,
};
use penmesh_e2e::{
    assemble_retained, batch_simplified, spawn_proxy, spawn_proxy_with, stroke_samples,
};
use uuid::Uuid;

#[tokio::test]
async fn a_dropped_connection_resumes_with_no_duplicate_and_no_loss() {
    // Arrange: 100 samples acked, 50 more sent without waiting, then the connection drops.
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(300);
    let stroke = Uuid::new_v4();
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    let mut pieces = ws.wait_ack(stroke, 0).await;
    for seq in (0..100).step_by(10) {
        ws.points(stroke, seq as u64, &samples[seq..seq + 10]).await;
    }
    pieces.extend(ws.wait_ack(stroke, 100).await);
    for seq in (100..150).step_by(10) {
        ws.points(stroke, seq as u64, &samples[seq..seq + 10]).await;
    }
    drop(ws);

    // Act: reconnect and resume.
    let mut ws = proxy.connect(&session).await;
    let welcome = ws.hello(vec![stroke]).await;
    assert_eq!(welcome.resume.len(), 1);
    let state = &welcome.resume[0];
    assert_eq!(state.stroke, stroke);
    assert_eq!(state.status, StrokeStatus::Open);
    let next = state.next_seq as usize;
    assert!((100..=150).contains(&next), "resumes from {next}");
    // Resend from a bit before `next` (a client that lost its acks): the overlap is ignored.
    let from = next - 5;
    for start in (from..300).step_by(20) {
        let end = (start + 20).min(300);
        ws.points(stroke, start as u64, &samples[start..end]).await;
    }
    ws.end(stroke, 300).await;
    let (done, others) = ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;

    // Assert
    for msg in &others {
        if let ServerMessage::Retained(r) = msg {
            pieces.push((r.first, r.points.0.clone()));
        }
        assert!(!matches!(msg, ServerMessage::Error(_)), "{msg:?}");
    }
    let expected = batch_simplified(&samples);
    assert_eq!(assemble_retained(&pieces), expected);
    let ServerMessage::StrokeDone(done) = done else { unreachable!() };
    assert_eq!(done.n_retained, expected.len() as u64);
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
    let stored = proxy.get_json(&format!("/v1/strokes/{stroke}/simplified"), &session).await;
    let stored: Vec<penmesh::Sample> = serde_json::from_value(stored["samples"].clone()).unwrap();
    assert_eq!(stored, expected);
}

#[tokio::test]
async fn a_dropped_stroke_is_interrupted_and_resumable_by_stroke_begin() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(40);
    let stroke = Uuid::new_v4();
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    ws.points(stroke, 0, &samples[..20]).await;
    ws.wait_ack(stroke, 20).await;
    drop(ws);
    // The old connection's end is noticed and the stroke marked interrupted.
    let mut status = String::new();
    for _ in 0..50 {
        status = proxy.stroke_info(&session, stroke).await["status"].as_str().unwrap().to_string();
        if status == "interrupted" {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    assert_eq!(status, "interrupted");

    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    ws.wait_ack(stroke, 20).await;
    ws.points(stroke, 20, &samples[20..]).await;
    ws.end(stroke, 40).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
}

#[tokio::test]
async fn resume_reports_unknown_done_and_foreign_strokes_without_revealing_them() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let other = proxy.create_session().await;
    let samples = stroke_samples(10);
    let (done_stroke, foreign_stroke, unknown) = (Uuid::new_v4(), Uuid::new_v4(), Uuid::new_v4());
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    penmesh_e2e::draw_stroke(&mut ws, done_stroke, &samples, 5).await;
    let mut ws_other = proxy.connect(&other).await;
    ws_other.hello(vec![]).await;
    ws_other.begin(foreign_stroke).await;
    ws_other.wait_ack(foreign_stroke, 0).await;

    let mut ws = proxy.connect(&session).await;
    let welcome = ws.hello(vec![done_stroke, foreign_stroke, unknown]).await;
    let status: Vec<_> = welcome.resume.iter().map(|r| (r.stroke, r.status, r.next_seq)).collect();
    assert_eq!(
        status,
        vec![
            (done_stroke, StrokeStatus::Done, 10),
            (foreign_stroke, StrokeStatus::Unknown, 0),
            (unknown, StrokeStatus::Unknown, 0),
        ]
    );
}

#[tokio::test]
async fn a_resent_batch_is_acked_again_and_stored_once() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(30);
    let stroke = Uuid::new_v4();
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    ws.points(stroke, 0, &samples[..10]).await;
    ws.wait_ack(stroke, 10).await;
    ws.points(stroke, 0, &samples[..10]).await;
    ws.wait_ack(stroke, 10).await;
    ws.points(stroke, 10, &samples[10..]).await;
    ws.wait_ack(stroke, 30).await;
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
    // Stored once: the chunk rows hold each sample at most once, and so do the log entries
    // (a sample moved into a chunk stays in its log record until the record is deleted).
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&proxy.db.url).await.unwrap();
    let (chunks, log) = penmesh_e2e::penmesh_proxy::stored_pieces(&pool, stroke).await.unwrap();
    pool.close().await;
    let total = |pieces: &[(u64, u64)]| pieces.iter().map(|p| p.1).sum::<u64>();
    assert!(total(&chunks) <= 30 && total(&log) <= 30, "chunks {chunks:?}, log {log:?}");
    assert!(total(&chunks) == 30 || total(&log) == 30, "chunks {chunks:?}, log {log:?}");
}

/// A client that vanished without a FIN (it reads and answers nothing, its socket stays open):
/// the heartbeat takes it for gone and lets go of its stroke, so the same person's resume on a
/// new connection is granted within the claim wait instead of refused until the idle timeout.
/// The control case, with a heartbeat longer than the claim wait, is refused.
#[tokio::test]
async fn a_vanished_client_lets_go_of_its_stroke_within_the_heartbeat() {
    for (heartbeat_ms, granted) in [(300, true), (60_000, false)] {
        let proxy = spawn_proxy_with(|c| {
            c.heartbeat_ms = heartbeat_ms;
            c.claim_wait_ms = 2_000;
        })
        .await;
        let session = proxy.create_session().await;
        let stroke = Uuid::new_v4();
        let mut vanished = proxy.drawing(&session, stroke).await;
        vanished.points(stroke, 0, &stroke_samples(10)).await;
        vanished.wait_ack(stroke, 10).await;

        let mut back = proxy.connect(&session).await;
        back.send(&ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-e2e".into(),
            name: None,
            resume: vec![stroke],
            key: Some(session.key.clone()),
        }))
        .await;
        let mut refused = false;
        let welcome = loop {
            match back.recv().await {
                ServerMessage::Welcome(welcome) => break welcome,
                ServerMessage::Error(e) if e.code == ErrorCode::StrokeConflict => refused = true,
                other => panic!("heartbeat {heartbeat_ms} ms: {other:?}"),
            }
        };
        let state = &welcome.resume[0];
        assert_eq!(refused, !granted, "heartbeat {heartbeat_ms} ms: {welcome:?}");
        assert_eq!((state.status, state.next_seq), (StrokeStatus::Open, 10));
        drop(vanished);
    }
}
