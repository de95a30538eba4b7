//! What the browser page needs from the proxy: the page itself, the token as a WebSocket
//! subprotocol, and the mesh of a stroke built by the proxy (`POST /v1/strokes/{id}/mesh/build`).

use futures_util::StreamExt;
use penmesh::protocol::{PROTOCOL_VERSION, ServerMessage};
use penmesh_e2e::{WsClient, draw_stroke, spawn_proxy, stroke_samples};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use uuid::Uuid;

#[tokio::test]
async fn the_page_is_served_at_the_root_and_at_a_session_path() {
    let proxy = spawn_proxy().await;
    for path in ["/", &format!("/s/{}", Uuid::new_v4())] {
        let response = proxy.http.get(proxy.url(path)).send().await.unwrap();
        assert_eq!(response.status(), 200, "{path}");
        assert!(response.headers()["content-type"].to_str().unwrap().starts_with("text/html"));
        let html = response.text().await.unwrap();
        assert!(html.contains(&format!("content=\"{PROTOCOL_VERSION}\"")), "{path}: {html}");
        assert!(html.contains("/web/app.js"));
    }
    // reqwest asks for no compression here: the plain bundle, which imports three.js.
    let js = proxy.http.get(proxy.url("/web/app.js")).send().await.unwrap();
    assert_eq!(js.status(), 200);
    assert!(js.headers().get("content-encoding").is_none());
    let body = js.text().await.unwrap();
    assert!(body.len() > 100_000, "the bundle holds three.js: {} bytes", body.len());
    let gz = proxy
        .http
        .get(proxy.url("/web/app.js"))
        .header("accept-encoding", "gzip, deflate")
        .send()
        .await
        .unwrap();
    assert_eq!(gz.headers()["content-encoding"], "gzip");
    assert!(gz.bytes().await.unwrap().len() < body.len() / 2);
}

async fn connect_with_subprotocols(
    port: u16,
    session: Uuid,
    protocols: &str,
) -> Result<(WsClient, Option<String>), tokio_tungstenite::tungstenite::Error> {
    let mut request =
        format!("ws://127.0.0.1:{port}/v1/sessions/{session}/ws").into_client_request().unwrap();
    request.headers_mut().insert("sec-websocket-protocol", protocols.parse().unwrap());
    let (ws, response) = tokio_tungstenite::connect_async(request).await?;
    let chosen =
        response.headers().get("sec-websocket-protocol").map(|v| v.to_str().unwrap().to_string());
    Ok((WsClient { ws, json: true, key: None }, chosen))
}

#[tokio::test]
async fn a_browser_passes_its_token_as_a_subprotocol() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let offer = format!("penmesh, penmesh.token.{}", session.token);
    let (mut ws, chosen) =
        connect_with_subprotocols(proxy.port, session.session, &offer).await.unwrap();
    assert_eq!(chosen.as_deref(), Some("penmesh"), "the proxy selects the plain subprotocol");
    ws.hello(vec![]).await;

    // A browser sees a refused upgrade only as a failed connection (1006), as when the network
    // fails: a wrong token offered as a subprotocol, or a session that does not exist, is told
    // in close code 4401 instead, which the page does not retry.
    for (session, offer) in [
        (session.session, "penmesh, penmesh.token.00".to_string()),
        (Uuid::new_v4(), format!("penmesh, penmesh.token.{}", session.token)),
    ] {
        let (mut wrong, _) = connect_with_subprotocols(proxy.port, session, &offer).await.unwrap();
        let close = match wrong.ws.next().await {
            Some(Ok(Message::Close(frame))) => frame.expect("a close frame with a code"),
            other => panic!("not a close frame first: {other:?}"),
        };
        assert_eq!(u16::from(close.code), 4401, "{close:?}");
        assert!(close.reason.contains("unauthorized"), "{close:?}");
    }
    // Without a subprotocol token (the native client's header), still the HTTP 401.
    let mut request = format!("ws://127.0.0.1:{}/v1/sessions/{}/ws", proxy.port, session.session)
        .into_client_request()
        .unwrap();
    request.headers_mut().insert("authorization", "Bearer 00".parse().unwrap());
    let refused = tokio_tungstenite::connect_async(request).await.expect_err("a wrong token");
    assert!(refused.to_string().contains("401"), "{refused}");
}

#[tokio::test]
async fn the_proxy_builds_stores_and_announces_a_thin_clients_mesh() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut drawer = proxy.connect(&session).await.json();
    drawer.hello(vec![]).await;
    let mut watcher = proxy.connect(&session).await;
    watcher.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    let build = |stroke: Uuid| proxy.build_mesh(&session, stroke);

    // Not before the stroke is done.
    drawer.begin(stroke).await;
    drawer.wait_ack(stroke, 0).await;
    let early = build(stroke).send().await.unwrap();
    assert_eq!(early.status(), 409);
    assert!(early.text().await.unwrap().contains("once it is done"));
    drawer.end(stroke, 0).await;
    let _ = drawer.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;

    let stroke = Uuid::new_v4();
    let samples = stroke_samples(200);
    draw_stroke(&mut drawer, stroke, &samples, 20).await;
    let response = build(stroke).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let info: serde_json::Value = response.json().await.unwrap();
    assert_eq!(info["uploader"], penmesh_proxy::PROXY_UPLOADER);
    assert!(info["triangles"].as_u64().unwrap() > 10, "{info}");

    // The same mesh LRPDP makes on the native client: the smooth centreline through the kept
    // samples, checked against every sample drawn.
    let simplified = proxy.get_json(&format!("/v1/strokes/{stroke}/simplified"), &session).await;
    let kept: Vec<usize> = serde_json::from_value(simplified["indices"].clone()).unwrap();
    let raw = proxy.raw_samples(&session, stroke).await;
    let outline =
        penmesh::fitted_outline(&raw, &kept, &penmesh::Brush::default(), &Default::default())
            .unwrap();
    let mesh = penmesh::solid_mesh(&outline, &Default::default());
    let stored = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), &session).send().await.unwrap();
    assert_eq!(stored.headers()["x-penmesh-triangles"], mesh.triangles().count().to_string());

    // Announced like an uploaded mesh.
    loop {
        if let ServerMessage::PeerMesh(m) = watcher.recv_any().await
            && m.stroke == stroke
        {
            assert_eq!(m.url, format!("/v1/strokes/{stroke}/mesh"));
            break;
        }
    }

    // Asking again keeps the stored mesh.
    let again: serde_json::Value = build(stroke).send().await.unwrap().json().await.unwrap();
    assert_eq!(again, info);

    let unknown = build(Uuid::new_v4()).send().await.unwrap();
    assert_eq!(unknown.status(), 404);
    let unauthorized = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{stroke}/mesh/build")))
        .send()
        .await
        .unwrap();
    assert_eq!(unauthorized.status(), 401);
}
