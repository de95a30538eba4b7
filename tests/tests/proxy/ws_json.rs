use penmesh::protocol::ServerMessage;
use penmesh_e2e::{batch_simplified, draw_stroke, spawn_proxy, stroke_samples};
use uuid::Uuid;

#[tokio::test]
async fn a_whole_stroke_in_json_is_simplified_acked_and_stored() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await.json();
    ws.hello(vec![]).await;
    let samples = stroke_samples(300);
    let stroke = Uuid::new_v4();

    let (retained, n_retained) = draw_stroke(&mut ws, stroke, &samples, 25).await;

    assert_eq!(retained, batch_simplified(&samples));
    assert_eq!(n_retained, retained.len() as u64);
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
}

#[tokio::test]
async fn answers_follow_the_form_of_the_latest_frame() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await.json();
    ws.hello(vec![]).await;
    ws.send_text(r#"{"ping":{"nonce":7}}"#).await;
    let (binary, msg) = ws.next_is_binary().await;
    assert!(!binary);
    assert!(matches!(msg, ServerMessage::Pong(p) if p.nonce == 7));
    ws.json = false;
    ws.send(&penmesh::protocol::ClientMessage::Ping(penmesh::protocol::Ping { nonce: 8 })).await;
    let (binary, _) = ws.next_is_binary().await;
    assert!(binary);
}
