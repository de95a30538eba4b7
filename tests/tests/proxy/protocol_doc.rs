//! `docs/protocol.md` is the contract, so every example in it is executed here: each JSON
//! message and hex frame against the codec, the conversations against a running proxy, each
//! HTTP answer's shape against the live answer, and the tables of variant and error indices
//! against the enums. A doc that drifts from the code fails this test.
//!
//! The doc's example blocks (fenced code blocks, by their info string):
//! - ` ```json client` / ` ```json server`: one message per line.
//! - ` ```frames client` / ` ```frames server`: a JSON line, then the hex of its binary frame
//!   on the lines after it (until the next JSON line).
//! - a trailing word `live` marks a conversation a client can send as it stands: it is sent
//!   line by line to a running proxy, on a fresh session, and must draw without an error.
//! - ` ```http`: a request line (`METHOD PATH STATUS`, the path may hold `{session}`,
//!   `{stroke}` and `{unknown}`), then lines `> name: value` of headers the request sends (a
//!   GET sends the session's token besides; `{token}` and `{key}` are the session's token and
//!   the conversation's key) and `< name: value` of headers the answer must have, exactly,
//!   then the answer: JSON, which the live answer must match in shape (the same keys at every
//!   level, values of the same JSON types), or hex, which must be the live answer's bytes, or
//!   nothing (the body is not looked at).

use std::collections::BTreeSet;
use std::time::Duration;

use penmesh::protocol::{
    ClientMessage, PROTOCOL_VERSION, ServerMessage, decode_client, decode_client_json,
    decode_server, decode_server_json, encode_client, encode_client_json, encode_server,
    encode_server_json,
};
use penmesh_e2e::{Incoming, TestProxy, spawn_proxy};
use serde_json::Value;

const LIMIT: usize = 1 << 20;

/// A fenced block of the doc: its info string's words and its lines.
#[derive(Debug)]
struct Block {
    kind: String,
    side: String,
    live: bool,
    lines: Vec<String>,
    /// Line number of the opening fence, for messages.
    at: usize,
}

fn doc() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    std::fs::read_to_string(path).expect("docs/protocol.md is readable")
}

fn blocks(doc: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    for (n, line) in doc.lines().enumerate() {
        // A block may be indented (inside a list item): its lines are read without it.
        let line = line.trim_start();
        let Some(info) = line.strip_prefix("```") else {
            if let Some(block) = open.as_mut() {
                block.lines.push(line.to_string());
            }
            continue;
        };
        match open.take() {
            Some(block) => out.push(block),
            None => {
                let words: Vec<&str> = info.split_whitespace().collect();
                open = Some(Block {
                    kind: words.first().unwrap_or(&"").to_string(),
                    side: words.get(1).unwrap_or(&"").to_string(),
                    live: words.contains(&"live"),
                    lines: Vec::new(),
                    at: n + 1,
                });
            }
        }
    }
    out
}

fn message_blocks<'a>(blocks: &'a [Block], kind: &str, side: &str) -> Vec<&'a Block> {
    blocks.iter().filter(|b| b.kind == kind && b.side == side).collect()
}

/// The JSON lines of a `json` block, with their line numbers.
fn json_lines(block: &Block) -> Vec<(usize, String)> {
    (block.lines.iter().enumerate())
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| (block.at + 1 + i, l.trim().to_string()))
        .collect()
}

/// The (JSON, frame bytes) pairs of a `frames` block, with the JSON's line number.
fn frame_pairs(block: &Block) -> Vec<(usize, String, Vec<u8>)> {
    let mut out: Vec<(usize, String, Vec<u8>)> = Vec::new();
    for (i, line) in block.lines.iter().enumerate() {
        let line = line.trim();
        if line.starts_with('{') {
            out.push((block.at + 1 + i, line.to_string(), Vec::new()));
        } else if !line.is_empty() {
            let (at, _, bytes) = out.last_mut().unwrap_or_else(|| {
                panic!("protocol.md:{}: hex before any JSON line", block.at + 1 + i)
            });
            for byte in line.split_whitespace() {
                bytes
                    .push(u8::from_str_radix(byte, 16).unwrap_or_else(|_| {
                        panic!("protocol.md:{at}: {byte:?} is not a hex byte")
                    }));
            }
        }
    }
    out
}

/// Is every key and value of `doc` in `actual`, numbers compared as numbers? A doc example may
/// leave optional fields out, but every field it shows must be one the message has, with the
/// value shown: a misspelt field would otherwise be ignored silently by the decoder.
fn shown_in(doc: &Value, actual: &Value) -> bool {
    match (doc, actual) {
        (Value::Object(d), Value::Object(a)) => {
            d.iter().all(|(k, v)| a.get(k).is_some_and(|av| shown_in(v, av)))
        }
        (Value::Array(d), Value::Array(a)) => {
            d.len() == a.len() && d.iter().zip(a).all(|(d, a)| shown_in(d, a))
        }
        (Value::Number(d), Value::Number(a)) => d.as_f64() == a.as_f64(),
        _ => doc == actual,
    }
}

fn check_json(side: &str, at: usize, line: &str) -> Value {
    let doc: Value = serde_json::from_str(line)
        .unwrap_or_else(|e| panic!("protocol.md:{at}: not JSON ({e}): {line}"));
    let encoded = match side {
        "client" => encode_client_json(
            &decode_client_json(line, LIMIT)
                .unwrap_or_else(|e| panic!("protocol.md:{at}: {e}: {line}")),
        ),
        _ => encode_server_json(
            &decode_server_json(line, LIMIT)
                .unwrap_or_else(|e| panic!("protocol.md:{at}: {e}: {line}")),
        ),
    };
    let actual: Value = serde_json::from_str(&encoded).unwrap();
    assert!(shown_in(&doc, &actual), "protocol.md:{at}: {line}\nreads back as {encoded}");
    doc
}

fn message_name(doc: &Value) -> String {
    doc.as_object().and_then(|o| o.keys().next()).cloned().unwrap_or_default()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

/// Every JSON example decodes, shows only fields the message has, and every message of this
/// version has one; every hex frame is exactly the binary encoding of the JSON beside it.
#[test]
fn every_example_message_and_frame_is_what_the_codec_says() {
    let doc = doc();
    let blocks = blocks(&doc);
    for side in ["client", "server"] {
        let names: &[&str] = match side {
            "client" => <ClientMessage as strum::VariantNames>::VARIANTS,
            _ => <ServerMessage as strum::VariantNames>::VARIANTS,
        };
        let mut in_json = BTreeSet::new();
        for block in message_blocks(&blocks, "json", side) {
            for (at, line) in json_lines(block) {
                in_json.insert(message_name(&check_json(side, at, &line)));
            }
        }
        let mut in_frames = BTreeSet::new();
        for block in message_blocks(&blocks, "frames", side) {
            for (at, line, bytes) in frame_pairs(block) {
                let doc = check_json(side, at, &line);
                in_frames.insert(message_name(&doc));
                let (encoded, decoded_equal) = match side {
                    "client" => {
                        let msg = decode_client_json(&line, LIMIT).unwrap();
                        let from_hex = decode_client(&bytes, LIMIT).unwrap_or_else(|e| {
                            panic!("protocol.md:{at}: the frame does not decode: {e}")
                        });
                        (encode_client(&msg), from_hex == msg)
                    }
                    _ => {
                        let msg = decode_server_json(&line, LIMIT).unwrap();
                        let from_hex = decode_server(&bytes, LIMIT).unwrap_or_else(|e| {
                            panic!("protocol.md:{at}: the frame does not decode: {e}")
                        });
                        (encode_server(&msg), from_hex == msg)
                    }
                };
                assert_eq!(
                    hex(&bytes),
                    hex(&encoded),
                    "protocol.md:{at}: the frame of {line} is not its encoding"
                );
                assert!(decoded_equal, "protocol.md:{at}: the frame decodes to another message");
            }
        }
        for name in names {
            assert!(in_json.contains(*name), "protocol.md has no JSON example of {side} {name}");
            assert!(in_frames.contains(*name), "protocol.md has no frame example of {side} {name}");
        }
    }
}

/// The rows of the doc's table that follows the line `marker`: (first cell, second cell), with
/// backticks dropped.
fn table_after(doc: &str, marker: &str) -> Vec<(String, String)> {
    let start = doc.find(marker).unwrap_or_else(|| panic!("protocol.md has no {marker:?}"));
    doc[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2)
        .map(|l| {
            let cells: Vec<String> =
                l.split('|').map(|c| c.trim().replace('`', "")).collect::<Vec<_>>();
            (cells[1].clone(), cells[2].clone())
        })
        .collect()
}

/// The index tables (messages, error codes) list every variant with its wire index.
#[test]
fn the_index_tables_match_the_enums() {
    let doc = doc();
    for (marker, names) in [
        ("<!-- client message indices -->", <ClientMessage as strum::VariantNames>::VARIANTS),
        ("<!-- server message indices -->", <ServerMessage as strum::VariantNames>::VARIANTS),
    ] {
        let rows = table_after(&doc, marker);
        let listed: Vec<(String, String)> =
            names.iter().enumerate().map(|(i, n)| (i.to_string(), n.to_string())).collect();
        assert_eq!(rows, listed, "the table after {marker} differs from the enum");
    }
    // Error codes: the binary index of each is its variant index, read from a real frame.
    let rows = table_after(&doc, "<!-- error code indices -->");
    assert!(!rows.is_empty());
    for (index, code) in &rows {
        let json = format!(r#"{{"error":{{"code":"{code}","message":"","stroke":null}}}}"#);
        let msg = decode_server_json(&json, LIMIT)
            .unwrap_or_else(|e| panic!("error code {code} of the table is not a code: {e}"));
        // version byte, variant 5 (error), then the code's index.
        assert_eq!(encode_server(&msg)[2].to_string(), *index, "index of error code {code}");
    }
    // One index past the table does not decode: the table lists every code.
    let n_codes = u8::try_from(rows.len()).unwrap();
    let past = [PROTOCOL_VERSION as u8, 5, n_codes, 0, 0];
    assert!(
        decode_server(&past, LIMIT).is_err(),
        "the table lists {n_codes} error codes but the enum has more"
    );
    assert!(
        doc.contains(&format!("**Protocol version: {PROTOCOL_VERSION}**")),
        "the doc names another version than {PROTOCOL_VERSION}"
    );
}

/// The answers a live conversation must get: every conversation draws (`welcome`, `ack`,
/// `stroke_done`) and pings (`pong`); a take-back and a bring-back are answered too.
fn expected_answers(sent: &str) -> Vec<&'static str> {
    let mut expected = vec!["welcome", "ack", "stroke_done", "pong"];
    for (asks, answer) in [
        ("remove_stroke", "stroke_removed"),
        ("restore_stroke", "stroke_restored"),
        ("set_placement", "peer_placement"),
    ] {
        if sent.contains(asks) {
            expected.push(answer);
        }
    }
    expected
}

/// Is `frame` a message about a finished stroke (take back, bring back, place), which a client
/// sends once it has that stroke's `stroke_done`?
fn needs_done(frame: &tokio_tungstenite::tungstenite::Message) -> bool {
    use tokio_tungstenite::tungstenite::Message;
    let msg = match frame {
        Message::Text(text) => decode_client_json(text, LIMIT).ok(),
        Message::Binary(bytes) => decode_client(bytes, LIMIT).ok(),
        _ => None,
    };
    matches!(
        msg,
        Some(
            ClientMessage::RemoveStroke(_)
                | ClientMessage::RestoreStroke(_)
                | ClientMessage::SetPlacement(_)
        )
    )
}

/// Sends each frame of a live block on a fresh session, as a client would (without waiting
/// for answers, except that a message about a finished stroke waits for its `stroke_done`),
/// and reads the answers until every one of `expected` came. Fails on any `error`, a close,
/// or an answer missing after 20 s.
async fn run_conversation(
    proxy: &TestProxy,
    session: &penmesh_e2e::TestSession,
    frames: Vec<tokio_tungstenite::tungstenite::Message>,
    expected: &[&str],
) -> BTreeSet<String> {
    use futures_util::SinkExt;
    let mut ws = proxy.connect(session).await;
    let mut got = BTreeSet::new();
    let talk = async {
        for frame in frames {
            while needs_done(&frame) && !got.contains("stroke_done") {
                got.insert(read_one(&mut ws).await);
            }
            ws.ws.send(frame).await.expect("send");
        }
        while !expected.iter().all(|e| got.contains(*e)) {
            got.insert(read_one(&mut ws).await);
        }
    };
    if tokio::time::timeout(Duration::from_secs(20), talk).await.is_err() {
        panic!("expected answers {expected:?}, got only {got:?}");
    }
    got
}

/// The name of the next message; fails on an `error` or a close.
async fn read_one(ws: &mut penmesh_e2e::WsClient) -> String {
    match ws.next_any().await {
        Incoming::Message(ServerMessage::Error(e)) => panic!("the proxy refused: {e:?}"),
        Incoming::Message(msg) => kind(&msg),
        Incoming::Closed(close) => panic!("closed: {close:?}"),
    }
}

fn kind(msg: &ServerMessage) -> String {
    message_name(&serde_json::from_str(&encode_server_json(msg)).unwrap())
}

/// The doc's live conversations, JSON and binary, draw on a running proxy: welcome, acks, the
/// stroke done, and every answer the doc says each message gets.
#[tokio::test]
async fn the_live_conversations_draw_on_a_running_proxy() {
    use tokio_tungstenite::tungstenite::Message;
    let proxy = spawn_proxy().await;
    let doc = doc();
    let blocks = blocks(&doc);
    let mut n_live = 0;
    for block in blocks.iter().filter(|b| b.live && b.side == "client") {
        let frames: Vec<Message> = match block.kind.as_str() {
            "json" => json_lines(block).into_iter().map(|(_, l)| Message::Text(l.into())).collect(),
            _ => {
                frame_pairs(block).into_iter().map(|(_, _, b)| Message::Binary(b.into())).collect()
            }
        };
        let expected = expected_answers(&block.lines.join("\n"));
        run_conversation(&proxy, &proxy.create_session().await, frames, &expected).await;
        n_live += 1;
    }
    assert!(n_live >= 2, "protocol.md has {n_live} live conversations, not one of each encoding");
}

/// JSON's shape: object keys at every level and each value's type; an array's elements are
/// compared with the doc's first element.
fn same_shape(doc: &Value, actual: &Value, path: &str) -> Result<(), String> {
    match (doc, actual) {
        (Value::Object(d), Value::Object(a)) => {
            let dk: BTreeSet<&String> = d.keys().collect();
            let ak: BTreeSet<&String> = a.keys().collect();
            if dk != ak {
                return Err(format!("{path}: keys {dk:?} in the doc, {ak:?} answered"));
            }
            d.iter().try_for_each(|(k, v)| same_shape(v, &a[k], &format!("{path}.{k}")))
        }
        (Value::Array(d), Value::Array(a)) => match d.first() {
            Some(first) => a
                .iter()
                .enumerate()
                .try_for_each(|(i, v)| same_shape(first, v, &format!("{path}[{i}]"))),
            None => Ok(()),
        },
        (Value::Number(_), Value::Number(_))
        | (Value::String(_), Value::String(_))
        | (Value::Bool(_), Value::Bool(_))
        | (Value::Null, Value::Null) => Ok(()),
        _ => Err(format!("{path}: {doc} in the doc, {actual} answered")),
    }
}

/// Each HTTP answer the doc shows has the shape of the live answer to the same request, on a
/// session with a stroke drawn by the doc's own JSON conversation and meshed by the proxy.
#[tokio::test]
async fn the_http_answers_have_the_documented_shapes() {
    use tokio_tungstenite::tungstenite::Message;
    let proxy = spawn_proxy().await;
    let doc = doc();
    let blocks = blocks(&doc);
    let conversation = blocks
        .iter()
        .find(|b| b.live && b.kind == "json" && b.side == "client")
        .expect("a live JSON conversation");
    let session = proxy.create_session().await;
    let lines = json_lines(conversation);
    let stroke = lines.iter().find_map(|(_, l)| match decode_client_json(l, LIMIT) {
        Ok(ClientMessage::StrokeBegin(b)) => Some(b.stroke),
        _ => None,
    });
    let frames = lines.iter().map(|(_, l)| Message::Text(l.clone().into())).collect();
    let expected = expected_answers(&conversation.lines.join("\n"));
    run_conversation(&proxy, &session, frames, &expected).await;
    let stroke = stroke.expect("the conversation begins a stroke");
    let key = json_lines(conversation)
        .iter()
        .find_map(|(_, l)| match decode_client_json(l, LIMIT) {
            Ok(ClientMessage::Hello(h)) => h.key,
            _ => None,
        })
        .expect("the conversation's hello has a key");
    let built = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{stroke}/mesh/build")))
        .bearer_auth(&session.token)
        .header("x-penmesh-key", &key)
        .send()
        .await
        .unwrap();
    assert!(built.status().is_success(), "mesh build: {}", built.status());

    let mut n_checked = 0;
    for block in blocks.iter().filter(|b| b.kind == "http") {
        let at = block.at + 1;
        let request = block.lines.first().expect("a request line");
        let words: Vec<&str> = request.split_whitespace().collect();
        let [method, path, status] = words[..] else {
            panic!("protocol.md:{at}: request line {request:?}")
        };
        let fill = |text: &str| {
            text.replace("{session}", &session.session.to_string())
                .replace("{stroke}", &stroke.to_string())
                .replace("{unknown}", &uuid::Uuid::new_v4().to_string())
                .replace("{token}", &session.token)
                .replace("{key}", &key)
        };
        let path = fill(path);
        let header = |line: &str| {
            let (name, value) = line.split_once(": ").unwrap_or_else(|| {
                panic!("protocol.md:{at}: {line:?} is not a header line `name: value`")
            });
            (name.to_ascii_lowercase(), fill(value))
        };
        let rest = &block.lines[1..];
        let sent: Vec<_> = rest.iter().filter_map(|l| l.strip_prefix("> ")).map(header).collect();
        let wanted: Vec<_> = rest.iter().filter_map(|l| l.strip_prefix("< ")).map(header).collect();
        let shown = rest.iter().filter(|l| !l.starts_with("> ") && !l.starts_with("< "));
        let shown = shown.map(|l| l.trim()).collect::<Vec<_>>().join("\n");
        let mut asked = match method {
            "GET" => proxy.get(&path, &session),
            "POST" => proxy.http.post(proxy.url(&path)),
            other => panic!("protocol.md:{at}: method {other}"),
        };
        for (name, value) in &sent {
            asked = asked.header(name.as_str(), value.as_str());
        }
        let answer = asked.send().await.unwrap();
        assert_eq!(answer.status().as_u16().to_string(), status, "protocol.md:{at}");
        for (name, value) in &wanted {
            let got = answer.headers().get(name.as_str()).map(|v| v.to_str().unwrap());
            assert_eq!(got, Some(value.as_str()), "protocol.md:{at}: the answer's {name}");
        }
        let bytes = answer.bytes().await.unwrap();
        if shown.starts_with('{') {
            let body: Value = serde_json::from_slice(&bytes).unwrap_or_else(|e| {
                panic!("protocol.md:{at}: the answer is not JSON ({e}): {bytes:?}")
            });
            let shown: Value = serde_json::from_str(&shown)
                .unwrap_or_else(|e| panic!("protocol.md:{at}: the answer shown is not JSON: {e}"));
            if let Err(e) = same_shape(&shown, &body, "") {
                panic!("protocol.md:{at}: {method} {path}: {e}\nanswered: {body}");
            }
        } else if !shown.is_empty() {
            let shown: Vec<u8> = shown
                .split_whitespace()
                .map(|b| u8::from_str_radix(b, 16).expect("a hex byte"))
                .collect();
            assert_eq!(hex(&bytes), hex(&shown), "protocol.md:{at}: {method} {path}: the bytes");
        }
        n_checked += 1;
    }
    assert!(n_checked >= 5, "protocol.md shows {n_checked} HTTP answers");
}

/// Finds every schema in `value` (an OpenAPI document's part) that says nothing of its content:
/// an object without properties, or an empty schema.
fn untyped_schemas(value: &Value, path: &str, out: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            let is_object = map.get("type") == Some(&Value::String("object".into()));
            let described = ["properties", "additionalProperties", "$ref", "oneOf", "allOf"]
                .iter()
                .any(|k| map.contains_key(*k));
            if is_object && !described {
                out.push(path.to_string());
            }
            for (k, v) in map {
                if k == "schema" && v.as_object().is_some_and(|m| m.is_empty()) {
                    out.push(format!("{path}.schema"));
                }
                untyped_schemas(v, &format!("{path}.{k}"), out);
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                untyped_schemas(v, &format!("{path}[{i}]"), out);
            }
        }
        _ => {}
    }
}

/// The served OpenAPI document types every body: no object schema without its fields (the
/// brush and the parameters were untyped objects), and the stroke's status is an enum.
#[tokio::test]
async fn the_openapi_document_types_every_body() {
    let proxy = spawn_proxy().await;
    let openapi: Value =
        proxy.http.get(proxy.url("/v1/openapi.json")).send().await.unwrap().json().await.unwrap();
    let mut untyped = Vec::new();
    untyped_schemas(&openapi, "", &mut untyped);
    assert!(untyped.is_empty(), "untyped schemas in /v1/openapi.json: {untyped:?}");
    let schemas = &openapi["components"]["schemas"];
    for (name, field) in [("Brush", "pressure_response"), ("AcutsParams", "angle_near_anchor")] {
        assert!(schemas[name]["properties"][field].is_object(), "{name}.{field} is not described");
    }
    let status = &schemas["StrokeStatus"]["enum"];
    assert!(status.as_array().is_some_and(|v| v.contains(&Value::from("interrupted"))), "{status}");
}
