use penmesh_e2e::{draw_stroke, spawn_proxy, stroke_samples};
use tokio_tungstenite::tungstenite::Error as WsError;
use uuid::Uuid;

fn status_of(result: Result<penmesh_e2e::WsClient, WsError>) -> u16 {
    match result {
        Err(WsError::Http(response)) => response.status().as_u16(),
        Err(other) => panic!("unexpected error {other}"),
        Ok(_) => 101,
    }
}

#[tokio::test]
async fn websocket_needs_the_session_token_and_reveals_nothing() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let other = proxy.create_session().await;
    let s = session.session;
    // Missing, wrong, another session's, an unknown session, and the right token in the query
    // string, which is not read (URLs reach logs): all 401.
    for path in [
        format!("/v1/sessions/{s}/ws"),
        format!("/v1/sessions/{s}/ws?token={}", session.token),
        format!("/v1/sessions/{s}/ws?token=wrong"),
        format!("/v1/sessions/{s}/ws?token={}", other.token),
        format!("/v1/sessions/{}/ws?token={}", Uuid::new_v4(), session.token),
        format!("/v1/sessions/not-a-uuid/ws?token={}", session.token),
    ] {
        assert_eq!(status_of(proxy.try_connect_path(&path).await), 401, "{path}");
    }
    // The header opens it.
    proxy.connect(&session).await.hello(vec![]).await;
}

#[tokio::test]
async fn http_reads_need_the_token_of_the_strokes_session() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let other = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    draw_stroke(&mut ws, stroke, &stroke_samples(20), 5).await;

    let list = format!("/v1/sessions/{}/strokes", session.session);
    assert_eq!(proxy.http.get(proxy.url(&list)).send().await.unwrap().status(), 401);
    assert_eq!(proxy.get(&list, &other).send().await.unwrap().status(), 401);
    assert_eq!(
        proxy
            .get(&format!("/v1/sessions/{}/strokes", Uuid::new_v4()), &session)
            .send()
            .await
            .unwrap()
            .status(),
        401
    );
    for path in ["simplified", "raw", "mesh"] {
        let url = format!("/v1/strokes/{stroke}/{path}");
        assert_eq!(proxy.http.get(proxy.url(&url)).send().await.unwrap().status(), 401, "{url}");
        assert_eq!(
            proxy.http.get(proxy.url(&url)).bearer_auth("nonsense").send().await.unwrap().status(),
            401,
            "{url}"
        );
        // Another session's token sees no such stroke.
        assert_eq!(proxy.get(&url, &other).send().await.unwrap().status(), 404, "{url}");
    }
    let put = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/mesh")))
        .bearer_auth(&other.token)
        .body(vec![1, 2, 3])
        .send()
        .await
        .unwrap();
    assert_eq!(put.status(), 404);
    assert_eq!(proxy.get(&list, &session).send().await.unwrap().status(), 200);
}
