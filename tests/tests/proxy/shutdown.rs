use axum::body::Body;
use axum::http::Request;
use penmesh::protocol::{ErrorCode, ServerMessage};
use penmesh_e2e::{
    TestDatabase, count_rows, spawn_proxy, spawn_proxy_on, stroke_samples, test_config,
};
use tower::ServiceExt;
use uuid::Uuid;

#[tokio::test]
async fn shutdown_keeps_every_acknowledged_sample_and_closes_with_1001() {
    // Arrange: one stroke with everything acked, one still streaming when shutdown comes.
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(400);
    let (calm, busy) = (Uuid::new_v4(), Uuid::new_v4());
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(calm).await;
    ws.points(calm, 0, &samples[..100]).await;
    ws.wait_ack(calm, 100).await;
    let mut ws2 = proxy.connect(&session).await;
    ws2.hello(vec![]).await;
    ws2.begin(busy).await;
    ws2.points(busy, 0, &samples[..10]).await;
    ws2.wait_ack(busy, 10).await;
    for seq in (10..400).step_by(10) {
        ws2.points(busy, seq as u64, &samples[seq..seq + 10]).await;
    }

    // Act
    proxy.trigger_shutdown();
    ws.expect_error(ErrorCode::ShuttingDown).await;
    assert_eq!(ws.expect_close().await, Some(1001));
    let mut acked_busy = 10;
    loop {
        match ws2.next().await {
            penmesh_e2e::Incoming::Message(ServerMessage::Ack(ack)) if ack.stroke == busy => {
                acked_busy = acked_busy.max(ack.upto_seq)
            }
            penmesh_e2e::Incoming::Message(_) => {}
            penmesh_e2e::Incoming::Closed(close) => {
                assert_eq!(close.map(|c| c.0), Some(1001));
                break;
            }
        }
    }
    let db = proxy.stop().await;

    // Assert, on a new proxy over the same database.
    let proxy = spawn_proxy_on(db, |_| {}).await;
    let calm_info = proxy.stroke_info(&session, calm).await;
    assert_eq!(calm_info["status"], "interrupted");
    assert_eq!(proxy.raw_samples(&session, calm).await, samples[..100].to_vec());
    let busy_info = proxy.stroke_info(&session, busy).await;
    assert_eq!(busy_info["status"], "interrupted");
    let stored = proxy.raw_samples(&session, busy).await;
    assert!(stored.len() as u64 >= acked_busy, "acked {acked_busy}, stored {}", stored.len());
    assert_eq!(stored, samples[..stored.len()].to_vec());
    let n = count_rows(&proxy.db, &format!("SELECT CAST(COALESCE(SUM(n), 0) AS BIGINT) FROM stroke_chunks WHERE stroke_id = '{busy}'")).await;
    assert_eq!(n as usize, stored.len());

    // And the interrupted stroke resumes on the new proxy.
    let mut ws = proxy.connect(&session).await;
    let welcome = ws.hello(vec![calm]).await;
    assert_eq!(welcome.resume[0].next_seq, 100);
    ws.points(calm, 100, &samples[100..]).await;
    ws.end(calm, 400).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(proxy.raw_samples(&session, calm).await, samples);
}

#[tokio::test]
async fn upgrades_are_refused_with_503_while_shutting_down() {
    let db = TestDatabase::fresh().await;
    let app = penmesh_proxy::Application::build(test_config(&db)).await.unwrap();
    let router = penmesh_proxy::router(app.state().clone());
    app.shutdown_handle().cancel();
    let request = Request::get(format!("/v1/sessions/{}/ws", Uuid::new_v4()))
        .header("connection", "upgrade")
        .header("upgrade", "websocket")
        .header("sec-websocket-version", "13")
        .header("sec-websocket-key", "dGhlIHNhbXBsZSBub25jZQ==")
        .body(Body::empty())
        .unwrap();
    let response = router.oneshot(request).await.unwrap();
    assert_eq!(response.status(), 503);
    app.run_until_stopped().await.unwrap();
}
