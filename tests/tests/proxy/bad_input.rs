use std::time::Duration;

use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Hello, PROTOCOL_VERSION, Ping, ServerMessage,
    StrokeBegin, encode_client,
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
    let bad_response = penmesh::Brush { pressure_response: 3.0, ..Default::default() };
    let bad_colour = penmesh::Brush { color: Some(0x1_00_00_00), ..Default::default() };
    for (brush, field) in [(bad_response, "pressure_response"), (bad_colour, "color")] {
        other
            .send(&ClientMessage::StrokeBegin(StrokeBegin {
                stroke: Uuid::new_v4(),
                brush,
                device: None,
                params: None,
                placement: None,
                solid: None,
            }))
            .await;
        let err = other.expect_error(ErrorCode::BadBrush).await;
        assert!(err.message.contains(field), "{}", err.message);
    }
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

/// Everything the proxy answered about `stroke` until it was quiet for half a second: its acks
/// and its errors.
async fn answers_about(ws: &mut WsClient, stroke: Uuid) -> (Vec<u64>, Vec<ErrorMessage>) {
    let (mut acks, mut errors) = (Vec::new(), Vec::new());
    while let Ok(msg) = tokio::time::timeout(Duration::from_millis(500), ws.recv()).await {
        match msg {
            ServerMessage::Ack(ack) if ack.stroke == stroke => acks.push(ack.upto_seq),
            ServerMessage::Error(err) if err.stroke == Some(stroke) => errors.push(err),
            _ => {}
        }
    }
    (acks, errors)
}

fn hello_named(ws: &WsClient, client: &str, name: Option<&str>) -> ClientMessage {
    ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: client.into(),
        name: name.map(str::to_string),
        resume: vec![],
        key: ws.key.clone(),
    })
}

#[tokio::test]
async fn a_nul_byte_in_a_begin_is_refused_and_the_batch_sent_after_it_is_not_acknowledged() {
    // Arrange: PostgreSQL cannot store a NUL byte in text; SQLite could. A client streams: the
    // first batch follows the begin at once.
    let proxy = spawn_proxy().await;
    let (session, mut ws) = ready(&proxy).await;
    let stroke = Uuid::new_v4();
    let begin = StrokeBegin {
        stroke,
        brush: Default::default(),
        device: Some("wacom\0ctl".into()),
        params: None,
        placement: None,
        solid: None,
    };

    // Act
    ws.send(&ClientMessage::StrokeBegin(begin)).await;
    ws.points(stroke, 0, &stroke_samples(8)).await;
    let (acks, errors) = answers_about(&mut ws, stroke).await;

    // Assert: the begin is refused naming the field, nothing of the stroke is acknowledged,
    // and the stroke does not exist.
    assert!(acks.is_empty(), "acknowledged {acks:?} of a stroke whose begin was refused");
    let refusal = errors.first().expect("the begin is refused");
    assert_eq!(refusal.code, ErrorCode::Malformed, "{errors:?}");
    assert!(refusal.message.contains("stroke_begin.device"), "{}", refusal.message);
    assert!(refusal.message.contains("NUL"), "{}", refusal.message);
    let raw = proxy.get(&format!("/v1/strokes/{stroke}/raw"), &session).send().await.unwrap();
    assert_eq!(raw.status(), 404);
    // The same stroke begun with a good device is drawn as usual.
    ws.begin(stroke).await;
    ws.wait_ack(stroke, 0).await;
    ws.points(stroke, 0, &stroke_samples(8)).await;
    ws.wait_ack(stroke, 8).await;
}

#[tokio::test]
async fn text_of_a_hello_with_a_nul_byte_or_too_long_is_refused_naming_the_field() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    let long = "n".repeat(penmesh::protocol::MAX_NAME_CHARS + 1);
    let cases = [
        ("penmesh-e2e", Some("Ada\0"), "hello.name", "NUL"),
        ("penmesh\0e2e", None, "hello.client", "NUL"),
        ("penmesh-e2e", Some(long.as_str()), "hello.name", "characters"),
        (long.as_str(), None, "hello.client", "characters"),
    ];
    for (client, name, field, what) in cases {
        ws.send(&hello_named(&ws, client, name)).await;
        let err = ws.expect_error(ErrorCode::Malformed).await;
        assert!(err.message.contains(field), "{}", err.message);
        assert!(err.message.contains(what), "{}", err.message);
    }
    // The connection goes on: a good hello is welcomed.
    let name = "n".repeat(penmesh::protocol::MAX_NAME_CHARS);
    ws.send(&hello_named(&ws, "penmesh-e2e", Some(&name))).await;
    ws.recv_until(|m| matches!(m, ServerMessage::Welcome(_))).await;
    still_alive(&mut ws).await;
}

#[tokio::test]
async fn huge_coordinates_are_refused_naming_the_sample_and_the_bound() {
    let proxy = spawn_proxy().await;
    let (mut ws, stroke) = with_stroke(&proxy, 5).await;
    for (x, y) in [(1e50, 0.0), (0.0, -1e50), (1e6 + 1.0, 0.0)] {
        let mut batch = stroke_samples(8)[5..].to_vec();
        batch[1].x = x;
        batch[1].y = y;
        ws.points(stroke, 5, &batch).await;
        let err = ws.expect_error(ErrorCode::BadSample).await;
        assert!(err.message.contains("sample 6"), "{}", err.message);
        assert!(err.message.contains("1000000"), "{}", err.message);
        assert_eq!(err.stroke, Some(stroke));
    }
    // Nothing of the refused batches was taken.
    ws.points(stroke, 5, &stroke_samples(8)[5..]).await;
    ws.wait_ack(stroke, 8).await;
}

#[tokio::test]
async fn a_stroke_spanning_the_coordinate_bound_gets_its_mesh() {
    // Arrange: the farthest a stroke may reach, from one corner of the bound to the other.
    let proxy = spawn_proxy().await;
    let (session, mut ws) = ready(&proxy).await;
    let bound = penmesh::MAX_COORDINATE;
    let samples: Vec<Sample> = (0..20)
        .map(|i| {
            let f = i as f64 / 19.0;
            let s =
                Sample::new(-bound + 2.0 * bound * f, bound - 2.0 * bound * f * f, i as f64, 0.5);
            penmesh::protocol::quantize_sample(&s)
        })
        .collect();
    let stroke = Uuid::new_v4();
    penmesh_e2e::draw_stroke(&mut ws, stroke, &samples, 5).await;

    // Act
    let response = proxy.build_mesh(&session, stroke).send().await.unwrap();

    // Assert
    let status = response.status();
    let body = response.text().await.unwrap();
    assert_eq!(status, 200, "{body}");
}

#[tokio::test]
async fn the_mesh_of_a_stroke_stored_with_huge_coordinates_is_refused_not_a_500() {
    let proxy = spawn_proxy().await;
    let (session, mut ws) = ready(&proxy).await;
    // One sample far out, and a whole stroke far out.
    let damages: [fn(usize, &mut Sample); 2] =
        [|i, s| s.x = 1e50 * (1.0 + i as f64), |i, s| s.x = if i == 4 { 1e50 } else { s.x }];
    for damage in damages {
        // Arrange: a done stroke whose stored samples hold x = 1e50 or more, as an earlier
        // version, which did not bound coordinates, stored them (samples as f64, layout 0).
        let (stroke, mut samples) = (Uuid::new_v4(), stroke_samples(10));
        penmesh_e2e::draw_stroke(&mut ws, stroke, &samples, 10).await;
        samples.iter_mut().enumerate().for_each(|(i, s)| damage(i, s));
        let blob: Vec<u8> =
            samples.iter().flat_map(|s| [s.x, s.y, s.t, s.p]).flat_map(f64::to_le_bytes).collect();
        sqlx::any::install_default_drivers();
        let pool = sqlx::AnyPool::connect(&proxy.db.url).await.unwrap();
        let changed = sqlx::query(
            "UPDATE stroke_chunks SET layout = 0, data = $1 \
             WHERE stroke_id = $2 AND seq = 0 AND n = 10",
        )
        .bind(blob)
        .bind(stroke.to_string())
        .execute(&pool)
        .await
        .unwrap();
        assert_eq!(changed.rows_affected(), 1, "the stroke is one chunk row");
        pool.close().await;

        // Act
        let response = proxy.build_mesh(&session, stroke).send().await.unwrap();

        // Assert: refused with what is wrong, neither an internal error nor a mesh.
        let status = response.status();
        let body: serde_json::Value = response.json().await.unwrap();
        assert_eq!(status, 409, "{body}");
        let message = body["message"].as_str().unwrap();
        assert!(message.contains("sample") && message.contains("1000000"), "{message}");
    }
}
