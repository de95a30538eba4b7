//! A participant's identity within a session (docs/reliability.md, "Who may do what"): the
//! proxy derives it from the session and `Hello.key` (or the `x-penmesh-key` header), and only
//! a stroke's drawer may resume it, append to it, or store or build its mesh. The token alone
//! still reads everything.

use std::time::Duration;

use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, KEY_HEADER, PROTOCOL_VERSION, ServerMessage, StrokeStatus,
};
use penmesh_e2e::{
    TIMEOUT, TestProxy, TestSession, WsClient, count_rows, draw_stroke, minimal_glb, spawn_proxy,
    stroke_samples,
};
use uuid::Uuid;

/// Waits until the stroke's stored status is `status`.
async fn until_status(proxy: &TestProxy, session: &TestSession, stroke: Uuid, status: &str) {
    let start = std::time::Instant::now();
    while proxy.stroke_info(session, stroke).await["status"] != status {
        assert!(start.elapsed() < TIMEOUT, "stroke {stroke} never became {status}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// A's stroke with `n` samples acknowledged, then A's connection dropped: the stroke is
/// `interrupted`, waiting for its drawer.
async fn interrupted_stroke(proxy: &TestProxy, a: &TestSession, n: usize) -> Uuid {
    let stroke = Uuid::new_v4();
    let mut ws = proxy.drawing(a, stroke).await;
    ws.points(stroke, 0, &stroke_samples(n)).await;
    ws.wait_ack(stroke, n as u64).await;
    drop(ws);
    until_status(proxy, a, stroke, "interrupted").await;
    stroke
}

/// A's done stroke, and A's participant id.
async fn done_stroke(proxy: &TestProxy, a: &TestSession) -> (Uuid, Uuid) {
    let mut ws = proxy.connect(a).await;
    let welcome = ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    draw_stroke(&mut ws, stroke, &stroke_samples(120), 30).await;
    (stroke, welcome.participant)
}

async fn connect_keyed(proxy: &TestProxy, session: &TestSession, key: Option<&str>) -> WsClient {
    let mut ws = proxy.connect(session).await;
    ws.key = key.map(str::to_string);
    ws
}

#[tokio::test]
async fn a_stranger_with_the_token_cannot_resume_or_continue_anothers_stroke() {
    let proxy = spawn_proxy().await;
    let a = proxy.create_session().await;
    let stroke = interrupted_stroke(&proxy, &a, 30).await;

    // B: the same token, another key. Resuming in hello is refused, and Welcome says only what
    // the stroke list tells any holder of the token.
    let b = a.stranger();
    let mut ws = proxy.connect(&b).await;
    ws.send(&ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: "stranger".into(),
        name: None,
        resume: vec![stroke],
        key: Some(b.key.clone()),
    }))
    .await;
    let (welcome, before) = ws.recv_until(|m| matches!(m, ServerMessage::Welcome(_))).await;
    let refusal = before
        .iter()
        .find_map(|m| match m {
            ServerMessage::Error(e) => Some(e.clone()),
            _ => None,
        })
        .expect("the resume is refused before the welcome");
    assert_eq!(refusal.code, ErrorCode::NotOwner, "{refusal:?}");
    assert_eq!(refusal.stroke, Some(stroke));
    assert!(refusal.message.contains("another participant"), "{}", refusal.message);
    let ServerMessage::Welcome(welcome) = welcome else { unreachable!() };
    assert_eq!(welcome.resume.len(), 1);
    assert_eq!(
        (welcome.resume[0].status, welcome.resume[0].next_seq),
        (StrokeStatus::Interrupted, 30)
    );

    // Nor by stroke_begin, nor by sending points to it; a keyless connection neither.
    ws.begin(stroke).await;
    let err = ws.expect_error(ErrorCode::NotOwner).await;
    assert_eq!(err.stroke, Some(stroke));
    ws.points(stroke, 30, &stroke_samples(40)[30..]).await;
    ws.expect_error(ErrorCode::UnknownStroke).await;
    let mut keyless = connect_keyed(&proxy, &a, None).await;
    keyless.hello(vec![]).await;
    keyless.begin(stroke).await;
    keyless.expect_error(ErrorCode::NotOwner).await;

    // The stroke is as A left it.
    let info = proxy.stroke_info(&a, stroke).await;
    assert_eq!(info["status"], "interrupted");
    assert_eq!(proxy.raw_samples(&a, stroke).await, stroke_samples(30));

    // (b) A, with its key on a new connection, resumes it and finishes it.
    let mut ws = proxy.connect(&a).await;
    let welcome = ws.hello(vec![stroke]).await;
    assert_eq!(info["participant"], welcome.participant.to_string());
    assert_eq!((welcome.resume[0].status, welcome.resume[0].next_seq), (StrokeStatus::Open, 30));
    ws.points(stroke, 30, &stroke_samples(40)[30..]).await;
    ws.wait_ack(stroke, 40).await;
    ws.end(stroke, 40).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(proxy.raw_samples(&a, stroke).await, stroke_samples(40));
}

/// Who may store or build a done stroke's mesh: only its drawer (the key of its hello), and
/// the refusals come before the body is read.
#[tokio::test]
async fn only_the_drawer_may_store_or_build_a_strokes_mesh() {
    let proxy = spawn_proxy().await;
    let a = proxy.create_session().await;
    let (stroke, a_id) = done_stroke(&proxy, &a).await;
    let glb = minimal_glb(8, 36);
    let stranger = a.stranger();
    let call = |method: &str, key: Option<&str>| {
        let request = match method {
            "PUT" => {
                proxy.http.put(proxy.url(&format!("/v1/strokes/{stroke}/mesh"))).body(glb.clone())
            }
            _ => proxy.http.post(proxy.url(&format!("/v1/strokes/{stroke}/mesh/build"))),
        }
        .bearer_auth(&a.token);
        match key {
            Some(key) => request.header(KEY_HEADER, key),
            None => request,
        }
    };
    // (who, x-penmesh-key, status, error, a piece of the message)
    let cases = [
        ("no key", None, 403, "forbidden", KEY_HEADER),
        (
            "another participant's key",
            Some(stranger.key.as_str()),
            403,
            "forbidden",
            "another participant",
        ),
        (
            "a key too short",
            Some("0123456789abcdef"),
            400,
            "bad_request",
            "x-penmesh-key is 16 characters",
        ),
        (
            "a key with a '/'",
            Some("0123456789abcdef/0123456789abcdef"),
            400,
            "bad_request",
            "x-penmesh-key holds '/'",
        ),
    ];
    for (who, key, status, error, needle) in cases {
        for method in ["PUT", "POST"] {
            let response = call(method, key).send().await.unwrap();
            assert_eq!(response.status(), status, "{method} with {who}");
            let body: serde_json::Value = response.json().await.unwrap();
            assert_eq!(body["error"], error, "{method} with {who}: {body}");
            let message = body["message"].as_str().unwrap();
            assert!(message.contains(needle), "{method} with {who}: {message}");
        }
    }
    assert_eq!(proxy.stroke_info(&a, stroke).await["has_mesh"], false, "nothing was stored");

    // (b, c) The drawer may; the uploader stored is its participant id, whatever the old
    // free-form header says.
    let response = proxy
        .put_mesh(&a, stroke, glb.clone())
        .header("x-penmesh-uploader", "someone else")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let info: serde_json::Value = response.json().await.unwrap();
    assert_eq!(info["uploader"], a_id.to_string());
    let built = proxy.build_mesh(&a, stroke).send().await.unwrap();
    assert_eq!(built.status(), 200, "the drawer may ask for a build (it keeps the stored mesh)");
    assert_eq!(built.json::<serde_json::Value>().await.unwrap()["uploader"], a_id.to_string());
    let stored = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), &a).send().await.unwrap();
    assert_eq!(stored.bytes().await.unwrap().to_vec(), glb);

    // A stranger still reads it all with the token alone.
    for path in ["mesh", "simplified", "raw"] {
        let response =
            proxy.get(&format!("/v1/strokes/{stroke}/{path}"), &stranger).send().await.unwrap();
        assert_eq!(response.status(), 200, "GET {path}");
    }

    // The API's description says so.
    let openapi: serde_json::Value =
        proxy.http.get(proxy.url("/v1/openapi.json")).send().await.unwrap().json().await.unwrap();
    for (path, method) in [
        ("/v1/strokes/{id}/mesh", "put"),
        ("/v1/strokes/{id}/mesh/build", "post"),
        ("/v1/strokes/{id}", "delete"),
        ("/v1/strokes/{id}/restore", "post"),
    ] {
        let call = &openapi["paths"][path][method];
        assert!(call["parameters"].to_string().contains(KEY_HEADER), "{path}: {call}");
        assert!(call["responses"]["403"].is_object(), "{path}: {call}");
    }

    // The stranger cannot replace it either.
    let response = proxy.put_mesh(&stranger, stroke, minimal_glb(3, 3)).send().await.unwrap();
    assert_eq!(response.status(), 403);
    let stored = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), &a).send().await.unwrap();
    assert_eq!(stored.bytes().await.unwrap().to_vec(), glb);
}

#[tokio::test]
async fn a_malformed_key_is_refused_naming_the_field_and_a_good_hello_follows() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let too_long = "a".repeat(129);
    // (key, a piece of the message)
    let cases = [
        ("", "hello.key is 0 characters"),
        ("0123456789abcdef", "hello.key is 16 characters"),
        (too_long.as_str(), "hello.key is 129 characters"),
        ("0123456789abcdef0123456789abcde+", "hello.key holds '+'"),
        ("0123456789abcdef 0123456789abcdef", "hello.key holds ' '"),
    ];
    for json in [false, true] {
        for (key, needle) in cases {
            let mut ws = connect_keyed(&proxy, &session, Some(key)).await;
            ws.json = json;
            ws.send(&ClientMessage::Hello(Hello {
                protocol: PROTOCOL_VERSION,
                client: "bad key".into(),
                name: None,
                resume: vec![],
                key: Some(key.into()),
            }))
            .await;
            let err = ws.expect_error(ErrorCode::Malformed).await;
            assert!(err.message.contains(needle), "{key:?} (json {json}): {}", err.message);
            // Not welcomed; a hello with a good key is.
            ws.key = Some(session.key.clone());
            ws.hello(vec![]).await;
        }
    }
}

#[tokio::test]
async fn the_same_key_is_one_participant_in_a_session_and_another_in_the_next() {
    let proxy = spawn_proxy().await;
    let first = proxy.create_session().await;
    let second = TestSession { key: first.key.clone(), ..proxy.create_session().await };
    let participant = |ws: WsClient| async move {
        let mut ws = ws;
        ws.hello(vec![]).await.participant
    };
    let in_first = participant(proxy.connect(&first).await).await;
    assert_eq!(participant(proxy.connect(&first).await).await, in_first, "a reconnect");
    assert_ne!(participant(proxy.connect(&second).await).await, in_first, "another session");
    assert_ne!(participant(proxy.connect(&first.stranger()).await).await, in_first);
    // Without a key: a fresh identity on each connection.
    let keyless = participant(connect_keyed(&proxy, &first, None).await).await;
    assert_ne!(participant(connect_keyed(&proxy, &first, None).await).await, keyless);
    assert_ne!(keyless, in_first);
}

/// A participant on two connections at once (its reconnect says hello before the old
/// connection's end is noticed) is present once, and leaves when its last connection does.
#[tokio::test]
async fn a_participant_on_two_connections_joins_once_and_leaves_with_the_last() {
    let proxy = spawn_proxy().await;
    let a = proxy.create_session().await;
    // Each watcher reads its history to `Synced` before the others go on: `Welcome` comes
    // before the history, and a stroke begun before a watcher's history is read reaches it in
    // the history (`PeerStrokes`), not as a `PeerStrokeBegin` (on a busy machine it did).
    let mut watcher = proxy.connect(&a.stranger()).await;
    watcher.hello(vec![]).await;
    assert!(presence_until_synced(&mut watcher, None).await.is_empty());
    let mut first = proxy.connect(&a).await;
    let me = first.hello(vec![]).await.participant;
    let mut second = proxy.connect(&a).await;
    assert_eq!(second.hello(vec![]).await.participant, me);
    let mut late = proxy.connect(&a.stranger()).await;
    late.hello(vec![]).await;
    let late_history = presence_until_synced(&mut late, Some(me)).await;

    drop(first);
    // Its leave is stored; then the second connection draws, so the watcher has heard
    // everything up to the leave once the stroke's begin arrives.
    let start = std::time::Instant::now();
    while count_rows(&proxy.db, "SELECT COUNT(*) FROM participants WHERE left_at IS NOT NULL").await
        < 1
    {
        assert!(start.elapsed() < TIMEOUT, "the first connection's leave is never stored");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let stroke = Uuid::new_v4();
    second.begin(stroke).await;
    second.wait_ack(stroke, 0).await;
    let mut presence = Vec::new();
    for (ws, history) in [(&mut watcher, Vec::new()), (&mut late, late_history)] {
        let mut seen = history;
        loop {
            match ws.recv_any().await {
                ServerMessage::PeerJoined(j) if j.participant == me => seen.push("joined"),
                ServerMessage::PeerLeft(l) if l.participant == me => seen.push("left"),
                ServerMessage::PeerStrokeBegin(b) if b.stroke == stroke => break,
                _ => {}
            }
        }
        presence.push(seen);
    }
    assert_eq!(presence, [vec!["joined"], vec!["joined"]], "(live, and from history)");

    drop(second);
    loop {
        match watcher.recv_any().await {
            ServerMessage::PeerLeft(l) if l.participant == me => break,
            ServerMessage::PeerJoined(j) if j.participant == me => panic!("joined again"),
            _ => {}
        }
    }
}

/// What `ws` hears of `who`'s presence up to its history's `Synced` ("joined", "left").
async fn presence_until_synced(ws: &mut WsClient, who: Option<Uuid>) -> Vec<&'static str> {
    let mut seen = Vec::new();
    loop {
        match ws.recv_any().await {
            ServerMessage::PeerJoined(j) if Some(j.participant) == who => seen.push("joined"),
            ServerMessage::PeerLeft(l) if Some(l.participant) == who => seen.push("left"),
            ServerMessage::Synced(_) => return seen,
            _ => {}
        }
    }
}
