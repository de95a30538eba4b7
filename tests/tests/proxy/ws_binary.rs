use penmesh::protocol::{ClientMessage, Ping, ServerMessage};
use penmesh_e2e::{batch_simplified, draw_stroke, spawn_proxy, stroke_samples};
use uuid::Uuid;

#[tokio::test]
async fn a_whole_stroke_in_binary_is_simplified_acked_and_stored() {
    // Arrange
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    let welcome = ws.hello(vec![]).await;
    assert_eq!(welcome.session, session.session);
    let samples = stroke_samples(500);
    let stroke = Uuid::new_v4();

    // Act
    let (retained, n_retained) = draw_stroke(&mut ws, stroke, &samples, 16).await;

    // Assert: streamed output equals the batch simplification, and so does the stored one.
    let expected = batch_simplified(&samples);
    assert!(expected.len() < samples.len() / 2, "the test stroke simplifies");
    assert_eq!(retained, expected);
    assert_eq!(n_retained, expected.len() as u64);
    let stored = proxy.get_json(&format!("/v1/strokes/{stroke}/simplified"), &session).await;
    let stored: Vec<penmesh::Sample> = serde_json::from_value(stored["samples"].clone()).unwrap();
    assert_eq!(stored, expected);
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
    let info = proxy.stroke_info(&session, stroke).await;
    assert_eq!(info["status"], "done");
    assert_eq!(info["n_points"], 500);
}

#[tokio::test]
async fn answers_come_back_in_binary_and_ping_gets_pong() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.send(&ClientMessage::Ping(Ping { nonce: 42 })).await;
    let (binary, msg) = ws.next_is_binary().await;
    assert!(binary);
    assert_eq!(msg, ServerMessage::Pong(Ping { nonce: 42 }));
}

#[tokio::test]
async fn many_strokes_on_many_connections_are_all_committed() {
    // Group commit serves several connections at once.
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(200);
    let mut tasks = Vec::new();
    for _ in 0..8 {
        let mut ws = proxy.connect(&session).await;
        let samples = samples.clone();
        tasks.push(tokio::spawn(async move {
            ws.hello(vec![]).await;
            let stroke = Uuid::new_v4();
            draw_stroke(&mut ws, stroke, &samples, 4).await;
            stroke
        }));
    }
    for task in tasks {
        let stroke = task.await.unwrap();
        assert_eq!(proxy.stroke_info(&session, stroke).await["status"], "done");
    }
}
