// The compact point batch of the protocol's binary encoding (docs/protocol.md, "The compact
// point batch"), read and written for codec.js: one bit string, most significant bit first; a
// mode, n − 1, a header per channel group (x and y, t, p), then the samples sample-major, each
// channel's head, first difference and second differences in Exp-Golomb codes.

import { FrameError, describe } from "./frame-error.js";

/// Each channel's grid step: x, y 1/16 unit, t 1/8 ms, p 1/1024.
export const STEPS = [1 / 16, 1 / 16, 1 / 8, 1 / 1024];
const GROUP_OF = [0, 0, 1, 2]; // x, y -> the x/y group; t; p
const GROUPS = [[0, 1], [2], [3]];
const DEFAULT_SHIFT = [4, 3, 0];
const MAX_SHIFT = 6;
const RAW = 7;
const K_HEAD = [14, 14, 8, 10];
const K_DELTA = [5, 5, 3, 4];
const K_SECOND = [2, 2, 0, 1];
const MAX_ORDER = 40;
const MAX_STEPS = 2 ** 48;
/// The most samples a batch holds, whatever the proxy's setting.
export const MAX_BATCH_SAMPLES = 2 ** 20;
const MAX_CODE_BITS = 62;
const T = 2; // t's channel
const POW2 = Array.from({ length: 64 }, (_, i) => 2 ** i);

const zigzag = (v) => (v >= 0 ? 2 * v : -2 * v - 1);
const unzigzag = (u) => (u % 2 === 0 ? u / 2 : -(u + 1) / 2);

function bitLength(v) {
  const hi = Math.floor(v / 2 ** 32);
  return hi ? 64 - Math.clz32(hi) : 32 - Math.clz32(v >>> 0);
}

/// The length in bits of the Exp-Golomb code of order `k` of `u`.
const codeLength = (u, k) => 2 * bitLength(u + POW2[k]) - 1 - k;

/// LOCO-I's running order of a channel's second differences: the smallest `k` with
/// `count · 2^k ≥ sum` (at most 40). `sum` is a number while it is below 2^53; in the rare
/// batch where it would pass, it goes on as the BigInt `big`, so the order is exact whatever
/// the values.
class Adaptive {
  constructor(channel) {
    this.sum = 2 * 2 ** K_SECOND[channel];
    this.big = null;
    this.count = 2;
  }

  order() {
    let k = 0;
    if (this.big === null) {
      for (let c = this.count; c < this.sum && k < MAX_ORDER; c *= 2) k++;
    } else {
      while (BigInt(this.count) << BigInt(k) < this.big && k < MAX_ORDER) k++;
    }
    return k;
  }

  add(u) {
    if (this.big !== null) this.big += BigInt(u);
    else if (this.sum + u > Number.MAX_SAFE_INTEGER) this.big = BigInt(this.sum) + BigInt(u);
    else this.sum += u;
    this.count += 1;
    if (this.count === 64) {
      this.count = 32;
      if (this.big === null) {
        this.sum = Math.floor(this.sum / 2);
      } else {
        this.big /= 2n;
        if (this.big <= BigInt(Number.MAX_SAFE_INTEGER)) {
          this.sum = Number(this.big);
          this.big = null;
        }
      }
    }
  }
}

/// The batch's bits, most significant first, read a byte's worth at a time. `sample` and
/// `channel` say where it is, for an error's words (set by the caller, cheaply).
class BitReader {
  constructor(data, pos, path) {
    this.data = data;
    this.at = pos * 8; // the next bit
    this.limit = data.length * 8;
    this.path = path;
    this.sample = -1; // -1: the batch's header
    this.channel = 0;
  }

  where() {
    if (this.sample < 0) return `${this.path}: the batch's header`;
    const what = this.sample === 0 ? "head" : this.sample === 1 ? "first difference" : "second difference";
    return `${this.path}: sample ${this.sample}'s ${what} of ${"xytp"[this.channel]}`;
  }

  truncated() {
    return new FrameError(`${this.where()}: truncated frame: the point batch goes past the frame's end (byte ${this.data.length})`);
  }

  one() {
    if (this.at >= this.limit) throw this.truncated();
    const b = (this.data[this.at >> 3] >> (7 - (this.at & 7))) & 1;
    this.at++;
    return b;
  }

  /// `n` bits (at most 53) as a number.
  bits(n) {
    if (this.at + n > this.limit) throw this.truncated();
    let v = 0;
    while (n > 0) {
      const left = 8 - (this.at & 7); // bits left in this byte
      const take = left < n ? left : n;
      const byte = this.data[this.at >> 3];
      v = v * (1 << take) + ((byte >> (left - take)) & ((1 << take) - 1));
      this.at += take;
      n -= take;
    }
    return v;
  }

  /// An Exp-Golomb code of order `k`: its zeros counted a byte at a time.
  golomb(k) {
    let zeros = 0;
    for (;;) {
      if (this.at >= this.limit) throw this.truncated();
      const offset = this.at & 7;
      const rest = (this.data[this.at >> 3] << offset) & 0xff; // this byte's unread bits, first at bit 7
      if (rest === 0) {
        zeros += 8 - offset;
        this.at += 8 - offset;
      } else {
        const lead = Math.clz32(rest) - 24;
        zeros += lead;
        this.at += lead + 1; // past the one bit
        break;
      }
      // "A code's value `v` is at most 62 bits" (its zeros + k + 1); the zeros come on top: a
      // head of 2^48 steps is 35 zeros and a 50-bit value, which the proxy reads.
      if (zeros + k + 1 > MAX_CODE_BITS) break;
    }
    if (zeros + k + 1 > MAX_CODE_BITS) throw new FrameError(`${this.where()}: an Exp-Golomb value longer than ${MAX_CODE_BITS} bits`);
    if (zeros + k > 52) {
      throw new FrameError(`${this.where()}: a value of ${zeros + k + 1} bits, past what a sample on the grid needs (the page reads up to 53)`);
    }
    // The leading one bit was read: v = 2^(zeros + k) + r, u = v − 2^k.
    return POW2[zeros + k] + this.bits(zeros + k) - POW2[k];
  }

  f64() {
    const bytes = new Uint8Array(8);
    for (let i = 0; i < 8; i++) bytes[i] = this.bits(8);
    return new DataView(bytes.buffer).getFloat64(0, false);
  }

  /// Ends the batch: the padding up to the byte boundary must be zero bits; the byte after it.
  end() {
    while (this.at & 7) {
      if (this.one() !== 0) throw new FrameError(`${this.path}: the point batch's padding bits are not zero`);
    }
    return this.at >> 3;
  }
}

/// Reads a batch from `data` at byte `pos`: its samples and the byte after it.
export function readBatch(data, pos, path = "points") {
  const r = new BitReader(data, pos, path);
  let signedHeads;
  if (r.one() === 1) signedHeads = false;
  else if (r.one() === 1) signedHeads = true;
  else return { points: [], end: r.end() };
  const n = r.golomb(0) + 1;
  if (n > MAX_BATCH_SAMPLES) throw new FrameError(`${path}: a batch of ${n} samples (at most ${MAX_BATCH_SAMPLES})`);
  // Each sample takes at least one bit per channel: a count past the frame's bits is truncated.
  if (4 * n > r.limit - r.at) throw new FrameError(`${path}: truncated frame: ${n} samples cannot fit in the ${r.limit - r.at} bits left`);
  const shifts = GROUPS.map((_, g) => (r.one() === 1 ? DEFAULT_SHIFT[g] : r.bits(3)));
  const points = new Array(n);
  const prev = [0, 0, 0, 0]; // v[i-1] per channel, in steps
  const prev2 = [0, 0, 0, 0]; // v[i-2]
  const adaptive = [0, 1, 2, 3].map((c) => new Adaptive(c));
  const scale = shifts.map((s) => 2 ** s);
  for (let i = 0; i < n; i++) {
    const sample = [0, 0, 0, 0];
    r.sample = i;
    for (let c = 0; c < 4; c++) {
      const g = GROUP_OF[c];
      r.channel = c;
      if (shifts[g] === RAW) {
        sample[c] = r.f64();
        continue;
      }
      let v;
      if (i === 0) {
        const u = r.golomb(K_HEAD[c]);
        v = (signedHeads ? unzigzag(u) : u) * scale[g];
      } else if (i === 1) {
        const u = r.golomb(K_DELTA[c]);
        v = prev[c] + (signedHeads || c !== T ? unzigzag(u) : u) * scale[g];
      } else {
        const a = adaptive[c];
        const u = r.golomb(a.order());
        a.add(u);
        v = 2 * prev[c] - prev2[c] + unzigzag(u) * scale[g];
      }
      if (!Number.isSafeInteger(v)) throw new FrameError(`${path}: sample ${i}'s ${"xytp"[c]} is ${v} steps, past what the page reads exactly (2^53)`);
      prev2[c] = prev[c];
      prev[c] = v;
      sample[c] = v * STEPS[c] + 0; // + 0: a zero is +0
    }
    points[i] = sample;
  }
  return { points, end: r.end() };
}

class BitWriter {
  constructor() {
    this.out = [];
    this.cur = 0;
    this.n = 0; // bits in cur
  }

  one(b) {
    this.cur = (this.cur << 1) | b;
    if (++this.n === 8) {
      this.out.push(this.cur);
      this.cur = 0;
      this.n = 0;
    }
  }

  /// `value` (a non-negative integer below 2^53) in `n` bits, most significant first, a byte's
  /// worth at a time.
  bits(value, n) {
    while (n > 0) {
      const take = Math.min(8 - this.n, n);
      n -= take;
      const chunk = Math.floor(value / POW2[n]) % POW2[take];
      this.cur = (this.cur << take) | chunk;
      this.n += take;
      if (this.n === 8) {
        this.out.push(this.cur);
        this.cur = 0;
        this.n = 0;
      }
    }
  }

  golomb(u, k) {
    const v = u + POW2[k];
    const length = bitLength(v);
    this.bits(0, length - 1 - k);
    this.bits(v, length);
  }

  f64(value) {
    const bytes = new Uint8Array(8);
    new DataView(bytes.buffer).setFloat64(0, value, false);
    for (const b of bytes) this.bits(b, 8);
  }

  bytes() {
    if (this.n) this.bits(0, 8 - this.n);
    return Uint8Array.from(this.out);
  }
}

/// Steps of `value` on a grid of `step`: rounded half away from zero (−0 becomes 0); null when
/// the value must travel raw (not finite, or beyond MAX_STEPS).
function quantise(value, step) {
  if (!Number.isFinite(value)) return null;
  const s = value / step;
  const steps = Math.sign(s) * Math.round(Math.abs(s)) + 0;
  return Math.abs(steps) > MAX_STEPS ? null : steps;
}

/// The batch of `points` (`[[x, y, t, p], …]`) as bytes, with the proxy's choice of shifts
/// (per group the largest usable one, or the default when it is usable and no longer).
export function encodeBatch(points, path = "points") {
  if (!Array.isArray(points)) throw new FrameError(`${path}: ${describe(points)} is not a list of samples`);
  const n = points.length;
  const w = new BitWriter();
  if (n === 0) {
    w.one(0);
    w.one(0);
    return w.bytes();
  }
  if (n > MAX_BATCH_SAMPLES) throw new FrameError(`${path}: ${n} samples (at most ${MAX_BATCH_SAMPLES})`);
  points.forEach((p, i) => {
    if (!Array.isArray(p) || p.length !== 4 || p.some((v) => typeof v !== "number")) {
      throw new FrameError(`${path}[${i}]: a sample is [x, y, t, p], four numbers; got ${JSON.stringify(p)}`);
    }
  });
  // Step counts per channel; a group with a value off the grid's range travels raw.
  const steps = [0, 1, 2, 3].map((c) => points.map((p) => quantise(p[c], STEPS[c])));
  const raw = GROUPS.map((chs) => chs.some((c) => steps[c].some((v) => v === null)));
  const signedHeads = !(
    [0, 1, 2, 3].every((c) => raw[GROUP_OF[c]] || steps[c][0] >= 0) &&
    (n < 2 || raw[GROUP_OF[T]] || steps[T][1] >= steps[T][0])
  );
  // Each channel's residuals: the head, the first difference, then the second differences.
  const residuals = steps.map((v, c) =>
    raw[GROUP_OF[c]] ? null : v.map((x, i) => (i === 0 ? x : i === 1 ? x - v[0] : x - 2 * v[i - 1] + v[i - 2])),
  );
  const unsignedAt = (c, i) => !signedHeads && (i === 0 || (i === 1 && c === T));
  // The code of residual `i` of channel `c` under `shift`, for the chosen order.
  const codeOf = (c, i, shift) => {
    const v = residuals[c][i] / 2 ** shift;
    return unsignedAt(c, i) ? v : zigzag(v);
  };
  // The bits of a group's codes under `shift` (the header included).
  const cost = (g, shift) => {
    let bits = shift === DEFAULT_SHIFT[g] ? 1 : 4;
    for (const c of GROUPS[g]) {
      const a = new Adaptive(c);
      for (let i = 0; i < n; i++) {
        const u = codeOf(c, i, shift);
        if (i === 0) bits += codeLength(u, K_HEAD[c]);
        else if (i === 1) bits += codeLength(u, K_DELTA[c]);
        else {
          bits += codeLength(u, a.order());
          a.add(u);
        }
      }
    }
    return bits;
  };
  const shifts = GROUPS.map((chs, g) => {
    if (raw[g]) return RAW;
    let largest = MAX_SHIFT;
    while (largest > 0 && !chs.every((c) => residuals[c].every((v) => v % 2 ** largest === 0))) largest--;
    const fallback = DEFAULT_SHIFT[g];
    return fallback <= largest && cost(g, fallback) <= cost(g, largest) ? fallback : largest;
  });
  if (signedHeads) {
    w.one(0);
    w.one(1);
  } else {
    w.one(1);
  }
  w.golomb(n - 1, 0);
  shifts.forEach((s, g) => {
    if (s === DEFAULT_SHIFT[g]) w.one(1);
    else {
      w.one(0);
      w.bits(s, 3);
    }
  });
  const adaptive = [0, 1, 2, 3].map((c) => new Adaptive(c));
  for (let i = 0; i < n; i++) {
    for (let c = 0; c < 4; c++) {
      const s = shifts[GROUP_OF[c]];
      if (s === RAW) {
        w.f64(points[i][c]);
        continue;
      }
      const u = codeOf(c, i, s);
      if (!Number.isSafeInteger(u)) throw new FrameError(`${path}[${i}]: channel ${"xytp"[c]}'s residual is past 2^53 steps`);
      if (i === 0) w.golomb(u, K_HEAD[c]);
      else if (i === 1) w.golomb(u, K_DELTA[c]);
      else {
        w.golomb(u, adaptive[c].order());
        adaptive[c].add(u);
      }
    }
  }
  return w.bytes();
}
