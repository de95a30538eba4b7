//! The wire codec: round trips of every message in both encodings, the JSON shape, refusal of
//! bad frames without panics, quantisation bounds, and bytes per sample on real pen data.
//!
//! `cargo test -p penmesh --test codec -- --nocapture` prints the bytes-per-sample table.

use penmesh::data_sets::{DataSet, SIGCOMP2011_DUTCH, SVC2004};
use penmesh::protocol::*;
use penmesh::{AcutsParams, Brush, Sample, resample};
use proptest::prelude::*;
use uuid::Uuid;

const LIMIT: usize = MAX_FRAME_BYTES_DEFAULT;

fn id(n: u128) -> Uuid {
    Uuid::from_u128(0x67e5_5044_10b1_426f_9247_bb68_0e5f_e0c8 ^ n)
}

fn samples(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            quantize_sample(&Sample::new(
                100.0 + 3.0 * f + (f * 0.3).sin(),
                50.0 - 2.0 * f,
                8.0 * f,
                0.5 + 0.4 * (f * 0.1).cos(),
            ))
        })
        .collect()
}

fn client_messages() -> Vec<ClientMessage> {
    vec![
        ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-test 0.1".into(),
            name: Some("Ada".into()),
            resume: vec![id(1), id(2)],
            key: Some("0123456789abcdef0123456789abcdef".into()),
        }),
        ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: String::new(),
            name: None,
            resume: vec![],
            key: None,
        }),
        ClientMessage::StrokeBegin(StrokeBegin {
            stroke: id(3),
            brush: Brush::default(),
            device: Some("wacom ctl-671".into()),
            params: Some(AcutsParams::default()),
            placement: None,
            solid: None,
        }),
        ClientMessage::StrokeBegin(StrokeBegin {
            stroke: id(3),
            brush: Brush {
                size: 3.5,
                pressure_response: 1.0,
                min_radius: 0.1,
                color: Some(0x3366cc),
            },
            device: None,
            params: None,
            placement: Some(standing()),
            solid: None,
        }),
        ClientMessage::Points(Points { stroke: id(3), seq: 0, points: PointBatch(samples(1)) }),
        ClientMessage::Points(Points { stroke: id(3), seq: 77, points: PointBatch(samples(32)) }),
        ClientMessage::Points(Points { stroke: id(3), seq: 9, points: PointBatch(vec![]) }),
        ClientMessage::StrokeEnd(StrokeEnd { stroke: id(3), n_points: 109 }),
        ClientMessage::Ping(Ping { nonce: u64::MAX }),
        ClientMessage::RemoveStroke(StrokeRef { stroke: id(3) }),
        ClientMessage::RestoreStroke(StrokeRef { stroke: id(3) }),
        ClientMessage::Rename(Rename { name: "Ada Lovelace".into() }),
        ClientMessage::SetPlacement(SetPlacement { stroke: id(3), placement: standing() }),
        ClientMessage::SetSolid(SetSolid {
            stroke: id(3),
            solid: penmesh::Solid::new(penmesh::SolidKind::Hole, Some(12.5)).unwrap(),
        }),
    ]
}

/// The front plane standing on the board, moved and mirrored: a placement off the identity.
fn standing() -> penmesh::Placement {
    penmesh::Placement::new([
        -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.1, 2.5, -3.0, 1.0,
    ])
    .unwrap()
}

fn server_messages() -> Vec<ServerMessage> {
    vec![
        ServerMessage::PeerPlacement(PeerPlacement {
            participant: id(11),
            stroke: id(3),
            placement: standing(),
        }),
        ServerMessage::Welcome(Welcome {
            protocol: PROTOCOL_VERSION,
            session: id(10),
            participant: id(11),
            resume: vec![
                ResumeState { stroke: id(1), next_seq: 40, status: StrokeStatus::Open },
                ResumeState { stroke: id(2), next_seq: 0, status: StrokeStatus::Unknown },
            ],
        }),
        ServerMessage::Ack(Ack { stroke: id(3), upto_seq: 64 }),
        ServerMessage::Retained(Retained {
            stroke: id(3),
            first: 5,
            points: PointBatch(samples(7)),
        }),
        ServerMessage::StrokeDone(StrokeDone {
            stroke: id(3),
            n_retained: 12,
            url: "/v1/strokes/x/simplified".into(),
        }),
        ServerMessage::Pong(Ping { nonce: 7 }),
        ServerMessage::Error(ErrorMessage {
            code: ErrorCode::BadSample,
            message: "sample 3: x is not a finite number (NaN)".into(),
            stroke: Some(id(3)),
        }),
        ServerMessage::Error(ErrorMessage {
            code: ErrorCode::NotOwner,
            message: "stroke x was begun by another participant".into(),
            stroke: Some(id(3)),
        }),
        ServerMessage::Error(ErrorMessage {
            code: ErrorCode::Lagged,
            message: "resync".into(),
            stroke: None,
        }),
        ServerMessage::PeerJoined(PeerJoined { participant: id(12), name: "Bob".into() }),
        ServerMessage::PeerLeft(PeerLeft { participant: id(12) }),
        ServerMessage::PeerStrokeBegin(PeerStrokeBegin {
            participant: id(12),
            stroke: id(4),
            brush: Brush::default(),
        }),
        ServerMessage::PeerRetained(PeerRetained {
            participant: id(12),
            stroke: id(4),
            first: 0,
            points: PointBatch(samples(3)),
        }),
        ServerMessage::PeerStrokeDone(PeerStrokeDone {
            participant: id(12),
            stroke: id(4),
            n_retained: 3,
            url: "/v1/strokes/y/simplified".into(),
        }),
        ServerMessage::PeerMesh(PeerMesh {
            participant: id(12),
            stroke: id(4),
            url: "/v1/strokes/y/mesh".into(),
        }),
        ServerMessage::StrokeRemoved(StrokeRemoval {
            participant: id(12),
            stroke: id(4),
            by: id(12),
        }),
        ServerMessage::StrokeRestored(StrokeRemoval {
            participant: id(12),
            stroke: id(4),
            by: id(12),
        }),
        ServerMessage::PeerRenamed(PeerJoined { participant: id(12), name: "Grace".into() }),
        ServerMessage::PeerSolid(PeerSolid {
            participant: id(12),
            stroke: id(4),
            solid: penmesh::Solid::new(penmesh::SolidKind::Filled, Some(0.1 + 0.2)).unwrap(),
        }),
    ]
}

#[test]
fn every_client_message_round_trips_in_both_encodings() {
    for msg in client_messages() {
        assert_eq!(decode_client(&encode_client(&msg), LIMIT).unwrap(), msg);
        assert_eq!(decode_client_json(&encode_client_json(&msg), LIMIT).unwrap(), msg);
    }
}

#[test]
fn every_server_message_round_trips_in_both_encodings() {
    for msg in server_messages() {
        assert_eq!(decode_server(&encode_server(&msg), LIMIT).unwrap(), msg);
        assert_eq!(decode_server_json(&encode_server_json(&msg), LIMIT).unwrap(), msg);
    }
}

#[test]
fn json_points_have_the_documented_shape() {
    let msg = ClientMessage::Points(Points {
        stroke: id(0),
        seq: 0,
        points: PointBatch(vec![Sample::new(1.0, 2.5, 0.0, 0.5), Sample::new(3.0, -4.0, 8.0, 1.0)]),
    });
    let json = encode_client_json(&msg);
    assert_eq!(
        json,
        r#"{"points":{"stroke":"67e55044-10b1-426f-9247-bb680e5fe0c8","seq":0,"points":[[1.0,2.5,0.0,0.5],[3.0,-4.0,8.0,1.0]]}}"#
    );
    assert_eq!(decode_client_json(&json, LIMIT).unwrap(), msg);
}

/// The participant key of protocol 3: optional in JSON (an older page's hello without it still
/// decodes, keyless), a field of its own in binary, and checked for its form.
#[test]
fn hello_carries_the_participant_key_in_both_encodings() {
    let key = "Zx-_0123456789abcdefghijklmnopqrstu";
    let text = format!(r#"{{"hello":{{"protocol":4,"client":"web","key":"{key}"}}}}"#);
    let ClientMessage::Hello(hello) = decode_client_json(&text, LIMIT).unwrap() else {
        panic!("not hello")
    };
    assert_eq!(hello.key.as_deref(), Some(key));
    let ClientMessage::Hello(keyless) =
        decode_client_json(r#"{"hello":{"protocol":4,"client":"web"}}"#, LIMIT).unwrap()
    else {
        panic!("not hello")
    };
    assert_eq!(keyless.key, None);
    // Binary: a field of its own; a keyed hello is longer than a keyless one by the key and
    // its one-byte length prefix.
    let with = encode_client(&ClientMessage::Hello(hello.clone()));
    let without = encode_client(&ClientMessage::Hello(Hello { key: None, ..hello }));
    assert_eq!(with.len(), without.len() + 1 + key.len());
    assert_eq!(PROTOCOL_VERSION, 6);

    assert_eq!(check_participant_key(key), Ok(()));
    assert_eq!(check_participant_key(&"a".repeat(KEY_MIN_CHARS)), Ok(()));
    assert_eq!(check_participant_key(&"a".repeat(KEY_MAX_CHARS)), Ok(()));
    for (bad, why) in [
        ("", "0 characters"),
        ("0123456789abcdef", "16 characters"),
        (&"a".repeat(KEY_MAX_CHARS + 1), "129 characters"),
        ("0123456789abcdef0123456789abcde/", "'/'"),
        ("0123456789abcdef 0123456789abcdef", "' '"),
        ("0123456789abcdef0123456789abcdeé", "'é'"),
    ] {
        let err = check_participant_key(bad).expect_err(bad);
        assert!(err.contains(why), "{bad:?}: {err}");
    }
}

#[test]
fn json_keeps_samples_exact_and_accepts_integers() {
    let exact = Sample::new(0.1, 1.0 / 3.0, 12.345_678_9, 0.123_456_789);
    let msg =
        ClientMessage::Points(Points { stroke: id(0), seq: 5, points: PointBatch(vec![exact]) });
    assert_eq!(decode_client_json(&encode_client_json(&msg), LIMIT).unwrap(), msg);
    let text = r#"{"points":{"stroke":"67e55044-10b1-426f-9247-bb680e5fe0c8","seq":1,"points":[[1,2,3,0]]}}"#;
    let ClientMessage::Points(points) = decode_client_json(text, LIMIT).unwrap() else {
        panic!("not points")
    };
    assert_eq!(points.points.0, vec![Sample::new(1.0, 2.0, 3.0, 0.0)]);
}

#[test]
fn json_refuses_unknown_messages_bad_text_and_oversized_frames() {
    for text in [r#"{"nope":{}}"#, r#""nope""#, "[1, 2]", "42"] {
        assert!(
            matches!(decode_client_json(text, LIMIT), Err(CodecError::UnknownMessage(_))),
            "{text}"
        );
    }
    for text in [
        r#"{"ping":{}}"#,
        r#"{"ping":{"nonce":-1}}"#,
        "not json",
        "",
        r#"{"points":{"stroke":"x","seq":0,"points":[]}}"#,
        r#"{"points":{"stroke":"67e55044-10b1-426f-9247-bb680e5fe0c8","seq":0,"points":[[1,2,3]]}}"#,
    ] {
        assert!(matches!(decode_client_json(text, LIMIT), Err(CodecError::BadJson(_))), "{text}");
    }
    let big = format!(r#"{{"ping":{{"nonce":{}}}}}"#, "1".repeat(100));
    assert_eq!(
        decode_client_json(&big, 50),
        Err(CodecError::TooLarge { size: big.len(), limit: 50 })
    );
}

#[test]
fn binary_refuses_empty_oversized_bad_version_trailing_and_unknown_frames() {
    let frame = encode_client(&ClientMessage::Ping(Ping { nonce: 1 }));
    assert_eq!(decode_client(&[], LIMIT), Err(CodecError::Empty));
    assert_eq!(
        decode_client(&frame, frame.len() - 1),
        Err(CodecError::TooLarge { size: frame.len(), limit: frame.len() - 1 })
    );
    let mut bad_version = frame.clone();
    bad_version[0] = 99;
    assert_eq!(decode_client(&bad_version, LIMIT), Err(CodecError::Version(99)));
    let mut trailing = frame.clone();
    trailing.push(0);
    assert!(
        matches!(decode_client(&trailing, LIMIT), Err(CodecError::Malformed(m)) if m.contains("trailing"))
    );
    // Variant indices 10 and 200 are no client message.
    for index in [10, 200] {
        assert!(matches!(
            decode_client(&[PROTOCOL_VERSION as u8, index], LIMIT),
            Err(CodecError::UnknownMessage(_))
        ));
    }
    // A server message is not a client message.
    let welcome = encode_server(&server_messages()[1]);
    assert!(decode_client(&welcome, LIMIT).is_err());
    // A string claiming 2^40 bytes inside a tiny frame.
    let mut forged = vec![PROTOCOL_VERSION as u8, 0, 1];
    forged.extend_from_slice(&[0xfd, 0, 0, 0, 0, 0, 1, 0, 0]);
    assert!(matches!(decode_client(&forged, LIMIT), Err(CodecError::Malformed(_))));
}

/// Packs a string of '0' and '1' into bytes, padded with zero bits.
fn pack_bits(bits: &str) -> Vec<u8> {
    let bits: Vec<u8> = bits.bytes().filter(|b| *b != b' ').map(|b| b - b'0').collect();
    bits.chunks(8)
        .map(|chunk| chunk.iter().enumerate().fold(0u8, |acc, (i, b)| acc | (b << (7 - i))))
        .collect()
}

/// A Points frame whose batch is the given bytes.
fn points_frame_with_batch(batch: &[u8]) -> Vec<u8> {
    let mut frame = encode_client(&ClientMessage::Points(Points {
        stroke: id(0),
        seq: 0,
        points: PointBatch(vec![]),
    }));
    assert_eq!(frame.pop(), Some(0), "an empty batch is one zero byte");
    frame.extend_from_slice(batch);
    frame
}

#[test]
fn binary_refuses_forged_sample_counts_without_allocating() {
    // n - 1 = 2^40 in Exp-Golomb: far over MAX_BATCH_SAMPLES.
    let huge = format!("1 {} 1 {}", "0".repeat(40), "0".repeat(40));
    let err = decode_client(&points_frame_with_batch(&pack_bits(&huge)), LIMIT).unwrap_err();
    let n = Some(1u64 << 40);
    assert_eq!(err, CodecError::BatchTooLarge { n, limit: MAX_BATCH_SAMPLES });
    // n = 2^20 (within the limit) but with no bytes behind it: cut short, nothing reserved.
    let many = format!("1 {} 1 {}", "0".repeat(20), "0".repeat(20));
    let err = decode_client(&points_frame_with_batch(&pack_bits(&many)), LIMIT).unwrap_err();
    assert!(matches!(&err, CodecError::Malformed(_)), "{err}");
    // Non-zero padding after an empty batch.
    let err = decode_client(&points_frame_with_batch(&[0b0000_0001]), LIMIT).unwrap_err();
    assert!(matches!(&err, CodecError::Malformed(m) if m.contains("padding")), "{err}");
    // A code longer than 62 bits.
    let long = format!("1 1 1 1 {}", "0".repeat(80));
    assert!(decode_client(&points_frame_with_batch(&pack_bits(&long)), LIMIT).is_err());
}

#[test]
fn the_callers_batch_limit_is_applied_while_decoding_in_both_encodings() {
    let points = |n: usize| {
        ClientMessage::Points(Points { stroke: id(1), seq: 0, points: PointBatch(samples(n)) })
    };
    // A forged count of 2^20 with no samples behind it: refused on the count alone.
    let forged =
        points_frame_with_batch(&pack_bits(&format!("1 {} 1 {}", "0".repeat(20), "0".repeat(20))));
    let binary = |bytes: &[u8], limit| decode_client_limited(bytes, LIMIT, limit);
    let json = |msg: &ClientMessage, limit| {
        decode_client_json_limited(&encode_client_json(msg), LIMIT, limit)
    };
    for (case, result, expected) in [
        ("binary at the limit", binary(&encode_client(&points(10)), 10), None),
        ("binary over", binary(&encode_client(&points(11)), 10), Some(Some(11))),
        ("binary forged count", binary(&forged, 4096), Some(Some(1 << 20))),
        ("json at the limit", json(&points(10), 10), None),
        ("json over", json(&points(11), 10), Some(None)),
    ] {
        match expected {
            None => assert_eq!(result, Ok(points(10)), "{case}"),
            Some(n) => {
                let err = result.unwrap_err();
                assert_eq!(
                    err,
                    CodecError::BatchTooLarge {
                        n,
                        limit: if case.contains("forged") { 4096 } else { 10 }
                    },
                    "{case}"
                );
                assert!(err.to_string().contains("larger than the limit"), "{case}: {err}");
            }
        }
    }
    // The limit is for one decode only: the next one without it takes a large batch.
    assert!(decode_client(&encode_client(&points(11)), LIMIT).is_ok());
    assert!(decode_client_json(&encode_client_json(&points(11)), LIMIT).is_ok());
}

#[test]
fn binary_frames_are_compact_for_a_typical_batch() {
    let msg =
        ClientMessage::Points(Points { stroke: id(0), seq: 1000, points: PointBatch(samples(32)) });
    let frame = encode_client(&msg);
    // Version, variant, uuid (17), seq (3), then the batch.
    assert!(frame.len() < 22 + 32 * 6, "{} bytes", frame.len());
}

#[test]
fn non_finite_and_huge_values_travel_raw_and_exact() {
    let odd = vec![
        Sample::new(f64::NAN, 1.0, 0.0, 0.5),
        Sample::new(1e300, f64::NEG_INFINITY, 1.0, 0.5),
        Sample::new(2.0, 3.0, f64::INFINITY, -0.0),
        Sample::new(-1e20, 4.0, 3.0, f64::MAX),
        Sample::new(-0.0, 5.0, 4.0, f64::MIN_POSITIVE),
    ];
    let back = round_trip(&odd);
    let expect: Vec<Sample> = odd.iter().map(quantize_sample).collect();
    assert_bits_eq(&back, &expect);
    assert!(back[0].x.is_nan());
    assert_eq!(back[1].x, 1e300);
    assert_eq!(back[4].x.to_bits(), 0.0f64.to_bits(), "-0.0 becomes +0.0");
    // The proxy's validation refuses them by field, as it would for JSON input.
    assert!(penmesh::validate_samples(&back, None, 0).is_err());
}

fn round_trip(batch: &[Sample]) -> Vec<Sample> {
    let msg =
        ClientMessage::Points(Points { stroke: id(0), seq: 0, points: PointBatch(batch.to_vec()) });
    match decode_client(&encode_client(&msg), usize::MAX).unwrap() {
        ClientMessage::Points(p) => p.points.0,
        other => panic!("decoded {other:?}"),
    }
}

fn assert_bits_eq(a: &[Sample], b: &[Sample]) {
    assert_eq!(a.len(), b.len());
    for (i, (a, b)) in a.iter().zip(b).enumerate() {
        for (x, y) in [(a.x, b.x), (a.y, b.y), (a.t, b.t), (a.p, b.p)] {
            assert_eq!(x.to_bits(), y.to_bits(), "sample {i}: {a:?} vs {b:?}");
        }
    }
}

fn half_steps() -> [f64; 4] {
    [POSITION_STEP / 2.0, POSITION_STEP / 2.0, TIME_STEP / 2.0, PRESSURE_STEP / 2.0]
}

fn channels(s: &Sample) -> [f64; 4] {
    [s.x, s.y, s.t, s.p]
}

/// Finite values of every magnitude, with a bias to pen-like ones.
fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -5000.0..5000.0f64,
        0.0..1.0f64,
        (-60i64..60).prop_map(|k| k as f64 / 16.0),
        prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO,
    ]
}

fn finite_sample() -> impl Strategy<Value = Sample> {
    (finite(), finite(), finite(), finite()).prop_map(|(x, y, t, p)| Sample::new(x, y, t, p))
}

fn any_sample() -> impl Strategy<Value = Sample> {
    let any = prop_oneof![finite(), prop::num::f64::ANY];
    (any.clone(), any.clone(), any.clone(), any).prop_map(|(x, y, t, p)| Sample::new(x, y, t, p))
}

/// A pen-like stroke: a random walk on the grid, sometimes with odd values mixed in.
fn walk() -> impl Strategy<Value = Vec<Sample>> {
    (
        prop::collection::vec((-40i64..40, -40i64..40, 0i64..200, -30i64..30), 0..70),
        -20000.0..20000.0f64,
    )
        .prop_map(|(steps, start)| {
            let (mut x, mut y, mut t, mut p) = (start, -start / 2.0, 0.0, 0.5);
            steps
                .into_iter()
                .map(|(dx, dy, dt, dp)| {
                    x += dx as f64 * 0.37;
                    y += dy as f64;
                    t += dt as f64 / 8.0;
                    p = (p + dp as f64 / 1024.0).clamp(0.0, 1.0);
                    Sample::new(x, y, t, p)
                })
                .collect()
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Quantisation moves each channel by at most half its step and is idempotent.
    #[test]
    fn quantisation_moves_a_sample_at_most_half_a_step(s in finite_sample()) {
        let q = quantize_sample(&s);
        for ((v, w), half) in channels(&s).into_iter().zip(channels(&q)).zip(half_steps()) {
            prop_assert!((v - w).abs() <= half, "{v} -> {w}");
        }
        prop_assert_eq!(quantize_sample(&q), q);
    }

    /// Any finite batch comes back within half a step per channel, exactly on the grid.
    #[test]
    fn finite_batches_round_trip_within_half_a_step(batch in prop::collection::vec(finite_sample(), 0..40)) {
        let back = round_trip(&batch);
        let expect: Vec<Sample> = batch.iter().map(quantize_sample).collect();
        assert_bits_eq(&back, &expect);
        for (s, b) in batch.iter().zip(&back) {
            for ((v, w), half) in channels(s).into_iter().zip(channels(b)).zip(half_steps()) {
                prop_assert!((v - w).abs() <= half, "{v} -> {w}");
            }
        }
    }

    /// Any f64 at all, NaN and infinities included, decodes to exactly its quantised value.
    #[test]
    fn any_batch_decodes_to_its_quantised_values(batch in prop::collection::vec(any_sample(), 0..12)) {
        let back = round_trip(&batch);
        let expect: Vec<Sample> = batch.iter().map(quantize_sample).collect();
        assert_bits_eq(&back, &expect);
    }

    /// Pen-like strokes round-trip bit-exactly once quantised.
    #[test]
    fn pen_like_strokes_round_trip(batch in walk()) {
        let quantised: Vec<Sample> = batch.iter().map(quantize_sample).collect();
        assert_bits_eq(&round_trip(&quantised), &quantised);
    }

    /// Random bytes never panic the decoders.
    #[test]
    fn random_bytes_never_panic(mut bytes in prop::collection::vec(any::<u8>(), 0..200), v in any::<bool>()) {
        if v && !bytes.is_empty() {
            bytes[0] = PROTOCOL_VERSION as u8;
        }
        let _ = decode_client(&bytes, LIMIT);
        let _ = decode_server(&bytes, LIMIT);
        // Random bit strings behind a valid Points header exercise the batch decoder.
        let _ = decode_client(&points_frame_with_batch(&bytes), LIMIT);
    }

    /// Truncated or mutated valid frames are refused or decode to something, never panic.
    #[test]
    fn damaged_frames_never_panic(
        batch in walk(),
        cut in any::<prop::sample::Index>(),
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..4),
    ) {
        let msg = ClientMessage::Points(Points { stroke: id(0), seq: 3, points: PointBatch(batch) });
        let frame = encode_client(&msg);
        let truncated = &frame[..cut.index(frame.len())];
        prop_assert!(decode_client(truncated, LIMIT).is_err());
        let mut mutated = frame.clone();
        for (at, xor) in flips {
            let i = at.index(mutated.len());
            mutated[i] ^= xor;
        }
        let _ = decode_client(&mutated, LIMIT);
        let text = encode_client_json(&msg);
        let _ = decode_client_json(&text[..cut.index(text.len())], LIMIT);
    }
}

// ---------------------------------------------------------------------------------------------
// Real pen data: bytes per sample.

/// Every stroke of a recorded data set, read in place by the crate's own readers
/// (`penmesh::data_sets`), in tablet units.
fn strokes_of(set: DataSet) -> Vec<Vec<Sample>> {
    let recordings = set.read().unwrap_or_else(|err| panic!("{err}"));
    recordings.iter().flat_map(|r| &r.strokes).map(|stroke| stroke.samples().to_vec()).collect()
}

/// Bytes the batch adds to a Points frame (the frame minus its header).
fn payload_bytes(batch: &[Sample]) -> usize {
    let frame = |points: Vec<Sample>| {
        encode_client(&ClientMessage::Points(Points {
            stroke: id(0),
            seq: 0,
            points: PointBatch(points),
        }))
    };
    frame(batch.to_vec()).len() - (frame(vec![]).len() - 1)
}

/// Average payload bytes per sample when each stroke is sent in batches of `size` samples
/// (`None`: the whole stroke in one batch). Also checks every batch round-trips exactly.
fn bytes_per_sample(strokes: &[Vec<Sample>], size: Option<usize>) -> f64 {
    let (mut bytes, mut n) = (0, 0);
    for stroke in strokes {
        let quantised: Vec<Sample> = stroke.iter().map(quantize_sample).collect();
        for batch in quantised.chunks(size.unwrap_or(quantised.len()).max(1)) {
            bytes += payload_bytes(batch);
            n += batch.len();
            assert_eq!(round_trip(batch), batch);
        }
    }
    bytes as f64 / n as f64
}

#[test]
fn real_pen_data_costs_at_most_6_bytes_per_sample_at_live_batch_sizes() {
    let resampled = |strokes: &[Vec<Sample>]| -> Vec<Vec<Sample>> {
        strokes.iter().map(|s| resample(s, 1.0).into_iter().map(|i| s[i]).collect()).collect()
    };
    let svc = strokes_of(SVC2004);
    let dutch = strokes_of(SIGCOMP2011_DUTCH);
    assert_eq!(svc.iter().map(Vec::len).sum::<usize>(), 7117);
    assert_eq!(dutch.iter().map(Vec::len).sum::<usize>(), 18843 - 6077);
    let sets = [
        ("svc2004 100 Hz raw", svc.clone(), 2),
        ("svc2004 resampled", resampled(&svc), 2),
        ("dutch 200 Hz raw", dutch.clone(), 3),
        ("dutch resampled", resampled(&dutch), 3),
    ];
    let sizes = [Some(1), Some(2), Some(3), Some(4), Some(8), Some(16), Some(32), Some(64), None];
    print!("\npayload bytes/sample      samples strokes");
    for size in sizes {
        match size {
            Some(n) => print!(" {n:>6}"),
            None => print!(" {:>6}", "stroke"),
        }
    }
    println!();
    for (name, strokes, live) in &sets {
        let n: usize = strokes.iter().map(Vec::len).sum();
        print!("{name:<24} {n:>8} {:>7}", strokes.len());
        let row: Vec<f64> = sizes.iter().map(|&size| bytes_per_sample(strokes, size)).collect();
        for v in &row {
            print!(" {v:>6.2}");
        }
        println!();
        // The live client batches 16 ms of samples: 2 at 100 Hz, 3 at 200 Hz. Two is enough.
        let at_live = row[sizes.iter().position(|s| *s == Some(*live)).unwrap()];
        assert!(at_live <= 6.0, "{name}: {at_live:.2} B/sample at batches of {live}");
        for (size, v) in sizes.iter().zip(&row).skip(1) {
            assert!(*v <= 6.0, "{name}: {v:.2} B/sample at batches of {size:?}");
        }
    }
}

/// The bare point batch the proxy stores: exact for samples on the grid (raw channels
/// included), and bytes that end early or go on after the batch are refused.
#[test]
fn bare_point_batches_round_trip_exactly_and_refuse_bad_bytes() {
    let mut batch = samples(50);
    batch.push(Sample::new(3.0e15, -7.25, 1.0e30, 1.0));
    for b in [&batch[..0], &batch[..1], &batch[..2], &batch[..]] {
        let bytes = encode_point_batch(b);
        let back = decode_point_batch(&bytes).unwrap();
        assert_eq!(back.len(), b.len());
        for (x, y) in back.iter().zip(b) {
            for (u, v) in [(x.x, y.x), (x.y, y.y), (x.t, y.t), (x.p, y.p)] {
                assert_eq!(u.to_bits(), v.to_bits());
            }
        }
    }
    let bytes = encode_point_batch(&batch[..10]);
    assert!(decode_point_batch(&bytes[..bytes.len() - 1]).is_err());
    let mut longer = bytes.clone();
    longer.push(0);
    let err = decode_point_batch(&longer).unwrap_err();
    assert!(err.to_string().contains("1 bytes after"), "{err}");
}
