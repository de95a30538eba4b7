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
pub const PROTOCOL_VERSION: u16 = 3;
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

// ---------------------------------------------------------------------------------------------
// Bit strings.

const CH_X: usize = 0;
const CH_Y: usize = 1;
const CH_T: usize = 2;
const CH_P: usize = 3;
const STEPS: [f64; 4] = [POSITION_STEP, POSITION_STEP, TIME_STEP, PRESSURE_STEP];
/// Exp-Golomb order of the first value of a channel (tablet coordinates are ~15 bits).
const K_HEAD: [u32; 4] = [14, 14, 8, 10];
/// Exp-Golomb order of the first difference (one sample's motion).
const K_DELTA: [u32; 4] = [5, 5, 3, 4];
/// Starting Exp-Golomb order of the second differences, adapted as they come.
const K_SECOND: [u32; 4] = [2, 2, 0, 1];
const MAX_SHIFT: u32 = 6;
const RAW_CODE: u64 = 7;
/// Longest Exp-Golomb code value (bits); longer ones are malformed.
const MAX_CODE_BITS: u32 = 62;

/// The default shift of a channel: whole stroke units / whole milliseconds, none for pressure.
fn default_shift(channel: usize) -> u32 {
    if channel == CH_P {
        return 0;
    }
    let per_unit = (1.0 / STEPS[channel]) as u64;
    per_unit.trailing_zeros().min(MAX_SHIFT)
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

#[derive(Debug, Default)]
struct BitWriter {
    bytes: Vec<u8>,
    acc: u64,
    n_acc: u32,
}

impl BitWriter {
    /// Writes the low `count` bits of `value`, most significant first.
    fn bits(&mut self, value: u64, count: u32) {
        if count > 32 {
            self.bits(value >> 32, count - 32);
            self.bits(value & 0xffff_ffff, 32);
            return;
        }
        if count == 0 {
            return;
        }
        let value = value & ((1u64 << count) - 1);
        self.acc = (self.acc << count) | value;
        self.n_acc += count;
        while self.n_acc >= 8 {
            self.n_acc -= 8;
            self.bytes.push((self.acc >> self.n_acc) as u8);
        }
        self.acc &= (1u64 << self.n_acc) - 1;
    }

    fn exp_golomb(&mut self, u: u64, k: u32) {
        let v = u + (1u64 << k);
        let len = 64 - v.leading_zeros();
        self.bits(0, len - 1 - k);
        self.bits(v, len);
    }

    fn finish(mut self) -> Vec<u8> {
        if self.n_acc > 0 {
            let pad = 8 - self.n_acc;
            self.bits(0, pad);
        }
        self.bytes
    }
}

/// Where a batch decoder gets its bytes: a slice, or bincode's sequence of `u8`.
trait ByteSource {
    type Error;
    /// The next byte; an error at the end.
    fn next_byte(&mut self) -> Result<u8, Self::Error>;
    fn malformed(message: &str) -> Self::Error;
}

struct BitReader<'a, R: ByteSource> {
    source: &'a mut R,
    byte: u8,
    n_left: u32,
}

impl<R: ByteSource> BitReader<'_, R> {
    fn bit(&mut self) -> Result<bool, R::Error> {
        if self.n_left == 0 {
            self.byte = self.source.next_byte()?;
            self.n_left = 8;
        }
        self.n_left -= 1;
        Ok((self.byte >> self.n_left) & 1 == 1)
    }

    /// Reads `count` (at most 64) bits, most significant first.
    fn bits(&mut self, count: u32) -> Result<u64, R::Error> {
        let mut v = 0u64;
        for _ in 0..count {
            v = (v << 1) | u64::from(self.bit()?);
        }
        Ok(v)
    }

    fn exp_golomb(&mut self, k: u32) -> Result<u64, R::Error> {
        let mut zeros = 0;
        while !self.bit()? {
            zeros += 1;
            if zeros + k + 1 > MAX_CODE_BITS {
                return Err(R::malformed("number code too long"));
            }
        }
        if zeros + k + 1 > MAX_CODE_BITS {
            return Err(R::malformed("number code too long"));
        }
        let rest = self.bits(zeros + k)?;
        let v = (1u64 << (zeros + k)) | rest;
        Ok(v - (1u64 << k))
    }

    /// The padding after the last code must be zero bits.
    fn finish(&mut self) -> Result<(), R::Error> {
        let mask = (1u32 << self.n_left) - 1;
        if u32::from(self.byte) & mask != 0 {
            return Err(R::malformed("non-zero padding bits"));
        }
        Ok(())
    }
}

/// LOCO-I style running estimate of the Exp-Golomb order of second differences.
#[derive(Debug, Clone, Copy)]
struct Adaptive {
    sum: u64,
    count: u64,
}

impl Adaptive {
    fn new(k0: u32) -> Adaptive {
        Adaptive { sum: 2 << k0, count: 2 }
    }

    fn order(&self) -> u32 {
        let mut k = 0;
        while (self.count << k) < self.sum && k < 40 {
            k += 1;
        }
        k
    }

    fn update(&mut self, u: u64) {
        self.sum = self.sum.saturating_add(u);
        self.count += 1;
        if self.count >= 64 {
            self.sum /= 2;
            self.count /= 2;
        }
    }
}

/// How a channel travels in one batch.
#[derive(Debug, Clone, Copy, PartialEq)]
enum ChannelMode {
    Grid { shift: u32 },
    Raw,
}

fn channel_value(s: &Sample, channel: usize) -> f64 {
    match channel {
        CH_X => s.x,
        CH_Y => s.y,
        CH_T => s.t,
        _ => s.p,
    }
}

/// The residual of sample `i` in a channel of step counts: value, first or second difference.
fn residual(steps: &[i64], i: usize) -> i64 {
    match i {
        0 => steps[0],
        1 => steps[1] - steps[0],
        _ => steps[i] - 2 * steps[i - 1] + steps[i - 2],
    }
}

/// Trailing zero bits common to every residual of the given channels (capped at `MAX_SHIFT`).
fn common_shift(channels: &[&[i64]]) -> u32 {
    let mut bits = 0u64;
    for steps in channels {
        for i in 0..steps.len() {
            bits |= residual(steps, i) as u64;
        }
    }
    bits.trailing_zeros().min(MAX_SHIFT)
}

fn write_header(w: &mut BitWriter, mode: ChannelMode, default: u32) {
    match mode {
        ChannelMode::Grid { shift } if shift == default => w.bits(1, 1),
        ChannelMode::Grid { shift } => w.bits(u64::from(shift), 4),
        ChannelMode::Raw => w.bits(RAW_CODE, 4),
    }
}

/// Writes the grid channels `channels` of `steps` (all on the grid) in sample-major order.
fn write_samples(
    w: &mut BitWriter,
    samples: &[Sample],
    steps: &[Vec<i64>; 4],
    modes: &[ChannelMode; 4],
    non_negative: bool,
) {
    let mut adaptive = K_SECOND.map(Adaptive::new);
    for (i, s) in samples.iter().enumerate() {
        for c in 0..4 {
            let shift = match modes[c] {
                ChannelMode::Grid { shift } => shift,
                ChannelMode::Raw => {
                    w.bits(quantize(channel_value(s, c), STEPS[c]).to_bits(), 64);
                    continue;
                }
            };
            let r = residual(&steps[c], i) >> shift;
            let plain = non_negative && (i == 0 || (i == 1 && c == CH_T));
            let u = if plain { r as u64 } else { zigzag(r) };
            match i {
                0 => w.exp_golomb(u, K_HEAD[c]),
                1 => w.exp_golomb(u, K_DELTA[c]),
                _ => {
                    w.exp_golomb(u, adaptive[c].order());
                    adaptive[c].update(u);
                }
            }
        }
    }
}

/// Encodes a batch into its self-delimiting bit string (see the module documentation).
fn encode_batch(samples: &[Sample]) -> Vec<u8> {
    let mut w = BitWriter::default();
    if samples.is_empty() {
        w.bits(0b00, 2);
        return w.finish();
    }
    let steps: [Option<Vec<i64>>; 4] = std::array::from_fn(|c| {
        samples.iter().map(|s| to_steps(channel_value(s, c), STEPS[c])).collect()
    });
    let xy_grid = steps[CH_X].is_some() && steps[CH_Y].is_some();
    let grid = [xy_grid, xy_grid, steps[CH_T].is_some(), steps[CH_P].is_some()];
    let steps: [Vec<i64>; 4] = {
        let mut steps = steps;
        std::array::from_fn(
            |c| if grid[c] { steps[c].take().unwrap_or_default() } else { Vec::new() },
        )
    };

    let non_negative = (0..4).all(|c| !grid[c] || steps[c][0] >= 0)
        && (!grid[CH_T] || samples.len() < 2 || steps[CH_T][1] >= steps[CH_T][0]);

    // Per header group (xy, t, p): the largest usable shift, or the default when usable and
    // cheaper. Groups are coded independently, so choosing each alone gives the shortest batch.
    let mut group_modes = [ChannelMode::Raw; 3];
    let groups: [&[usize]; 3] = [&[CH_X, CH_Y], &[CH_T], &[CH_P]];
    for (g, channels) in groups.iter().enumerate() {
        if !grid[channels[0]] {
            continue;
        }
        let usable =
            common_shift(&channels.iter().map(|&c| steps[c].as_slice()).collect::<Vec<_>>());
        let default = default_shift(channels[0]);
        let cost = |shift: u32, header: u64| {
            header
                + channels
                    .iter()
                    .map(|&c| grid_bits(&steps[c], c, shift, non_negative))
                    .sum::<u64>()
        };
        let shift =
            if default <= usable && cost(default, 1) <= cost(usable, 4) { default } else { usable };
        group_modes[g] = ChannelMode::Grid { shift };
    }
    let modes = [group_modes[0], group_modes[0], group_modes[1], group_modes[2]];

    if non_negative {
        w.bits(0b1, 1);
    } else {
        w.bits(0b01, 2);
    }
    w.exp_golomb(samples.len() as u64 - 1, 0);
    write_header(&mut w, modes[CH_X], default_shift(CH_X));
    write_header(&mut w, modes[CH_T], default_shift(CH_T));
    write_header(&mut w, modes[CH_P], default_shift(CH_P));
    write_samples(&mut w, samples, &steps, &modes, non_negative);
    w.finish()
}

/// The compact point batch of `samples` as bytes, outside any frame: what the proxy stores.
/// Lossless for samples on the grid ([`quantize_sample`]'s output):
/// `decode_point_batch(&encode_point_batch(b)) == b` bit for bit.
pub fn encode_point_batch(samples: &[Sample]) -> Vec<u8> {
    encode_batch(samples)
}

/// Reads bytes written by [`encode_point_batch`]; refuses bytes that end early or go on after
/// the batch.
pub fn decode_point_batch(bytes: &[u8]) -> Result<Vec<Sample>, CodecError> {
    let mut source = SliceSource(bytes.iter());
    let samples = decode_batch(&mut source)?;
    match source.0.len() {
        0 => Ok(samples),
        n => Err(CodecError::Malformed(format!("{n} bytes after the point batch"))),
    }
}

struct SliceSource<'a>(std::slice::Iter<'a, u8>);

impl ByteSource for SliceSource<'_> {
    type Error = CodecError;

    fn next_byte(&mut self) -> Result<u8, CodecError> {
        self.0.next().copied().ok_or_else(|| Self::malformed("cut short"))
    }

    fn malformed(message: &str) -> CodecError {
        CodecError::Malformed(format!("point batch: {message}"))
    }
}

/// Length of an Exp-Golomb code of order `k` for `u`.
fn exp_golomb_bits(u: u64, k: u32) -> u64 {
    let len = 64 - (u + (1u64 << k)).leading_zeros();
    u64::from(2 * len - 1 - k)
}

/// Bits the grid channel `channel` (its step counts `steps`) takes with `shift`.
fn grid_bits(steps: &[i64], channel: usize, shift: u32, non_negative: bool) -> u64 {
    let mut adaptive = Adaptive::new(K_SECOND[channel]);
    let mut bits = 0;
    for i in 0..steps.len() {
        let r = residual(steps, i) >> shift;
        let plain = non_negative && (i == 0 || (i == 1 && channel == CH_T));
        let u = if plain { r as u64 } else { zigzag(r) };
        bits += match i {
            0 => exp_golomb_bits(u, K_HEAD[channel]),
            1 => exp_golomb_bits(u, K_DELTA[channel]),
            _ => {
                let k = adaptive.order();
                adaptive.update(u);
                exp_golomb_bits(u, k)
            }
        };
    }
    bits
}

fn read_header<R: ByteSource>(
    r: &mut BitReader<'_, R>,
    default: u32,
) -> Result<ChannelMode, R::Error> {
    if r.bit()? {
        return Ok(ChannelMode::Grid { shift: default });
    }
    match r.bits(3)? {
        RAW_CODE => Ok(ChannelMode::Raw),
        shift => Ok(ChannelMode::Grid { shift: shift as u32 }),
    }
}

/// Decodes one batch, pulling exactly its bytes from `source`.
fn decode_batch<R: ByteSource>(source: &mut R) -> Result<Vec<Sample>, R::Error> {
    let mut r = BitReader { source, byte: 0, n_left: 0 };
    let non_negative = if r.bit()? {
        true
    } else if r.bit()? {
        false
    } else {
        r.finish()?;
        return Ok(Vec::new());
    };
    let n = r.exp_golomb(0)?.saturating_add(1);
    let limit = BatchLimit::limit();
    if n > limit as u64 {
        BatchLimit::refuse(BatchRefused { n: Some(n), limit });
        return Err(R::malformed(&format!(
            "batch of {n} samples is larger than the limit of {limit}"
        )));
    }
    let n = n as usize;
    let xy = read_header(&mut r, default_shift(CH_X))?;
    let t = read_header(&mut r, default_shift(CH_T))?;
    let p = read_header(&mut r, default_shift(CH_P))?;
    let modes = [xy, xy, t, p];

    let mut adaptive = K_SECOND.map(Adaptive::new);
    // The last two step counts of each channel.
    let mut prev = [[0i64; 2]; 4];
    let mut samples = Vec::with_capacity(n.min(1024));
    for i in 0..n {
        let mut values = [0f64; 4];
        for c in 0..4 {
            let shift = match modes[c] {
                ChannelMode::Grid { shift } => shift,
                ChannelMode::Raw => {
                    values[c] = f64::from_bits(r.bits(64)?);
                    continue;
                }
            };
            let plain = non_negative && (i == 0 || (i == 1 && c == CH_T));
            let u = match i {
                0 => r.exp_golomb(K_HEAD[c])?,
                1 => r.exp_golomb(K_DELTA[c])?,
                _ => {
                    let u = r.exp_golomb(adaptive[c].order())?;
                    adaptive[c].update(u);
                    u
                }
            };
            // Codes are at most 62 bits, so these fit an i64 with room for the shift.
            let residual = if plain { u as i64 } else { unzigzag(u) };
            let residual = residual
                .checked_mul(1 << shift)
                .ok_or_else(|| R::malformed("value out of range"))?;
            let [older, last] = prev[c];
            let predicted = match i {
                0 => 0,
                1 => last,
                _ => 2 * last - older,
            };
            let k = predicted
                .checked_add(residual)
                .filter(|k| k.abs() <= MAX_STEPS)
                .ok_or_else(|| R::malformed("value out of range"))?;
            prev[c] = [last, k];
            values[c] = from_steps(k, STEPS[c]);
        }
        samples.push(Sample::new(values[0], values[1], values[2], values[3]));
    }
    r.finish()?;
    Ok(samples)
}

impl Serialize for PointBatch {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        if serializer.is_human_readable() {
            return self.0.serialize(serializer);
        }
        let bytes = encode_batch(&self.0);
        let mut tuple = serializer.serialize_tuple(bytes.len())?;
        for byte in &bytes {
            tuple.serialize_element(byte)?;
        }
        tuple.end()
    }
}

struct SeqSource<'de, A>(A, std::marker::PhantomData<&'de ()>);

impl<'de, A: SeqAccess<'de>> ByteSource for SeqSource<'de, A> {
    type Error = A::Error;

    fn next_byte(&mut self) -> Result<u8, A::Error> {
        self.0.next_element::<u8>()?.ok_or_else(|| Self::malformed("point batch cut short"))
    }

    fn malformed(message: &str) -> A::Error {
        serde::de::Error::custom(format_args!("point batch: {message}"))
    }
}

struct BatchVisitor;

impl<'de> Visitor<'de> for BatchVisitor {
    type Value = PointBatch;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a compact point batch")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<PointBatch, A::Error> {
        decode_batch(&mut SeqSource(seq, std::marker::PhantomData)).map(PointBatch)
    }
}

/// A JSON batch: an array of samples, refused at the first sample past the limit.
struct JsonBatchVisitor;

impl<'de> Visitor<'de> for JsonBatchVisitor {
    type Value = PointBatch;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("an array of [x, y, t, p] samples")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<PointBatch, A::Error> {
        let limit = BatchLimit::limit();
        let mut samples = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(limit).min(1024));
        while let Some(sample) = seq.next_element::<Sample>()? {
            if samples.len() == limit {
                BatchLimit::refuse(BatchRefused { n: None, limit });
                return Err(serde::de::Error::custom(format_args!(
                    "batch of more than {limit} samples"
                )));
            }
            samples.push(sample);
        }
        Ok(PointBatch(samples))
    }
}

impl<'de> Deserialize<'de> for PointBatch {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<PointBatch, D::Error> {
        if deserializer.is_human_readable() {
            return deserializer.deserialize_seq(JsonBatchVisitor);
        }
        // The bit string delimits itself: the visitor takes exactly the bytes it needs.
        deserializer.deserialize_tuple(usize::MAX, BatchVisitor)
    }
}

// ---------------------------------------------------------------------------------------------
// Frames.

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<BINCODE_LIMIT>()
}

fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    let body = bincode::serde::encode_to_vec(msg, config()).expect("messages always encode");
    let mut out = Vec::with_capacity(body.len() + 1);
    out.push(PROTOCOL_VERSION as u8); // lossless: asserted where the constant is declared
    out.extend_from_slice(&body);
    out
}

/// The variant names and count of a message enum, so decoding can tell an unknown message from
/// a malformed one without reading error texts.
trait MessageKind {
    const NAMES: &'static [&'static str];
}

impl MessageKind for ClientMessage {
    const NAMES: &'static [&'static str] =
        &["hello", "stroke_begin", "points", "stroke_end", "ping"];
}

impl MessageKind for ServerMessage {
    const NAMES: &'static [&'static str] = &[
        "welcome",
        "ack",
        "retained",
        "stroke_done",
        "pong",
        "error",
        "peer_joined",
        "peer_left",
        "peer_stroke_begin",
        "peer_retained",
        "peer_stroke_done",
        "peer_mesh",
        "synced",
    ];
}

fn decode<T: DeserializeOwned + MessageKind>(
    bytes: &[u8],
    limit: usize,
    max_batch: usize,
) -> Result<T, CodecError> {
    let limit = limit.min(BINCODE_LIMIT);
    if bytes.len() > limit {
        return Err(CodecError::TooLarge { size: bytes.len(), limit });
    }
    let (&version, body) = bytes.split_first().ok_or(CodecError::Empty)?;
    if u16::from(version) != PROTOCOL_VERSION {
        return Err(CodecError::Version(version));
    }
    // The enum's variant index is bincode's first varint; one byte below 251.
    if let Some(&index) = body.first()
        && usize::from(index) >= T::NAMES.len()
    {
        return Err(CodecError::UnknownMessage(format!(
            "variant index {index}; this version has {} messages",
            T::NAMES.len()
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
/// Decodes a binary frame of at most `limit` bytes.
pub fn decode_client(bytes: &[u8], limit: usize) -> Result<ClientMessage, CodecError> {
    decode(bytes, limit, MAX_BATCH_SAMPLES)
}
/// Decodes a binary frame of at most `limit` bytes whose point batch (if any) holds at most
/// `max_batch` samples: a larger count is refused with [`CodecError::BatchTooLarge`] before
/// the samples are read.
pub fn decode_client_limited(
    bytes: &[u8],
    limit: usize,
    max_batch: usize,
) -> Result<ClientMessage, CodecError> {
    decode(bytes, limit, max_batch)
}
/// Decodes a binary frame of at most `limit` bytes.
pub fn decode_server(bytes: &[u8], limit: usize) -> Result<ServerMessage, CodecError> {
    decode(bytes, limit, MAX_BATCH_SAMPLES)
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
