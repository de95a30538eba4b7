//! The version policy of the wire protocol (`docs/protocol.md`, "Versions"): version 6 is
//! spoken beside versions 5 and 4. bincode is not self-describing, so a version-4 binary
//! `StrokeBegin` (which has no placement) must be read as version 4, a version-5 one (no solid)
//! as version 5, and an older client is never sent a message it lacks, nor a `HistoryStroke`
//! with what version 6 added. Also the cost of a move and of a solid on the wire.

use penmesh::protocol::*;
use penmesh::{Placement, Solid, SolidKind};
use uuid::Uuid;

const LIMIT: usize = MAX_FRAME_BYTES_DEFAULT;

fn id(n: u128) -> Uuid {
    Uuid::from_u128(0x67e5_5044_10b1_426f_9247_bb68_0e5f_e0c8 ^ n)
}

/// A turn of 30° about z, moved, as a gizmo leaves it: every element a full `f64`.
fn moved() -> Placement {
    let (s, c) = 30f64.to_radians().sin_cos();
    Placement::new([c, s, 0.0, 0.0, -s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 12.5, -3.25, 40.0, 1.0])
        .unwrap()
}

fn begin(placement: Option<Placement>) -> ClientMessage {
    ClientMessage::StrokeBegin(StrokeBegin {
        stroke: id(1),
        brush: Default::default(),
        device: Some("wacom".into()),
        params: None,
        placement,
        solid: None,
    })
}

// A version-4 binary stroke_begin (no placement field) decodes as version 4, at the identity;
// read as version 5 the same bytes do not decode: the version byte is what tells them apart.
#[test]
fn a_version_4_stroke_begin_decodes_as_version_4() {
    let v4 = encode_client_as(&begin(None), 4).unwrap();
    let v5 = encode_client_as(&begin(None), 5).unwrap();
    assert_eq!((v4[0], v5[0]), (4, 5));
    assert_eq!(v5.len(), v4.len() + 1, "version 5 adds the placement's option tag");
    assert_eq!(decode_client(&v4, LIMIT).unwrap(), begin(None));
    let mut misread = v4.clone();
    misread[0] = 5;
    assert!(matches!(decode_client(&misread, LIMIT), Err(CodecError::Malformed(_))));
    // Every other version-4 client message is laid out as in version 5.
    let ping = ClientMessage::Ping(Ping { nonce: 9 });
    assert_eq!(encode_client_as(&ping, 4).unwrap()[1..], encode_client(&ping)[1..]);
    assert_eq!(decode_client(&encode_client_as(&ping, 4).unwrap(), LIMIT).unwrap(), ping);
    // A version-4 frame has no SetPlacement (variant 8 there is past its last message).
    let set = ClientMessage::SetPlacement(SetPlacement { stroke: id(1), placement: moved() });
    let mut as_v4 = encode_client(&set);
    as_v4[0] = 4;
    assert!(matches!(decode_client(&as_v4, LIMIT), Err(CodecError::UnknownMessage(_))));
}

// What version 4 cannot say is not encoded for it: a placement, sent or received.
#[test]
fn version_4_is_never_sent_a_placement() {
    assert_eq!(encode_client_as(&begin(Some(moved())), 4), None);
    assert!(encode_client_as(&begin(Some(Placement::IDENTITY)), 4).is_some());
    let set = ClientMessage::SetPlacement(SetPlacement { stroke: id(1), placement: moved() });
    assert_eq!(encode_client_as(&set, 4), None);
    let placed = ServerMessage::PeerPlacement(PeerPlacement {
        participant: id(2),
        stroke: id(1),
        placement: moved(),
    });
    assert_eq!(encode_server_as(&placed, 4), None);
    assert_eq!(encode_server_json_as(&placed, 4), None);
    assert!(encode_server_as(&placed, 5).is_some());
    // The rest goes to version 4 as it is, with its version byte, and decodes there.
    let synced = ServerMessage::Synced(Synced { n_strokes: 3 });
    let frame = encode_server_as(&synced, 4).unwrap();
    assert_eq!(frame[0], 4);
    assert_eq!(frame[1..], encode_server(&synced)[1..]);
    assert_eq!(decode_server(&frame, LIMIT).unwrap(), synced);
    let mut placed_v4 = encode_server(&placed);
    placed_v4[0] = 4;
    assert!(matches!(decode_server(&placed_v4, LIMIT), Err(CodecError::UnknownMessage(_))));
    assert!(is_supported_version(4) && is_supported_version(5) && is_supported_version(6));
    assert!(!is_supported_version(3) && !is_supported_version(7));
    assert_eq!(encode_server_as(&synced, 3), None);
}

// A placement crosses both encodings bit for bit, and a bad one does not decode, naming what
// is wrong.
#[test]
fn placements_cross_the_wire_bit_exactly_and_bad_ones_are_refused() {
    let set = ClientMessage::SetPlacement(SetPlacement { stroke: id(1), placement: moved() });
    let bits = |m: &ClientMessage| match m {
        ClientMessage::SetPlacement(s) => s.placement.to_bytes(),
        _ => unreachable!(),
    };
    assert_eq!(bits(&decode_client(&encode_client(&set), LIMIT).unwrap()), bits(&set));
    assert_eq!(bits(&decode_client_json(&encode_client_json(&set), LIMIT).unwrap()), bits(&set));
    let stroke = id(1);
    let shear = format!(
        r#"{{"set_placement":{{"stroke":"{stroke}","placement":{{"matrix":[1,0,0,0,0.5,1,0,0,0,0,1,0,0,0,0,1]}}}}}}"#
    );
    let err = decode_client_json(&shear, LIMIT).unwrap_err().to_string();
    assert!(err.contains("not a similarity"), "{err}");
    let mut binary = encode_client(&set);
    // The last element (m15) becomes 2.0: not an affine map.
    let n = binary.len();
    binary[n - 8..].copy_from_slice(&2.0f64.to_le_bytes());
    let err = decode_client(&binary, LIMIT).unwrap_err().to_string();
    assert!(err.contains("matrix[15] = 2"), "{err}");
}

// The cost of one move on the wire (docs/performance.md): at most 200 bytes each way in the
// binary encoding; JSON for comparison.
#[test]
fn a_move_costs_at_most_200_bytes_in_binary() {
    let set = ClientMessage::SetPlacement(SetPlacement { stroke: id(1), placement: moved() });
    let told = ServerMessage::PeerPlacement(PeerPlacement {
        participant: id(2),
        stroke: id(1),
        placement: moved(),
    });
    let (up, down) = (encode_client(&set).len(), encode_server(&told).len());
    let (up_json, down_json) = (encode_client_json(&set).len(), encode_server_json(&told).len());
    println!(
        "one move: set_placement {up} B binary, {up_json} B JSON; peer_placement {down} B binary, {down_json} B JSON"
    );
    assert_eq!(up, 1 + 1 + 17 + 128);
    assert_eq!(down, 1 + 1 + 17 + 17 + 128);
    assert!(up <= 200 && down <= 200);
}

fn filled() -> Solid {
    Solid::new(SolidKind::Filled, Some(0.1 + 24.0)).unwrap()
}

fn history_stroke() -> HistoryStroke {
    HistoryStroke {
        participant: id(2),
        stroke: id(1),
        brush: Default::default(),
        points: PointBatch(vec![penmesh::Sample::new(1.0, 2.0, 0.0, 0.5)]),
        done: true,
        mesh: true,
        placement: moved(),
        solid: filled(),
    }
}

// Version 6 adds solids and a history stroke's placement and solid; versions 5 and 4 are sent
// neither, and read their own frames as before.
#[test]
fn version_6_adds_solids_and_older_versions_see_only_what_they_have() {
    let solid_begin = ClientMessage::StrokeBegin(StrokeBegin {
        stroke: id(1),
        brush: Default::default(),
        device: None,
        params: None,
        placement: None,
        solid: Some(filled()),
    });
    let frame = encode_client(&solid_begin);
    assert_eq!(frame[0], 6);
    assert_eq!(decode_client(&frame, LIMIT).unwrap(), solid_begin);
    assert_eq!(encode_client_as(&solid_begin, 5), None, "version 5 cannot say a solid");
    assert_eq!(encode_client_as(&solid_begin, 4), None);
    // A version-5 stroke_begin (a placement, no solid) is read as version 5: the rod.
    let v5 = encode_client_as(&begin(Some(moved())), 5).unwrap();
    assert_eq!(decode_client(&v5, LIMIT).unwrap(), begin(Some(moved())));
    let set = ClientMessage::SetSolid(SetSolid { stroke: id(1), solid: filled() });
    assert_eq!(decode_client(&encode_client(&set), LIMIT).unwrap(), set);
    assert_eq!(decode_client_json(&encode_client_json(&set), LIMIT).unwrap(), set);
    assert_eq!(encode_client_as(&set, 5), None);
    let mut as_v5 = encode_client(&set);
    as_v5[0] = 5;
    assert!(matches!(decode_client(&as_v5, LIMIT), Err(CodecError::UnknownMessage(_))));

    let told =
        ServerMessage::PeerSolid(PeerSolid { participant: id(2), stroke: id(1), solid: filled() });
    assert_eq!(decode_server(&encode_server(&told), LIMIT).unwrap(), told);
    for version in [4, 5] {
        assert_eq!(encode_server_as(&told, version), None, "version {version}");
        assert_eq!(encode_server_json_as(&told, version), None, "version {version}");
    }

    // A history's stroke carries its placement and solid in version 6 only.
    let strokes = ServerMessage::PeerStrokes(PeerStrokes { strokes: vec![history_stroke()] });
    assert_eq!(decode_server(&encode_server(&strokes), LIMIT).unwrap(), strokes);
    let json = encode_server_json(&strokes);
    assert!(json.contains("\"solid\":{\"kind\":\"filled\""), "{json}");
    assert_eq!(decode_server_json(&json, LIMIT).unwrap(), strokes);
    let mut old = history_stroke();
    (old.placement, old.solid) = (Placement::IDENTITY, Solid::ROD);
    let old = ServerMessage::PeerStrokes(PeerStrokes { strokes: vec![old] });
    for version in [4, 5] {
        let frame = encode_server_as(&strokes, version).unwrap();
        assert_eq!(frame[0], version as u8);
        assert!(frame.len() < encode_server(&strokes).len(), "without placement and solid");
        assert_eq!(decode_server(&frame, LIMIT).unwrap(), old, "version {version}");
        let json = encode_server_json_as(&strokes, version).unwrap();
        assert!(!json.contains("solid") && !json.contains("placement"), "{json}");
        assert_eq!(decode_server_json(&json, LIMIT).unwrap(), old);
    }
    // The messages a version-6 PeerStrokes stands for include its placement and solid.
    let ServerMessage::PeerStrokes(carried) = &strokes else { unreachable!() };
    let messages = carried.messages();
    assert!(
        messages
            .iter()
            .any(|m| matches!(m, ServerMessage::PeerPlacement(p) if p.placement == moved()))
    );
    assert!(
        messages.iter().any(|m| matches!(m, ServerMessage::PeerSolid(s) if s.solid == filled()))
    );
}

// A solid on the wire: a few dozen bytes, never mesh bytes.
#[test]
fn a_solid_costs_a_few_dozen_bytes() {
    let set = ClientMessage::SetSolid(SetSolid { stroke: id(1), solid: filled() });
    let told =
        ServerMessage::PeerSolid(PeerSolid { participant: id(2), stroke: id(1), solid: filled() });
    let (up, down) = (encode_client(&set).len(), encode_server(&told).len());
    println!(
        "one solid: set_solid {up} B binary, {} B JSON; peer_solid {down} B binary",
        encode_client_json(&set).len()
    );
    // Version byte, variant, uuid (length-prefixed), kind, option tag, f64.
    assert_eq!(up, 1 + 1 + 17 + 1 + 1 + 8);
    assert_eq!(down, 1 + 1 + 17 + 17 + 1 + 1 + 8);
}
