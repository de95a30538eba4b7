use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, Ping, ServerMessage, StrokeBegin,
    encode_client,
};
use penmesh_e2e::{WsClient, spawn_proxy, stroke_samples};
use uuid::Uuid;

/// The connection still answers after an error.
async fn still_alive(ws: &mut WsClient) {
    ws.send(&ClientMessage::Ping(Ping { nonce: 99 })).await;
    ws.recv_until(|m| matches!(m, ServerMessage::Pong(p) if p.nonce == 99)).await;
}

async fn ready(proxy: &penmesh_e2e::TestProxy) -> (penmesh_e2e::TestSession, WsClient) {
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    (session, ws)
}

/// A connection with one open stroke that has `n` samples.
async fn with_stroke(proxy: &penmesh_e2e::TestProxy, n: usize) -> (WsClient, Uuid) {
    let (_, mut ws) = ready(proxy).await;
    let stroke = Uuid::new_v4();
    ws.begin(stroke).await;
    ws.points(stroke, 0, &stroke_samples(n)).await;
    ws.wait_ack(stroke, n as u64).await;
    (ws, stroke)
}

#[tokio::test]
async fn malformed_binary_is_refused_and_the_connection_goes_on() {
    let proxy = spawn_proxy().await;
    let (_, mut ws) = ready(&proxy).await;
    ws.send_binary(vec![PROTOCOL_VERSION as u8, 2, 0xff, 0xff, 0xff, 0xff, 0xff]).await;
    let err = ws.expect_error(ErrorCode::Malformed).await;
    assert!(!err.message.is_empty());
    ws.send_binary(vec![]).await;
    ws.expect_error(ErrorCode::Malformed).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn bad_json_is_refused_and_the_connection_goes_on() {
    let proxy = spawn_proxy().await;
    let (_, mut ws) = ready(&proxy).await;
    ws.send_text("{this is not json").await;
    ws.expect_error(ErrorCode::BadJson).await;
    ws.send_text(r#"{"points":{"stroke":"not-a-uuid","seq":0,"points":[]}}"#).await;
    ws.expect_error(ErrorCode::BadJson).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn unknown_messages_are_refused_in_json_and_binary() {
    let proxy = spawn_proxy().await;
    let (_, mut ws) = ready(&proxy).await;
    ws.send_text(r#"{"dance":{"steps":3}}"#).await;
    let err = ws.expect_error(ErrorCode::UnknownMessage).await;
    assert!(err.message.contains("dance"), "{}", err.message);
    // Binary: a valid version byte, then a variant index no message has.
    ws.send_binary(vec![PROTOCOL_VERSION as u8, 77]).await;
    ws.expect_error(ErrorCode::UnknownMessage).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn non_finite_coordinates_are_refused_naming_the_sample() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    for bad in [f64::NAN, f64::INFINITY] {
        let mut batch = stroke_samples(8)[5..].to_vec();
        batch[1].x = bad;
        ws.points(stroke, 5, &batch).await;
        let err = ws.expect_error(ErrorCode::BadSample).await;
        assert!(err.message.contains("sample 6"), "{}", err.message);
        assert_eq!(err.stroke, Some(stroke));
    }
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn pressure_outside_the_unit_range_is_refused() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    let mut ws = {
        ws.json = true;
        ws
    };
    ws.send_text(&format!(
        r#"{{"points":{{"stroke":"{stroke}","seq":5,"points":[[1,1,100,1.5]]}}}}"#
    ))
    .await;
    let err = ws.expect_error(ErrorCode::BadSample).await;
    assert!(err.message.contains("pressure"), "{}", err.message);
    assert!(err.message.contains("sample 5"), "{}", err.message);
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn time_going_backwards_is_refused_within_and_across_batches() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    let last_t = stroke_samples(5)[4].t;
    ws.points(stroke, 5, &[Sample::new(0.0, 0.0, last_t - 1.0, 0.5)]).await;
    let err = ws.expect_error(ErrorCode::BadSample).await;
    assert!(err.message.contains("time goes backwards"), "{}", err.message);
    ws.points(
        stroke,
        5,
        &[Sample::new(0.0, 0.0, last_t + 10.0, 0.5), Sample::new(0.0, 0.0, last_t + 5.0, 0.5)],
    )
    .await;
    let err = ws.expect_error(ErrorCode::BadSample).await;
    assert!(err.message.contains("sample 6"), "{}", err.message);
    // Nothing of the refused batches was taken: seq 5 is still next.
    ws.points(stroke, 5, &[Sample::new(0.0, 0.0, last_t + 10.0, 0.5)]).await;
    ws.wait_ack(stroke, 6).await;
}

#[tokio::test]
async fn points_for_an_unknown_or_finished_stroke_are_refused() {
    let proxy = spawn_proxy().await;
    let (_, mut ws) = ready(&proxy).await;
    let unknown = Uuid::new_v4();
    ws.points(unknown, 0, &stroke_samples(3)).await;
    let err = ws.expect_error(ErrorCode::UnknownStroke).await;
    assert_eq!(err.stroke, Some(unknown));

    let done = Uuid::new_v4();
    penmesh_e2e::draw_stroke(&mut ws, done, &stroke_samples(10), 5).await;
    ws.points(done, 10, &stroke_samples(12)[10..]).await;
    ws.expect_error(ErrorCode::StrokeFinished).await;
    ws.end(done, 12).await;
    ws.expect_error(ErrorCode::StrokeFinished).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn a_seq_gap_is_refused_naming_the_expected_seq() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    ws.points(stroke, 7, &stroke_samples(9)[7..]).await;
    let err = ws.expect_error(ErrorCode::SeqGap).await;
    assert!(err.message.contains("expected seq 5"), "{}", err.message);
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn a_wrong_count_at_stroke_end_is_refused_and_the_stroke_stays_open() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    ws.end(stroke, 6).await;
    let err = ws.expect_error(ErrorCode::CountMismatch).await;
    assert!(err.message.contains('5') && err.message.contains('6'), "{}", err.message);
    ws.end(stroke, 5).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
}

#[tokio::test]
async fn a_stroke_id_of_another_session_is_a_conflict_and_a_bad_brush_is_refused() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 3).await;
    let (_, mut other) = ready(&proxy).await;
    other.begin(stroke).await;
    other.expect_error(ErrorCode::StrokeConflict).await;
    let brush = penmesh::Brush { pressure_response: 3.0, ..Default::default() };
    other
        .send(&ClientMessage::StrokeBegin(StrokeBegin {
            stroke: Uuid::new_v4(),
            brush,
            device: None,
            params: None,
        }))
        .await;
    let err = other.expect_error(ErrorCode::BadBrush).await;
    assert!(err.message.contains("pressure_response"), "{}", err.message);
    still_alive(&mut other).await;
    // The first connection did not notice.
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn a_missing_hello_closes_with_a_protocol_error() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.send(&ClientMessage::Ping(Ping { nonce: 1 })).await;
    ws.expect_error(ErrorCode::Protocol).await;
    assert_eq!(ws.expect_close().await, Some(1002));
}

#[tokio::test]
async fn a_wrong_protocol_version_closes_and_a_second_hello_does_not() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.send_binary(encode_client(&ClientMessage::Hello(Hello {
        protocol: 999,
        client: "old".into(),
        name: None,
        resume: vec![],
        key: None,
    })))
    .await;
    let err = ws.expect_error(ErrorCode::Protocol).await;
    assert!(err.message.contains("999"), "{}", err.message);
    assert_eq!(ws.expect_close().await, Some(1002));

    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    ws.send(&ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: "again".into(),
        name: None,
        resume: vec![],
        key: None,
    }))
    .await;
    ws.expect_error(ErrorCode::Protocol).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn bad_input_on_one_connection_does_not_disturb_another() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut good = proxy.connect(&session).await;
    good.hello(vec![]).await;
    let mut bad = proxy.connect(&session).await;
    bad.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    let samples = stroke_samples(50);
    good.begin(stroke).await;
    good.points(stroke, 0, &samples[..25]).await;
    for _ in 0..10 {
        bad.send_binary(vec![PROTOCOL_VERSION as u8, 0xff, 0xff]).await;
        bad.send_text("nope").await;
    }
    good.points(stroke, 25, &samples[25..]).await;
    good.wait_ack(stroke, 50).await;
    for _ in 0..20 {
        bad.recv().await;
    }
    still_alive(&mut bad).await;
}
