//! Frames: the version byte and bincode of a message, or its JSON text.

use super::*;
use crate::protocol::{v4, v5};

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<BINCODE_LIMIT>()
}

fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    encode_version(msg, PROTOCOL_VERSION)
}

fn encode_version<T: Serialize>(msg: &T, version: u16) -> Vec<u8> {
    let body = bincode::serde::encode_to_vec(msg, config()).expect("messages always encode");
    let mut out = Vec::with_capacity(body.len() + 1);
    out.push(version as u8); // lossless: versions are asserted below 256 where declared
    out.extend_from_slice(&body);
    out
}

/// The variant names and count of a message enum (serde's names, which strum derives from the
/// enum itself), so decoding can tell an unknown message from a malformed one without reading
/// error texts.
trait MessageKind {
    const NAMES: &'static [&'static str];
}

impl MessageKind for ClientMessage {
    const NAMES: &'static [&'static str] = <ClientMessage as strum::VariantNames>::VARIANTS;
}

impl MessageKind for ServerMessage {
    const NAMES: &'static [&'static str] = <ServerMessage as strum::VariantNames>::VARIANTS;
}

impl MessageKind for v4::ClientMessageV4 {
    const NAMES: &'static [&'static str] = <v4::ClientMessageV4 as strum::VariantNames>::VARIANTS;
}

impl MessageKind for v5::ClientMessageV5 {
    const NAMES: &'static [&'static str] = <v5::ClientMessageV5 as strum::VariantNames>::VARIANTS;
}

/// Whether the proxy and this codec speak `version`: the current one and the two before.
pub fn is_supported_version(version: u16) -> bool {
    (OLDEST_PROTOCOL_VERSION..=PROTOCOL_VERSION).contains(&version)
}

/// The version a binary frame says it is of (its first byte), when it is one this codec
/// speaks: what the proxy answers a client in before its `hello` names the connection's
/// version, and what it checks every later frame against.
pub fn binary_frame_version(bytes: &[u8]) -> Option<u16> {
    let version = u16::from(*bytes.first()?);
    is_supported_version(version).then_some(version)
}

/// The version byte and body of a binary frame, checked against the limit and the versions
/// this codec reads.
fn split_frame(bytes: &[u8], limit: usize) -> Result<(u16, &[u8]), CodecError> {
    let limit = limit.min(BINCODE_LIMIT);
    if bytes.len() > limit {
        return Err(CodecError::TooLarge { size: bytes.len(), limit });
    }
    let (&version, body) = bytes.split_first().ok_or(CodecError::Empty)?;
    if !is_supported_version(u16::from(version)) {
        return Err(CodecError::Version(version));
    }
    Ok((u16::from(version), body))
}

/// A client frame of any version served, as the current message.
fn decode_client_frame(
    bytes: &[u8],
    limit: usize,
    max_batch: usize,
) -> Result<ClientMessage, CodecError> {
    let (version, body) = split_frame(bytes, limit)?;
    match version {
        v4::VERSION => {
            let names = <v4::ClientMessageV4 as MessageKind>::NAMES.len();
            decode_body::<v4::ClientMessageV4>(body, names, max_batch).map(Into::into)
        }
        v5::VERSION => {
            let names = <v5::ClientMessageV5 as MessageKind>::NAMES.len();
            decode_body::<v5::ClientMessageV5>(body, names, max_batch).map(Into::into)
        }
        _ => decode_body(body, ClientMessage::NAMES.len(), max_batch),
    }
}

/// A server frame of any version served (a version-5 frame has no `PeerSolid` and its own
/// `PeerStrokes`; a version-4 frame has no `PeerPlacement` either).
fn decode_server_frame(bytes: &[u8], limit: usize) -> Result<ServerMessage, CodecError> {
    let (version, body) = split_frame(bytes, limit)?;
    let names = match version {
        v4::VERSION => v4::N_SERVER_MESSAGES,
        v5::VERSION => v5::N_SERVER_MESSAGES,
        _ => ServerMessage::NAMES.len(),
    };
    if version < PROTOCOL_VERSION && body.first() == Some(&(v5::PEER_STROKES_INDEX as u8)) {
        let (_, old): (u32, v5::PeerStrokesV5) = decode_body(body, names, MAX_BATCH_SAMPLES)?;
        return Ok(ServerMessage::PeerStrokes(old.into()));
    }
    decode_body(body, names, MAX_BATCH_SAMPLES)
}

/// `msg` as a frame of the older `version`, which has it (checked by the caller): the same
/// layout but for `PeerStrokes`, written as the variant's index and the old shape (bincode
/// writes an enum so).
fn encode_old_server(msg: &ServerMessage, version: u16) -> Vec<u8> {
    match msg {
        ServerMessage::PeerStrokes(strokes) => {
            encode_version(&(v5::PEER_STROKES_INDEX, v5::PeerStrokesV5::from(strokes)), version)
        }
        msg => encode_version(msg, version),
    }
}

/// `msg` as JSON for a client of the older `version`, which has it: `PeerStrokes` without
/// what version 6 added.
fn encode_old_server_json(msg: &ServerMessage) -> String {
    match msg {
        ServerMessage::PeerStrokes(strokes) => {
            let old = v5::OldServerJson::PeerStrokes(strokes.into());
            serde_json::to_string(&old).expect("messages always serialise to JSON")
        }
        msg => encode_server_json(msg),
    }
}

fn decode_body<T: DeserializeOwned>(
    body: &[u8],
    n_names: usize,
    max_batch: usize,
) -> Result<T, CodecError> {
    // The enum's variant index is bincode's first varint; one byte below 251.
    if let Some(&index) = body.first()
        && usize::from(index) >= n_names
    {
        return Err(CodecError::UnknownMessage(format!(
            "variant index {index}; this version has {n_names} messages"
        )));
    }
    let batch_limit = BatchLimit::set(max_batch);
    let (msg, used) = bincode::serde::decode_from_slice(body, config()).map_err(|e| {
        batch_limit.refused().unwrap_or_else(|| CodecError::Malformed(e.to_string()))
    })?;
    if used != body.len() {
        return Err(CodecError::Malformed(format!("{} trailing bytes", body.len() - used)));
    }
    Ok(msg)
}

fn decode_json<T: DeserializeOwned + MessageKind>(
    text: &str,
    limit: usize,
    max_batch: usize,
) -> Result<T, CodecError> {
    if text.len() > limit {
        return Err(CodecError::TooLarge { size: text.len(), limit });
    }
    let batch_limit = BatchLimit::set(max_batch);
    serde_json::from_str(text).map_err(|e| {
        if let Some(refused) = batch_limit.refused() {
            return refused;
        }
        // Only on the error path: look again to tell an unknown message from bad JSON.
        match serde_json::from_str::<serde_json::Value>(text) {
            Ok(serde_json::Value::Object(map)) if map.len() == 1 => {
                let name = map.keys().next().map(String::as_str).unwrap_or_default();
                if T::NAMES.contains(&name) {
                    CodecError::BadJson(e.to_string())
                } else {
                    CodecError::UnknownMessage(format!("{name:?}"))
                }
            }
            Ok(serde_json::Value::String(name)) if !T::NAMES.contains(&name.as_str()) => {
                CodecError::UnknownMessage(format!("{name:?}"))
            }
            Ok(other) if !other.is_object() => CodecError::UnknownMessage(format!(
                "expected an object with one message, got {}",
                json_kind(&other)
            )),
            _ => CodecError::BadJson(e.to_string()),
        }
    })
}

fn json_kind(value: &serde_json::Value) -> &'static str {
    match value {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "an array",
        serde_json::Value::Object(_) => "an object",
    }
}

/// A binary frame of a client message.
pub fn encode_client(msg: &ClientMessage) -> Vec<u8> {
    encode(msg)
}
/// A binary frame of a server message.
pub fn encode_server(msg: &ServerMessage) -> Vec<u8> {
    encode(msg)
}
/// A binary frame of `msg` as a client of protocol `version` sends it; `None` when that
/// version cannot say it (a placement in version 4) or is not spoken.
pub fn encode_client_as(msg: &ClientMessage, version: u16) -> Option<Vec<u8>> {
    match version {
        PROTOCOL_VERSION => Some(encode(msg)),
        v5::VERSION => v5::ClientMessageV5::from_current(msg).map(|m| encode_version(&m, version)),
        v4::VERSION => v4::ClientMessageV4::from_current(msg).map(|m| encode_version(&m, version)),
        _ => None,
    }
}
/// Whether a client of protocol `version` has `msg` (`PeerSolid` is version 6's,
/// `PeerPlacement` version 5's).
pub fn server_message_exists_in(msg: &ServerMessage, version: u16) -> bool {
    match version {
        PROTOCOL_VERSION => true,
        v5::VERSION => v5::server_message_exists(msg),
        v4::VERSION => v4::server_message_exists(msg),
        _ => false,
    }
}
/// A binary frame of `msg` for a client of protocol `version`; `None` when that version has
/// no such message (`PeerSolid` for versions 5 and 4, `PeerPlacement` for version 4: the
/// connection is not sent it).
pub fn encode_server_as(msg: &ServerMessage, version: u16) -> Option<Vec<u8>> {
    match version {
        PROTOCOL_VERSION => Some(encode(msg)),
        _ if server_message_exists_in(msg, version) => Some(encode_old_server(msg, version)),
        _ => None,
    }
}
/// A JSON text frame of `msg` for a client of protocol `version`; `None` as for
/// [`encode_server_as`].
pub fn encode_server_json_as(msg: &ServerMessage, version: u16) -> Option<String> {
    match version {
        PROTOCOL_VERSION => Some(encode_server_json(msg)),
        _ if server_message_exists_in(msg, version) => Some(encode_old_server_json(msg)),
        _ => None,
    }
}
/// Decodes a binary frame of at most `limit` bytes, of the current version or one of the two
/// before (read as the current message: a version-5 `StrokeBegin` has no solid, a version-4
/// one no placement either).
pub fn decode_client(bytes: &[u8], limit: usize) -> Result<ClientMessage, CodecError> {
    decode_client_frame(bytes, limit, MAX_BATCH_SAMPLES)
}
/// Decodes a binary frame of at most `limit` bytes whose point batch (if any) holds at most
/// `max_batch` samples: a larger count is refused with [`CodecError::BatchTooLarge`] before
/// the samples are read.
pub fn decode_client_limited(
    bytes: &[u8],
    limit: usize,
    max_batch: usize,
) -> Result<ClientMessage, CodecError> {
    decode_client_frame(bytes, limit, max_batch)
}
/// Decodes a binary frame of at most `limit` bytes, of the current version or one of the two
/// before.
pub fn decode_server(bytes: &[u8], limit: usize) -> Result<ServerMessage, CodecError> {
    decode_server_frame(bytes, limit)
}
/// A JSON text frame of a client message.
pub fn encode_client_json(msg: &ClientMessage) -> String {
    serde_json::to_string(msg).expect("messages always serialise to JSON")
}
/// A JSON text frame of a server message.
pub fn encode_server_json(msg: &ServerMessage) -> String {
    serde_json::to_string(msg).expect("messages always serialise to JSON")
}
/// Decodes a JSON text frame of at most `limit` bytes.
pub fn decode_client_json(text: &str, limit: usize) -> Result<ClientMessage, CodecError> {
    decode_json(text, limit, MAX_BATCH_SAMPLES)
}
/// [`decode_client_limited`] for a JSON text frame.
pub fn decode_client_json_limited(
    text: &str,
    limit: usize,
    max_batch: usize,
) -> Result<ClientMessage, CodecError> {
    decode_json(text, limit, max_batch)
}
/// Decodes a JSON text frame of at most `limit` bytes.
pub fn decode_server_json(text: &str, limit: usize) -> Result<ServerMessage, CodecError> {
    decode_json(text, limit, MAX_BATCH_SAMPLES)
}
