//! The one place that knows the wire encoding.
//!
//! PLACEHOLDER: `PointBatch` is not yet quantised; binary frames carry f64 samples.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{ClientMessage, PointBatch, ServerMessage};
use crate::model::Sample;

/// Version byte that opens every binary frame.
pub const PROTOCOL_VERSION: u16 = 1;
/// Default largest frame a decoder accepts.
pub const MAX_FRAME_BYTES_DEFAULT: usize = 256 * 1024;
/// Quantisation step of x and y in the binary encoding (stroke units).
pub const POSITION_STEP: f64 = 1.0 / 16.0;
/// Quantisation step of t (ms).
pub const TIME_STEP: f64 = 1.0 / 8.0;
/// Quantisation step of p.
pub const PRESSURE_STEP: f64 = 1.0 / 4096.0;

/// A frame that cannot be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CodecError {
    #[error("frame of {size} bytes is larger than the limit of {limit} bytes")]
    TooLarge { size: usize, limit: usize },
    #[error("empty frame")]
    Empty,
    #[error("unsupported binary protocol version {0}")]
    Version(u8),
    #[error("malformed binary frame: {0}")]
    Malformed(String),
    #[error("bad JSON message: {0}")]
    BadJson(String),
}

/// Snaps a sample to the quantisation grid of the binary encoding.
pub fn quantize_sample(s: &Sample) -> Sample {
    let q = |v: f64, step: f64| (v / step).round() * step;
    Sample::new(
        q(s.x, POSITION_STEP),
        q(s.y, POSITION_STEP),
        q(s.t, TIME_STEP),
        q(s.p, PRESSURE_STEP),
    )
}

impl Serialize for PointBatch {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for PointBatch {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<PointBatch, D::Error> {
        Ok(PointBatch(Vec::<Sample>::deserialize(deserializer)?))
    }
}

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<{ 16 * 1024 * 1024 }>()
}

fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = vec![PROTOCOL_VERSION as u8];
    bincode::serde::encode_into_std_write(msg, &mut out, config())
        .expect("encoding into a Vec cannot fail");
    out
}

fn decode<T: DeserializeOwned>(bytes: &[u8], limit: usize) -> Result<T, CodecError> {
    if bytes.len() > limit {
        return Err(CodecError::TooLarge { size: bytes.len(), limit });
    }
    let (&version, body) = bytes.split_first().ok_or(CodecError::Empty)?;
    if u16::from(version) != PROTOCOL_VERSION {
        return Err(CodecError::Version(version));
    }
    let (msg, used) = bincode::serde::decode_from_slice(body, config())
        .map_err(|e| CodecError::Malformed(e.to_string()))?;
    if used != body.len() {
        return Err(CodecError::Malformed(format!("{} trailing bytes", body.len() - used)));
    }
    Ok(msg)
}

fn decode_json<T: DeserializeOwned>(text: &str, limit: usize) -> Result<T, CodecError> {
    if text.len() > limit {
        return Err(CodecError::TooLarge { size: text.len(), limit });
    }
    serde_json::from_str(text).map_err(|e| CodecError::BadJson(e.to_string()))
}

pub fn encode_client(msg: &ClientMessage) -> Vec<u8> {
    encode(msg)
}
pub fn encode_server(msg: &ServerMessage) -> Vec<u8> {
    encode(msg)
}
pub fn decode_client(bytes: &[u8], limit: usize) -> Result<ClientMessage, CodecError> {
    decode(bytes, limit)
}
pub fn decode_server(bytes: &[u8], limit: usize) -> Result<ServerMessage, CodecError> {
    decode(bytes, limit)
}
pub fn encode_client_json(msg: &ClientMessage) -> String {
    serde_json::to_string(msg).expect("messages always serialise to JSON")
}
pub fn encode_server_json(msg: &ServerMessage) -> String {
    serde_json::to_string(msg).expect("messages always serialise to JSON")
}
pub fn decode_client_json(text: &str, limit: usize) -> Result<ClientMessage, CodecError> {
    decode_json(text, limit)
}
pub fn decode_server_json(text: &str, limit: usize) -> Result<ServerMessage, CodecError> {
    decode_json(text, limit)
}
