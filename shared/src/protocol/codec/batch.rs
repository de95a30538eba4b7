//! The compact point batch (binary only): see the layout in [`super`]'s docs.

use super::bits::*;
use super::*;

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

/// The default shift of a channel: whole stroke units / whole milliseconds, none for pressure.
fn default_shift(channel: usize) -> u32 {
    if channel == CH_P {
        return 0;
    }
    let per_unit = (1.0 / STEPS[channel]) as u64;
    per_unit.trailing_zeros().min(MAX_SHIFT)
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
    // Real strokes take 2 to 8 bytes a sample: room for that, so the bytes are not moved as
    // they grow (the writer encodes every sample the proxy stores, twice).
    let mut w = BitWriter::with_capacity(4 + samples.len() * 8);
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
    let mut r = BitReader::new(source);
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
