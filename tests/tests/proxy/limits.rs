use std::time::Duration;

use futures_util::SinkExt;
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Ping, PointBatch, Points, ServerMessage, StrokeBegin, encode_client,
};
use penmesh_e2e::{Incoming, TestProxy, TestSession, WsClient, spawn_proxy_with, stroke_samples};
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use uuid::Uuid;

#[tokio::test]
async fn a_message_over_the_limit_is_refused_and_one_over_the_hard_limit_closes() {
    let proxy = spawn_proxy_with(|c| c.max_message_bytes = 1024).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.send_text(&format!(r#"{{"ping":{{"nonce":1}}, "pad":"{}"}}"#, "x".repeat(2000))).await;
    let err = ws.expect_error(ErrorCode::FrameTooLarge).await;
    assert!(err.message.contains("1024"), "{}", err.message);
    ws.send(&ClientMessage::Ping(penmesh::protocol::Ping { nonce: 2 })).await;
    ws.recv_until(|m| matches!(m, ServerMessage::Pong(_))).await;
    // Past four times the limit the WebSocket layer refuses to read it at all.
    let _ = ws.ws.send(Message::Binary(vec![0u8; 8000].into())).await;
    let close = ws.expect_close().await;
    assert_eq!(close, Some(1009), "closed as too big, told apart by its error type");
}

#[tokio::test]
async fn a_batch_over_the_limit_is_refused() {
    let proxy = spawn_proxy_with(|c| c.max_batch_samples = 10).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    ws.points(stroke, 0, &stroke_samples(11)).await;
    let err = ws.expect_error(ErrorCode::BatchTooLarge).await;
    assert!(err.message.contains("11") && err.message.contains("10"), "{}", err.message);
    ws.points(stroke, 0, &stroke_samples(10)).await;
    ws.wait_ack(stroke, 10).await;
}

#[tokio::test]
async fn a_stroke_over_the_limit_is_refused() {
    let proxy = spawn_proxy_with(|c| c.max_stroke_samples = 20).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    let samples = stroke_samples(21);
    ws.begin(stroke).await;
    ws.points(stroke, 0, &samples[..15]).await;
    ws.points(stroke, 15, &samples[15..]).await;
    let err = ws.expect_error(ErrorCode::StrokeTooLong).await;
    assert!(err.message.contains("20"), "{}", err.message);
    ws.end(stroke, 15).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
}

#[tokio::test]
async fn open_strokes_per_connection_are_limited() {
    let proxy = spawn_proxy_with(|c| c.max_open_strokes = 2).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let strokes = [Uuid::new_v4(), Uuid::new_v4(), Uuid::new_v4()];
    for s in &strokes[..2] {
        ws.begin(*s).await;
        ws.wait_ack(*s, 0).await;
    }
    ws.begin(strokes[2]).await;
    let err = ws.expect_error(ErrorCode::TooManyOpenStrokes).await;
    assert_eq!(err.stroke, Some(strokes[2]));
    ws.end(strokes[0], 0).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    ws.begin(strokes[2]).await;
    ws.wait_ack(strokes[2], 0).await;
}

#[tokio::test]
async fn connections_per_session_are_limited() {
    let proxy = spawn_proxy_with(|c| c.max_connections_per_session = 2).await;
    let session = proxy.create_session().await;
    let mut first = proxy.connect(&session).await;
    first.hello(vec![]).await;
    let mut second = proxy.connect(&session).await;
    second.hello(vec![]).await;
    let mut third = proxy.connect(&session).await;
    third.expect_error(ErrorCode::TooManyConnections).await;
    assert_eq!(third.expect_close().await, Some(1008));
    // Another session is not affected, and a slot frees when a connection leaves.
    let other = proxy.create_session().await;
    proxy.connect(&other).await.hello(vec![]).await;
    first.ws.close(None).await.unwrap();
    drop(first);
    let mut again = None;
    for _ in 0..50 {
        let mut ws = proxy.connect(&session).await;
        ws.send(&ClientMessage::Hello(penmesh::protocol::Hello {
            protocol: penmesh::protocol::PROTOCOL_VERSION,
            client: "t".into(),
            name: None,
            resume: vec![],
            key: None,
        }))
        .await;
        if let ServerMessage::Welcome(_) = ws.recv().await {
            again = Some(ws);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(again.is_some(), "a slot frees when a connection leaves");
}

#[tokio::test]
async fn an_idle_connection_is_closed_and_its_stroke_interrupted() {
    let proxy = spawn_proxy_with(|c| c.idle_timeout_secs = 1).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    ws.points(stroke, 0, &stroke_samples(5)).await;
    ws.wait_ack(stroke, 5).await;
    ws.expect_error(ErrorCode::IdleTimeout).await;
    assert_eq!(ws.expect_close().await, Some(1000));
    let mut status = serde_json::Value::Null;
    for _ in 0..50 {
        status = proxy.stroke_info(&session, stroke).await["status"].clone();
        if status == "interrupted" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(status, "interrupted");
}

#[tokio::test]
async fn the_http_body_size_is_limited() {
    let proxy = spawn_proxy_with(|c| c.max_body_bytes = 1000).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    penmesh_e2e::draw_stroke(&mut ws, stroke, &stroke_samples(10), 10).await;
    let response = proxy.put_mesh(&session, stroke, vec![0u8; 2000]).send().await.unwrap();
    assert_eq!(response.status(), 413);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["error"], "too_large");
}

#[tokio::test]
async fn a_mesh_upload_with_a_wrong_token_or_key_is_refused_before_its_body_is_read() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let proxy = spawn_proxy_with(|_| {}).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    penmesh_e2e::draw_stroke(&mut ws, stroke, &stroke_samples(10), 10).await;
    let stranger = session.stranger();
    // (token, participant key, the answer that comes without the body; None: it waits for it)
    let cases = [
        ("wrong", &session.key, Some("401")),
        (session.token.as_str(), &stranger.key, Some("403")),
        (session.token.as_str(), &session.key, None),
    ];
    for (token, key, refused) in cases {
        // Announce 10 MB and send a few bytes: a server that reads the body first would wait.
        let mut socket = tokio::net::TcpStream::connect(("127.0.0.1", proxy.port)).await.unwrap();
        let head = format!(
            "PUT /v1/strokes/{stroke}/mesh HTTP/1.1\r\nhost: localhost\r\n\
             authorization: Bearer {token}\r\nx-penmesh-key: {key}\r\n\
             content-length: 10000000\r\n\r\nglTF"
        );
        socket.write_all(head.as_bytes()).await.unwrap();
        let mut answer = vec![0u8; 64];
        let read = tokio::time::timeout(Duration::from_secs(5), socket.read(&mut answer)).await;
        if let Some(code) = refused {
            let n = read.expect("a refusal is answered without the body").unwrap();
            let status = String::from_utf8_lossy(&answer[..n]).to_string();
            assert!(status.starts_with(&format!("HTTP/1.1 {code}")), "{status}");
        } else {
            // The right token and key: the proxy waits for the body it was promised (or
            // refuses it as too large at once); either way it does not answer 401 or 403.
            if let Ok(Ok(n)) = read {
                let status = String::from_utf8_lossy(&answer[..n]).to_string();
                assert!(
                    !status.starts_with("HTTP/1.1 401") && !status.starts_with("HTTP/1.1 403"),
                    "{status}"
                );
            }
        }
    }
}

#[tokio::test]
async fn a_slow_reader_is_disconnected_instead_of_growing_memory() {
    let proxy = spawn_proxy_with(|c| {
        c.outgoing_queue = 4;
        c.max_stroke_samples = 100_000_000;
        c.max_stroke_retained = 100_000_000;
    })
    .await;
    let session = proxy.create_session().await;
    // A client with a tiny receive buffer that never reads.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let stream =
        socket.connect(format!("127.0.0.1:{}", proxy.port).parse().unwrap()).await.unwrap();
    let mut request = format!("ws://127.0.0.1:{}/v1/sessions/{}/ws", proxy.port, session.session)
        .into_client_request()
        .unwrap();
    request
        .headers_mut()
        .insert("authorization", format!("Bearer {}", session.token).parse().unwrap());
    let (ws, _) =
        tokio_tungstenite::client_async(request, tokio_tungstenite::MaybeTlsStream::Plain(stream))
            .await
            .unwrap();
    let mut ws = WsClient { ws, json: false, key: None };
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    // A zigzag: every sample is retained, so each batch comes back as a large Retained.
    let batch = 2000usize;
    let mut sent_all = true;
    for b in 0..2000usize {
        let points: Vec<Sample> = (0..batch)
            .map(|i| {
                let k = b * batch + i;
                Sample::new(
                    // Within the coordinate bound (±1e6): back to 0 every 250 000 samples.
                    (k % 250_000) as f64 * 4.0,
                    if k.is_multiple_of(2) { 0.0 } else { 50.0 },
                    k as f64,
                    0.5,
                )
            })
            .collect();
        let msg = ClientMessage::Points(Points {
            stroke,
            seq: (b * batch) as u64,
            points: PointBatch(points),
        });
        let send = ws.ws.send(Message::Binary(encode_client(&msg).into()));
        match tokio::time::timeout(Duration::from_secs(5), send).await {
            Ok(Ok(())) => {}
            _ => {
                sent_all = false;
                break;
            }
        }
        if proxy.metrics().await.contains("penmesh_ws_slow_reader_disconnects_total") {
            sent_all = false;
            break;
        }
    }
    // The sender may not notice: the proxy stops reading a connection whose answers overflow,
    // but a host whose loopback receive buffers grow to 32 MB (`net.ipv4.tcp_rmem`) takes all
    // 24 MB of batches into the kernel first. What must happen either way is the disconnect.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    let mut disconnected = !sent_all;
    while !disconnected && tokio::time::Instant::now() < deadline {
        disconnected = proxy.metrics().await.contains("penmesh_ws_slow_reader_disconnects_total");
        if !disconnected {
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }
    assert!(disconnected, "the proxy kept a reader that never reads");
    // Draining what was buffered ends in the connection's end.
    loop {
        match ws.next().await {
            Incoming::Closed(_) => break,
            Incoming::Message(_) => continue,
        }
    }
    assert!(proxy.metrics().await.contains("penmesh_ws_slow_reader_disconnects_total"));
}

#[tokio::test]
async fn a_burst_of_answers_larger_than_the_outgoing_queue_does_not_cut_off_a_reader() {
    // A queue of 4 frames, and 64 batches in flight: one group commit acknowledges more
    // batches at once than the queue holds, but this client reads everything, so the proxy
    // must wait for its socket instead of taking it for a slow reader. (A straight line, so
    // that ACUTS retains nothing until the end: no session events to fall behind on.)
    let proxy = spawn_proxy_with(|c| {
        c.outgoing_queue = 4;
        c.commit_interval_ms = 50;
    })
    .await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    let samples: Vec<Sample> =
        (0..600).map(|i| Sample::new(i as f64, 0.0, i as f64 * 5.0, 0.5)).collect();
    for (k, batch) in samples.chunks(4).enumerate() {
        ws.points(stroke, (4 * k) as u64, batch).await;
    }
    ws.wait_ack(stroke, samples.len() as u64).await;
    ws.end(stroke, samples.len() as u64).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    // (The connection was not dropped as a slow reader: it got its StrokeDone. The metric of
    // slow-reader disconnects is process-wide, shared with the other tests running at once.)
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
}

/// Fields bigger than the settings allow: each refused with a code and a message that names
/// the field and the limit (the batch before its samples are decoded).
#[tokio::test]
async fn fields_over_their_limits_are_refused_naming_them() {
    let proxy = spawn_proxy_with(|c| {
        c.max_batch_samples = 10;
        c.max_device_chars = 20;
        c.max_stroke_retained = 15;
        c.max_open_strokes = 2;
    })
    .await;
    let session = proxy.create_session().await;
    // A zigzag: every sample is retained.
    let zigzag: Vec<Sample> = (0..20)
        .map(|i| Sample::new(i as f64 * 4.0, if i % 2 == 0 { 0.0 } else { 50.0 }, i as f64, 0.5))
        .collect();
    let begin = |stroke, device: &str| {
        ClientMessage::StrokeBegin(StrokeBegin {
            stroke,
            brush: Default::default(),
            device: Some(device.into()),
            params: None,
            placement: None,
            solid: None,
        })
    };
    let points = |stroke, seq: usize, samples: &[Sample]| {
        ClientMessage::Points(Points {
            stroke,
            seq: seq as u64,
            points: PointBatch(samples.to_vec()),
        })
    };
    let s = Uuid::new_v4();
    /// A case: its name, JSON or binary, what is sent after hello, the error and words of it.
    type Case<'a> = (&'a str, bool, Vec<ClientMessage>, ErrorCode, &'a [&'a str]);
    let cases: Vec<Case> = vec![
        (
            "device",
            false,
            vec![begin(s, &"d".repeat(21))],
            ErrorCode::Malformed,
            &["device", "21", "20"],
        ),
        (
            "binary batch",
            false,
            vec![points(s, 0, &stroke_samples(11))],
            ErrorCode::BatchTooLarge,
            &["11", "10"],
        ),
        (
            "json batch",
            true,
            vec![points(s, 0, &stroke_samples(11))],
            ErrorCode::BatchTooLarge,
            &["more", "10"],
        ),
        (
            "retained",
            false,
            vec![begin(s, "pen"), points(s, 0, &zigzag[..10]), points(s, 10, &zigzag[10..])],
            ErrorCode::StrokeTooLong,
            &["retain", "15"],
        ),
    ];
    for (case, json, messages, code, words) in cases {
        let mut ws = proxy.connect(&session).await;
        if json {
            ws = ws.json();
        }
        ws.hello(vec![]).await;
        for msg in &messages {
            ws.send(msg).await;
        }
        let err = ws.expect_error(code).await;
        for word in words {
            assert!(err.message.contains(word), "{case}: {}", err.message);
        }
        // The connection goes on.
        ws.send(&ClientMessage::Ping(penmesh::protocol::Ping { nonce: 7 })).await;
        ws.recv_until(|m| matches!(m, ServerMessage::Pong(_))).await;
    }
    // A resume list longer than the open strokes a connection may hold: refused and closed.
    let mut ws = proxy.connect(&session).await;
    ws.send(&ClientMessage::Hello(penmesh::protocol::Hello {
        protocol: penmesh::protocol::PROTOCOL_VERSION,
        client: "t".into(),
        name: None,
        resume: (0..3).map(|_| Uuid::new_v4()).collect(),
        key: None,
    }))
    .await;
    let err = ws.expect_error(ErrorCode::TooManyOpenStrokes).await;
    assert!(err.message.contains("resume") && err.message.contains('2'), "{}", err.message);
    assert_eq!(ws.expect_close().await, Some(1008));
}

/// `POST /v1/sessions` needs nothing: per client address, a burst and then a rate.
#[tokio::test]
async fn session_creation_is_rate_limited_per_client_address() {
    for trust in [false, true] {
        let proxy = spawn_proxy_with(|c| {
            c.session_burst = 2;
            c.session_rate_per_minute = 6;
            c.trust_forwarded_for = trust;
        })
        .await;
        let post = |forwarded: Option<&str>| {
            let request = proxy.http.post(proxy.url("/v1/sessions"));
            match forwarded {
                Some(address) => request.header("x-forwarded-for", address),
                None => request,
            }
        };
        for (request, status) in [
            (None, 201),
            (None, 201),
            (None, 429),
            // Another address: its own bucket when the header is trusted, else the same one.
            (Some("203.0.113.7"), if trust { 201 } else { 429 }),
            (Some("198.51.100.1, 203.0.113.8"), if trust { 201 } else { 429 }),
        ] {
            let response = post(request).send().await.unwrap();
            assert_eq!(response.status(), status, "trust {trust}, {request:?}");
            if status == 429 {
                let wait: u64 =
                    response.headers()["retry-after"].to_str().unwrap().parse().unwrap();
                assert!((1..=10).contains(&wait), "retry-after {wait}");
                let body: serde_json::Value = response.json().await.unwrap();
                assert_eq!(body["error"], "too_many_requests");
            }
        }
    }
}

#[tokio::test]
async fn websocket_connections_per_replica_are_limited_before_the_upgrade() {
    let proxy = spawn_proxy_with(|c| c.max_connections = 2).await;
    let (a, b) = (proxy.create_session().await, proxy.create_session().await);
    let mut first = proxy.connect(&a).await;
    first.hello(vec![]).await;
    let mut second = proxy.connect(&b).await;
    second.hello(vec![]).await;
    match proxy.try_connect(&a).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
            assert_eq!(response.status(), 503);
            let body = String::from_utf8_lossy(response.body().as_deref().unwrap_or_default());
            assert!(body.contains("busy") && body.contains("max-connections"), "{body}");
        }
        other => panic!("expected 503, got {:?}", other.map(|_| "an open socket")),
    }
    // A slot frees when a connection ends.
    first.ws.close(None).await.unwrap();
    drop(first);
    let mut again = false;
    for _ in 0..50 {
        if let Ok(mut ws) = proxy.try_connect(&a).await {
            ws.hello(vec![]).await;
            again = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(again, "a slot frees when a connection ends");
}

/// One client address may hold `--max-connections-per-address` WebSockets of a replica; past
/// it an upgrade is refused with 503 naming the limit and the address, before the upgrade,
/// while other addresses (here told apart by a trusted `X-Forwarded-For`) connect as before.
#[tokio::test]
async fn websocket_connections_per_client_address_are_limited_before_the_upgrade() {
    let proxy = spawn_proxy_with(|c| {
        c.max_connections_per_address = 2;
        c.trust_forwarded_for = true;
    })
    .await;
    let session = proxy.create_session().await;
    let stranger = "198.51.100.7";
    let mut first = connect_from(&proxy, &session, Some(stranger)).await.unwrap();
    first.hello(vec![]).await;
    let mut second = connect_from(&proxy, &session, Some(stranger)).await.unwrap();
    second.hello(vec![]).await;
    match connect_from(&proxy, &session, Some(stranger)).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
            assert_eq!(response.status(), 503);
            let body = String::from_utf8_lossy(response.body().as_deref().unwrap_or_default());
            assert!(
                body.contains("busy")
                    && body.contains("max-connections-per-address")
                    && body.contains(stranger),
                "{body}"
            );
        }
        other => panic!("expected 503, got {:?}", other.map(|_| "an open socket")),
    }
    // Other addresses are not affected: another forwarded one, and the peer's own.
    connect_from(&proxy, &session, Some("203.0.113.9")).await.unwrap().hello(vec![]).await;
    connect_from(&proxy, &session, None).await.unwrap().hello(vec![]).await;
    // A slot frees when a connection ends.
    first.ws.close(None).await.unwrap();
    drop(first);
    let mut again = false;
    for _ in 0..50 {
        if let Ok(mut ws) = connect_from(&proxy, &session, Some(stranger)).await {
            ws.hello(vec![]).await;
            again = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(again, "a slot of the address frees when its connection ends");
}

/// A connection to the session's WebSocket, with `X-Forwarded-For: forwarded` when given.
async fn connect_from(
    proxy: &TestProxy,
    session: &TestSession,
    forwarded: Option<&str>,
) -> Result<WsClient, tokio_tungstenite::tungstenite::Error> {
    let mut request = penmesh_e2e::ws_request(proxy.port, session);
    if let Some(address) = forwarded {
        request.headers_mut().insert("x-forwarded-for", address.parse().unwrap());
    }
    let (ws, _) = tokio_tungstenite::connect_async(request).await?;
    Ok(WsClient { ws, json: false, key: Some(session.key.clone()) })
}

/// Sends a WebSocket ping, and a `Ping` message too when `ping_message`, every 250 ms,
/// collecting what comes back, until the proxy closes the connection or `within` has passed.
/// Returns the messages and the close code (1006 when the socket ended without a close frame;
/// `None` while it is still open).
async fn ping_until_closed(
    ws: &mut WsClient,
    ping_message: bool,
    within: Duration,
) -> (Vec<ServerMessage>, Option<u16>) {
    let ping = encode_client(&ClientMessage::Ping(Ping { nonce: 1 }));
    let mut messages = Vec::new();
    let deadline = Instant::now() + within;
    while Instant::now() < deadline {
        let _ = ws.ws.send(Message::Ping(Vec::new().into())).await;
        if ping_message {
            let _ = ws.ws.send(Message::Binary(ping.clone().into())).await;
        }
        let until = Instant::now() + Duration::from_millis(250);
        while let Ok(incoming) = tokio::time::timeout_at(until, ws.next()).await {
            match incoming {
                Incoming::Message(msg) => messages.push(msg),
                Incoming::Closed(close) => return (messages, Some(close.map_or(1006, |c| c.0))),
            }
        }
    }
    (messages, None)
}

/// A connection that never says hello is closed at the hello deadline, however it pings, and
/// its slot frees.
#[tokio::test]
async fn a_connection_that_never_says_hello_is_closed_at_the_hello_deadline() {
    let proxy = spawn_proxy_with(|c| {
        c.hello_timeout_secs = 1;
        c.max_connections = 1;
    })
    .await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    let started = Instant::now();
    let (messages, close) = ping_until_closed(&mut ws, false, Duration::from_secs(6)).await;
    let waited = started.elapsed();
    assert_eq!(close, Some(1008), "closed at the hello deadline, not open after {waited:?}");
    assert!(waited >= Duration::from_millis(900), "closed after {waited:?}");
    let error = messages.iter().find_map(|m| match m {
        ServerMessage::Error(e) => Some(e),
        _ => None,
    });
    let error = error.expect("the close is explained");
    assert_eq!(error.code, ErrorCode::Protocol);
    assert!(error.message.contains("hello") && error.message.contains("1 s"), "{}", error.message);
    let mut again = false;
    for _ in 0..50 {
        if let Ok(mut ws) = proxy.try_connect(&session).await {
            ws.hello(vec![]).await;
            again = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(again, "the replica's only slot frees");
}

/// Pings keep a connection's peer alive, not its slot: a connection that only pings (a `Ping`
/// message and a WebSocket ping every 250 ms, each answered) is closed at the idle timeout and
/// frees its slot, while one that draws as slowly, a batch every 500 ms, stays.
#[tokio::test]
async fn a_connection_that_only_pings_is_closed_at_the_idle_timeout_and_frees_its_slot() {
    let proxy = spawn_proxy_with(|c| {
        c.idle_timeout_secs = 2;
        c.max_connections = 2;
    })
    .await;
    let session = proxy.create_session().await;
    let mut pinger = proxy.connect(&session).await;
    pinger.hello(vec![]).await;
    let drawer_session = session.stranger();
    let stroke = Uuid::new_v4();
    let mut drawer = proxy.drawing(&drawer_session, stroke).await;
    assert!(proxy.try_connect(&session).await.is_err(), "both slots are taken");
    let samples = stroke_samples(40);
    let started = Instant::now();
    let drawing = async {
        for (k, batch) in samples.chunks(4).enumerate() {
            tokio::time::sleep(Duration::from_millis(500)).await;
            drawer.points(stroke, (4 * k) as u64, batch).await;
            drawer.wait_ack(stroke, (4 * k + batch.len()) as u64).await;
        }
    };
    let pinging = ping_until_closed(&mut pinger, true, Duration::from_secs(8));
    let ((), (messages, close)) = tokio::join!(drawing, pinging);
    assert!(started.elapsed() >= Duration::from_secs(5), "the drawer drew for 5 s");
    assert_eq!(close, Some(1000), "a connection that only pings is closed at the idle timeout");
    assert!(messages.iter().any(|m| matches!(m, ServerMessage::Pong(_))), "its pings were heard");
    let idle = messages.iter().any(|m| {
        matches!(m, ServerMessage::Error(e) if e.code == ErrorCode::IdleTimeout
            && e.message.contains("2 s"))
    });
    assert!(idle, "{messages:?}");
    // The drawer, as idle in time but working, is still there.
    drawer.end(stroke, samples.len() as u64).await;
    drawer.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(proxy.raw_samples(&drawer_session, stroke).await, samples);
    let mut again = false;
    for _ in 0..50 {
        if let Ok(mut ws) = proxy.try_connect(&session).await {
            ws.hello(vec![]).await;
            again = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(again, "the pinger's slot frees");
}

/// The byte bound of the outgoing queue never drops an answer owed: a drawer whose answers
/// (JSON, every sample retained) are far larger than the bound, and many at once (one group
/// commit acknowledges many batches), still gets every ack and retained sample, in order.
#[tokio::test]
async fn answers_larger_than_the_outgoing_bytes_all_reach_a_reader() {
    let proxy = spawn_proxy_with(|c| {
        c.outgoing_queue_bytes = 1024;
        c.commit_interval_ms = 50;
    })
    .await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await.json();
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    // A zigzag on the codec's grid: every sample is retained.
    let samples: Vec<Sample> = (0..600)
        .map(|i| Sample::new(i as f64 * 4.0, if i % 2 == 0 { 0.0 } else { 50.0 }, i as f64, 0.5))
        .collect();
    ws.begin(stroke).await;
    for (k, batch) in samples.chunks(20).enumerate() {
        ws.points(stroke, (20 * k) as u64, batch).await;
    }
    // Every ack and retained sample, in order. A `lagged` may come too (with PostgreSQL the
    // session's events come back through NOTIFY and overflow the 1 KB): it is about the
    // session's events, not this drawer's answers, and is no failure here.
    let mut retained = Vec::new();
    loop {
        match ws.recv().await {
            ServerMessage::Ack(ack) if ack.upto_seq >= samples.len() as u64 => break,
            ServerMessage::Retained(r) => retained.push((r.first, r.points.0)),
            ServerMessage::Error(err) => assert_eq!(err.code, ErrorCode::Lagged, "{err:?}"),
            _ => {}
        }
    }
    ws.end(stroke, samples.len() as u64).await;
    let (_, rest) = ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    for msg in rest {
        if let ServerMessage::Retained(r) = msg {
            retained.push((r.first, r.points.0));
        }
    }
    assert_eq!(penmesh_e2e::assemble_retained(&retained), samples);
    // (The connection was not dropped as a slow reader: it got its StrokeDone. The metric of
    // slow-reader disconnects is process-wide, shared with the other tests running at once.)
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
}

/// Slowloris: a connection that does not finish its request head within the header timeout
/// (from its opening, or from its previous request) is closed.
#[tokio::test]
async fn a_connection_that_sends_half_a_request_is_closed_after_the_header_timeout() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let proxy = spawn_proxy_with(|c| c.header_timeout_secs = 1).await;
    for partial in [
        "",
        "GET /healthz HT",
        "GET /healthz HTTP/1.1\r\nhost: localhost\r\n",
        // A whole request, then nothing: answered, then closed when idle.
        "GET /healthz HTTP/1.1\r\nhost: localhost\r\n\r\n",
    ] {
        let started = tokio::time::Instant::now();
        let mut socket = tokio::net::TcpStream::connect(("127.0.0.1", proxy.port)).await.unwrap();
        socket.write_all(partial.as_bytes()).await.unwrap();
        let mut answer = Vec::new();
        let closed =
            tokio::time::timeout(Duration::from_secs(5), socket.read_to_end(&mut answer)).await;
        assert!(closed.is_ok(), "{partial:?}: still open after 5 s");
        let waited = started.elapsed();
        assert!(waited >= Duration::from_millis(900), "{partial:?}: closed after {waited:?}");
        if partial.ends_with("\r\n\r\n") {
            assert!(answer.starts_with(b"HTTP/1.1 200"), "{}", String::from_utf8_lossy(&answer));
        }
    }
}

#[tokio::test]
async fn an_http_request_whose_body_does_not_come_gets_408() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let proxy = spawn_proxy_with(|c| c.request_timeout_secs = 1).await;
    let session = proxy.create_session().await;
    let stroke = Uuid::new_v4();
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    penmesh_e2e::draw_stroke(&mut ws, stroke, &stroke_samples(10), 10).await;
    let mut socket = tokio::net::TcpStream::connect(("127.0.0.1", proxy.port)).await.unwrap();
    let head = format!(
        "PUT /v1/strokes/{stroke}/mesh HTTP/1.1\r\nhost: localhost\r\n\
         authorization: Bearer {}\r\nx-penmesh-key: {}\r\ncontent-length: 1000\r\n\r\nglTF",
        session.token, session.key
    );
    socket.write_all(head.as_bytes()).await.unwrap();
    let mut answer = vec![0u8; 64];
    let n = tokio::time::timeout(Duration::from_secs(5), socket.read(&mut answer))
        .await
        .expect("answered within the request timeout")
        .unwrap();
    let status = String::from_utf8_lossy(&answer[..n]).to_string();
    assert!(status.starts_with("HTTP/1.1 408"), "{status}");
}
