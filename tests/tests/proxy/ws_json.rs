use penmesh::protocol::ServerMessage;
use penmesh_e2e::{batch_simplified, draw_stroke, spawn_proxy, spawn_proxy_with, stroke_samples};
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

/// `params: null` (and absent) in `stroke_begin`: the stroke is simplified with the proxy's
/// defaults and keeps them, so its HTTP reads show them, never `null` (docs/protocol.md).
#[tokio::test]
async fn a_stroke_begun_with_null_params_reads_back_with_the_proxys_defaults() {
    let proxy = spawn_proxy_with(|c| c.tolerance = 2.5).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await.json();
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.send_text(&format!(
        r#"{{"stroke_begin":{{"stroke":"{stroke}","brush":{{"size":8.0,"pressure_response":0.5,"min_radius":0.25,"color":null}},"device":null,"params":null}}}}"#
    ))
    .await;
    ws.wait_ack(stroke, 0).await;
    let info = proxy.stroke_info(&session, stroke).await;
    let expected = serde_json::json!({
        "tolerance": 2.5, "angle_deg": 45.0, "angle_near_anchor": false,
        "pressure": {"interpolation": 0.2},
    });
    assert_eq!(info["params"], expected);
}
