//! The one place that knows the wire encoding.
//!
//! # Frames
//!
//! - **Binary**: one version byte ([`PROTOCOL_VERSION`]), then bincode 2 (serde mode, standard
//!   config: little endian, varint integers) of [`ClientMessage`] or [`ServerMessage`]. A frame
//!   longer than the caller's limit (and never longer than 16 MiB, bincode's own allocation
//!   limit, so a forged length prefix cannot allocate more) is refused before decoding; a wrong
//!   version byte, a body that does not decode, or trailing bytes are refused too.
//! - **JSON text**: serde's externally tagged form with snake_case names,
//!   `{"points":{"stroke":"…","seq":0,"points":[[x,y,t,p],…]}}`. A [`PointBatch`] is a plain
//!   array of `[x, y, t, p]`, exact to the last bit of each `f64`. JSON has no NaN or infinity:
//!   serde_json writes a non-finite value as `null`, which decoding refuses as bad JSON.
//!
//! # The compact point batch (binary only)
//!
//! Each channel is quantised to a fixed grid: x and y to [`POSITION_STEP`] = 1/16 stroke unit
//! (CSS px or tablet units), t to [`TIME_STEP`] = 1/8 ms (ms since the stroke's first sample),
//! p to [`PRESSURE_STEP`] = 1/1024. The steps are powers of two, so [`quantize_sample`] is exact
//! arithmetic: it moves a value by at most half a step, and decoding returns grid values
//! bit-exactly (`decode(encode(b)) == quantize(b)`, and `quantize` is idempotent).
//!
//! A batch is self-contained (it never refers to an earlier batch) and is one bit string,
//! written most significant bit first and padded with zero bits to a whole byte:
//!
//! ```text
//! mode        '1' = samples follow, heads are non-negative
//!             '01' = samples follow, heads are signed (zigzag)   '00' = empty batch
//! n - 1       Exp-Golomb order 0
//! headers     for xy (shared), t, p: '1' = the default shift, or '0' + 3 bits s:
//!             s in 0..=6 is the shift, s = 7 means the channel is sent raw
//! samples     sample-major: for each sample, x, y, t, p:
//!               sample 0   the value itself (the "head")       Exp-Golomb order K_HEAD
//!               sample 1   first difference                    Exp-Golomb order K_DELTA
//!               sample i   second difference (linear            Exp-Golomb, order adapted
//!                          prediction 2 v[i-1] - v[i-2])        to the running mean (LOCO-I)
//!             every value is in steps, shifted right by the channel's shift and zigzagged,
//!             except the heads and t's first difference in '1' mode (plain non-negative);
//!             a raw channel carries the 64 bits of each quantised f64 instead
//! padding     zero bits up to the byte boundary
//! ```
//!
//! The shift is the number of trailing zero bits common to every value of the channel in the
//! batch (capped at 6): integer tablet coordinates on a 1/16 grid are all multiples of 16, so
//! they cost what integers cost. The default shifts are "whole stroke units" for x and y (4),
//! "whole milliseconds" for t (3) and 0 for p. The encoder picks whichever of the default and
//! the largest usable shift is cheaper.
//!
//! For bincode the bit string is written as a tuple of bytes, i.e. with no length prefix: it is
//! self-delimiting (the count comes first), which saves a byte per frame, a sixth of a
//! two-sample batch. The decoder pulls bytes one by one and stops at the end of the bit string.
//!
//! **Values off the integer grid.** A value whose step count exceeds [`MAX_STEPS`] = 2^48 in
//! magnitude (e.g. |x| > 2^44 stroke units), and every non-finite value, makes its channel raw
//! for that batch: the exact `f64` goes over the wire, NaN and infinity included. So encoding
//! never fails and never panics, `quantize_sample` leaves such values as they are, and the
//! proxy's sample validation refuses them with `bad_sample` naming the field, as it would for
//! JSON input.
//!
//! **Decoding never panics** on any bytes: every count and value is bounded (a batch holds at
//! most [`MAX_BATCH_SAMPLES`] samples, Exp-Golomb codes at most 62 bits, values at most
//! [`MAX_STEPS`]), arithmetic is checked, and nothing is allocated ahead of the bytes that back
//! it (the sample vector grows as samples are read, each of which costs at least 4 bits).
//!
//! Real pen data (SVC2004 at 100 Hz, SigComp2011 Dutch at 200 Hz, tablet units) costs, in
//! payload bytes per sample: 7.5 to 8.1 for one-sample batches, 5.6 to 5.9 for two, 4.4 to 5.1
//! for three, 2.4 to 3.4 for 16, and 1.9 to 3.1 for whole strokes (table in `tests/codec.rs`).

use serde::de::{DeserializeOwned, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{ClientMessage, PointBatch, ServerMessage};
use crate::model::Sample;

/// Version byte that opens every binary frame, and the version a `Hello` names.
///
/// 2: `AcutsParams` carries the pressure gate as an enum and the `angle_near_anchor` flag, so
/// a version-1 peer would misread a session's parameters.
/// 3: `Hello` carries the participant's `key`, and `ErrorCode` has `not_owner`.
/// 4: `Brush` carries a `color`; strokes can be taken back and brought back (`RemoveStroke`,
/// `RestoreStroke`, `StrokeRemoved`, `StrokeRestored`, `ErrorCode::StrokeOpen`); a participant
/// can change its name (`Rename`, `PeerRenamed`); a history's strokes come several to a
/// message (`PeerStrokes`).
/// 5: strokes have a placement in 3D (`StrokeBegin.placement`, `SetPlacement`,
/// `PeerPlacement`).
/// 6: strokes have a solid (`StrokeBegin.solid`, `SetSolid`, `PeerSolid`,
/// `ErrorCode::BadSolid`), and a history's stroke carries its placement and solid
/// (`HistoryStroke.placement`, `.solid`). The proxy serves versions 5 and 4 beside it
/// ([`OLDEST_PROTOCOL_VERSION`]), each sent only what its version has.
pub const PROTOCOL_VERSION: u16 = 6;
/// The oldest version the proxy still serves: its clients draw and watch, and are never told
/// of placements nor solids (every stroke reaches them in its own plane's coordinates).
pub const OLDEST_PROTOCOL_VERSION: u16 = 4;
// Binary frames carry the version in one byte.
const _: () = assert!(PROTOCOL_VERSION <= u8::MAX as u16);
/// Default largest frame a decoder accepts.
pub const MAX_FRAME_BYTES_DEFAULT: usize = 256 * 1024;
/// Quantisation step of x and y in the binary encoding (stroke units). A power of two.
pub const POSITION_STEP: f64 = 1.0 / 16.0;
/// Quantisation step of t (ms). A power of two.
pub const TIME_STEP: f64 = 1.0 / 8.0;
/// Quantisation step of p. A power of two.
pub const PRESSURE_STEP: f64 = 1.0 / 1024.0;
/// Largest magnitude, in steps, of a value sent on the grid; larger ones are sent raw.
pub const MAX_STEPS: i64 = 1 << 48;
/// Most samples one batch may hold; a larger count is refused when decoding. A caller with a
/// lower limit passes it to [`decode_client_limited`], which refuses a larger count before
/// decoding (or allocating for) the samples.
pub const MAX_BATCH_SAMPLES: usize = 1 << 20;

thread_local! {
    /// The batch limit of the frame being decoded on this thread, and the batch it refused.
    /// serde gives a `Deserialize` impl no context, and decoding is synchronous, so the limit
    /// reaches [`PointBatch`]'s decoder this way; [`BatchLimit`] sets and restores it.
    static BATCH_LIMIT: std::cell::Cell<(usize, Option<BatchRefused>)> =
        const { std::cell::Cell::new((MAX_BATCH_SAMPLES, None)) };
}

/// A batch over the limit: its count (binary), or only that it has more (JSON).
#[derive(Debug, Clone, Copy, PartialEq)]
struct BatchRefused {
    n: Option<u64>,
    limit: usize,
}

/// Sets the batch limit for one decode on this thread; restores the previous one when dropped.
struct BatchLimit(usize);

impl BatchLimit {
    fn set(limit: usize) -> BatchLimit {
        let limit = limit.min(MAX_BATCH_SAMPLES);
        BatchLimit(BATCH_LIMIT.replace((limit, None)).0)
    }

    fn limit() -> usize {
        BATCH_LIMIT.get().0
    }

    fn refuse(refused: BatchRefused) {
        BATCH_LIMIT.set((refused.limit, Some(refused)));
    }

    /// The batch this decode refused, if that is why it failed.
    fn refused(&self) -> Option<CodecError> {
        BATCH_LIMIT.get().1.map(|r| CodecError::BatchTooLarge { n: r.n, limit: r.limit })
    }
}

impl Drop for BatchLimit {
    fn drop(&mut self) {
        BATCH_LIMIT.set((self.0, None));
    }
}

/// bincode's own limit on what one decode may claim (string and vector lengths).
const BINCODE_LIMIT: usize = 16 * 1024 * 1024;

// The grid is exact only for power-of-two steps.
const _: () = {
    const fn is_power_of_two(step: f64) -> bool {
        step > 0.0 && step.to_bits() & ((1u64 << 52) - 1) == 0
    }
    assert!(is_power_of_two(POSITION_STEP));
    assert!(is_power_of_two(TIME_STEP));
    assert!(is_power_of_two(PRESSURE_STEP));
};

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
    /// Well-formed framing that names a message this protocol version does not have.
    #[error("unknown message: {0}")]
    UnknownMessage(String),
    /// A point batch with more samples than the caller's limit (`n`: its count, when known
    /// before reading them).
    #[error("batch of {} samples is larger than the limit of {limit}",
            .n.map_or_else(|| "more".to_string(), |n| n.to_string()))]
    BatchTooLarge { n: Option<u64>, limit: usize },
}

/// The step count of `v` on a grid of `step`, if it is finite and within [`MAX_STEPS`].
fn to_steps(v: f64, step: f64) -> Option<i64> {
    let k = (v / step).round();
    // NaN fails the comparison.
    if k.abs() <= MAX_STEPS as f64 { Some(k as i64) } else { None }
}

fn from_steps(k: i64, step: f64) -> f64 {
    // `k` is at most 2^48 in magnitude: exact in f64, and 0 gives +0.0.
    k as f64 * step
}

fn quantize(v: f64, step: f64) -> f64 {
    match to_steps(v, step) {
        Some(k) => from_steps(k, step),
        None => v,
    }
}

/// Snaps a sample to the quantisation grid of the binary encoding: each channel moves by at
/// most half its step. Non-finite values and values beyond [`MAX_STEPS`] steps are left as they
/// are (they travel raw). `-0.0` becomes `0.0`.
pub fn quantize_sample(s: &Sample) -> Sample {
    Sample::new(
        quantize(s.x, POSITION_STEP),
        quantize(s.y, POSITION_STEP),
        quantize(s.t, TIME_STEP),
        quantize(s.p, PRESSURE_STEP),
    )
}

mod batch;
mod bits;
mod frames;

pub use batch::{decode_point_batch, encode_point_batch};
pub use frames::{
    binary_frame_version, encode_client_as, encode_server_as, encode_server_json_as,
    is_supported_version, server_message_exists_in,
};
pub use frames::{
    decode_client, decode_client_json, decode_client_json_limited, decode_client_limited,
    decode_server, decode_server_json, encode_client, encode_client_json, encode_server,
    encode_server_json,
};
