//! A connection speaks the version its `hello` names, and nothing later (`docs/protocol.md`,
//! "Versions"): a version-4 connection, JSON or binary, is refused a version-5 message
//! (`set_placement`, a `stroke_begin` with a `placement`) and a binary frame of version 5 with
//! `unknown_message`, and nothing changes. Every binary frame the proxy sends it carries
//! byte 4, the errors before `welcome` included (issue 52, items 1 and 3).

use futures_util::StreamExt;
use penmesh::Placement;
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Hello, Ping, PointBatch, Points, ServerMessage,
    SetPlacement, StrokeBegin, StrokeEnd, StrokeId, decode_server, encode_client, encode_client_as,
    encode_client_json,
};
use penmesh_e2e::{TestProxy, TestSession, WsClient, new_key, spawn_proxy, stroke_samples};
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

fn standing() -> Placement {
    Placement::new([
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 40.0, 1.0,
    ])
    .unwrap()
}

fn hello(protocol: u16, key: Option<String>) -> ClientMessage {
    ClientMessage::Hello(Hello {
        protocol,
        client: "version-4 client".into(),
        name: Some("old".into()),
        resume: vec![],
        key,
    })
}

fn begin(stroke: StrokeId, placement: Option<Placement>) -> ClientMessage {
    ClientMessage::StrokeBegin(StrokeBegin {
        stroke,
        brush: Default::default(),
        device: None,
        params: None,
        placement,
        solid: None,
    })
}

/// How a client of version 4 sends: JSON text, or binary frames with byte 4.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Form {
    Json,
    Binary,
}

async fn send_as(ws: &mut WsClient, form: Form, msg: &ClientMessage) {
    let frame = match form {
        Form::Json => Message::Text(encode_client_json(msg).into()),
        Form::Binary => {
            Message::Binary(encode_client_as(msg, 4).expect("version 4 says it").into())
        }
    };
    futures_util::SinkExt::send(&mut ws.ws, frame).await.unwrap();
}

/// The next message (session events skipped); a binary frame's version byte with it.
async fn next_with_version(ws: &mut WsClient) -> (Option<u8>, ServerMessage) {
    loop {
        let frame = tokio::time::timeout(std::time::Duration::from_secs(10), ws.ws.next())
            .await
            .expect("a frame in time")
            .expect("open")
            .unwrap();
        let (version, msg) = match frame {
            Message::Binary(bytes) => (Some(bytes[0]), decode_server(&bytes, usize::MAX).unwrap()),
            Message::Text(text) => {
                (None, penmesh::protocol::decode_server_json(&text, usize::MAX).unwrap())
            }
            Message::Close(close) => panic!("closed: {close:?}"),
            _ => continue,
        };
        if !penmesh_e2e::is_session_event(&msg) {
            return (version, msg);
        }
    }
}

async fn expect_error(ws: &mut WsClient, code: ErrorCode) -> ErrorMessage {
    loop {
        if let (_, ServerMessage::Error(err)) = next_with_version(ws).await {
            assert_eq!(err.code, code, "{err:?}");
            return err;
        }
    }
}

/// A version-4 client draws a stroke on the board and has its `stroke_done`.
async fn old_client_with_a_stroke(
    proxy: &TestProxy,
    session: &TestSession,
    form: Form,
) -> (WsClient, StrokeId) {
    let mut ws = proxy.connect(session).await;
    send_as(&mut ws, form, &hello(4, Some(new_key()))).await;
    let (_, ServerMessage::Welcome(welcome)) = next_with_version(&mut ws).await else {
        panic!("no welcome")
    };
    assert_eq!(welcome.protocol, 4);
    let stroke = Uuid::new_v4();
    let samples = stroke_samples(30);
    send_as(&mut ws, form, &begin(stroke, None)).await;
    send_as(
        &mut ws,
        form,
        &ClientMessage::Points(Points { stroke, seq: 0, points: PointBatch(samples.clone()) }),
    )
    .await;
    send_as(
        &mut ws,
        form,
        &ClientMessage::StrokeEnd(StrokeEnd { stroke, n_points: samples.len() as u64 }),
    )
    .await;
    loop {
        match next_with_version(&mut ws).await {
            (_, ServerMessage::StrokeDone(done)) if done.stroke == stroke => break,
            (_, ServerMessage::Error(err)) => panic!("{err:?}"),
            _ => {}
        }
    }
    (ws, stroke)
}

/// The stroke's placement history: one entry (its begin, at the identity) when nothing moved it.
async fn placements(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) -> usize {
    let history = proxy.get_json(&format!("/v1/strokes/{stroke}/placements"), session).await;
    history["placements"].as_array().unwrap().len()
}

/// A version-4 connection, JSON or binary, cannot place a stroke: `set_placement` and a
/// `stroke_begin` with a placement are `unknown_message`, and so is any binary frame of
/// version 5 (a ping, or a `set_placement`). The stroke stays on the board, nothing new is
/// stored, and the connection goes on (its ping is answered).
#[tokio::test]
async fn a_version_4_connection_is_refused_version_5_messages_and_frames() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    for form in [Form::Json, Form::Binary] {
        let (mut ws, stroke) = old_client_with_a_stroke(&proxy, &session, form).await;
        let set = ClientMessage::SetPlacement(SetPlacement { stroke, placement: standing() });
        if form == Form::Json {
            send_as(&mut ws, form, &set).await;
            let err = expect_error(&mut ws, ErrorCode::UnknownMessage).await;
            assert!(err.message.contains("set_placement"), "{err:?}");
            let placed = Uuid::new_v4();
            send_as(&mut ws, form, &begin(placed, Some(standing()))).await;
            let err = expect_error(&mut ws, ErrorCode::UnknownMessage).await;
            assert!(err.message.contains("stroke_begin.placement"), "{err:?}");
            let missing = proxy.get(&format!("/v1/strokes/{placed}/raw"), &session).send().await;
            assert_eq!(missing.unwrap().status(), 404, "{form:?}: the placed stroke was begun");
        }
        // Version-5 frames: the message itself, and one version 4 has too.
        for msg in [set.clone(), ClientMessage::Ping(Ping { nonce: 5 })] {
            ws.send_binary(encode_client_as(&msg, 5).unwrap()).await;
            let err = expect_error(&mut ws, ErrorCode::UnknownMessage).await;
            assert!(err.message.contains("version 5"), "{err:?}");
        }
        send_as(&mut ws, form, &ClientMessage::Ping(Ping { nonce: 6 })).await;
        let (version, msg) = next_with_version(&mut ws).await;
        assert_eq!(msg, ServerMessage::Pong(Ping { nonce: 6 }), "{form:?}");
        assert_eq!(version, (form == Form::Binary).then_some(4));
        assert_eq!(placements(&proxy, &session, stroke).await, 1, "{form:?}: the stroke moved");
        let info = proxy.stroke_info(&session, stroke).await;
        assert_eq!(info["placement"]["matrix"], serde_json::json!(Placement::IDENTITY.matrix()));
    }
}

/// A version-4 binary client's errors before `welcome` come with byte 4, as every later frame
/// does: a first frame that is not `hello`, an unsupported `hello.protocol`, a malformed key,
/// name or client, and a resume list past the limit.
#[tokio::test]
async fn errors_before_welcome_carry_the_clients_version_byte() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let long_resume = ClientMessage::Hello(Hello {
        resume: (0..17).map(|_| Uuid::new_v4()).collect(),
        ..match hello(4, None) {
            ClientMessage::Hello(h) => h,
            _ => unreachable!(),
        }
    });
    let with = |f: fn(&mut Hello)| {
        let ClientMessage::Hello(mut h) = hello(4, Some(new_key())) else { unreachable!() };
        f(&mut h);
        ClientMessage::Hello(h)
    };
    let cases: Vec<(ClientMessage, ErrorCode)> = vec![
        (ClientMessage::Ping(Ping { nonce: 1 }), ErrorCode::Protocol),
        (hello(3, None), ErrorCode::Protocol),
        (with(|h| h.key = Some("short".into())), ErrorCode::Malformed),
        (with(|h| h.name = Some("a\0b".into())), ErrorCode::Malformed),
        (with(|h| h.client = "x".repeat(201)), ErrorCode::Malformed),
        (long_resume, ErrorCode::TooManyOpenStrokes),
    ];
    for (first, code) in cases {
        let mut ws = proxy.connect(&session).await;
        send_as(&mut ws, Form::Binary, &first).await;
        let (version, msg) = next_with_version(&mut ws).await;
        let ServerMessage::Error(err) = msg else { panic!("{first:?}: {msg:?}") };
        assert_eq!(err.code, code, "{first:?}: {err:?}");
        assert_eq!(version, Some(4), "{first:?}: the error's version byte");
    }
    // A frame of a version not served is answered in the current one: the client's is unknown.
    let mut ws = proxy.connect(&session).await;
    let mut frame = encode_client(&hello(5, None));
    frame[0] = 9;
    ws.send_binary(frame).await;
    let (version, msg) = next_with_version(&mut ws).await;
    assert!(
        matches!(msg, ServerMessage::Error(ref e) if e.code == ErrorCode::Malformed),
        "{msg:?}"
    );
    assert_eq!(version, Some(penmesh::protocol::PROTOCOL_VERSION as u8));
    // A hello whose frame says another version than it names is refused, and a good one
    // follows on the same connection.
    let mut ws = proxy.connect(&session).await;
    let mut frame = encode_client_as(&hello(5, None), 5).unwrap();
    frame[0] = 4;
    ws.send_binary(frame).await;
    let err = expect_error(&mut ws, ErrorCode::Protocol).await;
    assert!(err.message.contains("hello.protocol is 5"), "{err:?}");
    send_as(&mut ws, Form::Binary, &hello(4, None)).await;
    let (version, msg) = next_with_version(&mut ws).await;
    assert!(matches!(msg, ServerMessage::Welcome(ref w) if w.protocol == 4), "{msg:?}");
    assert_eq!(version, Some(4));
}
