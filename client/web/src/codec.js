// The protocol's binary encoding (docs/protocol.md, "Binary"), written from that page alone: one
// version byte, then the message in bincode 2 (standard configuration: little endian, varint
// integers), the samples in the compact point batch. Every message of versions 4, 5 and 6, both
// directions, is described once, as data (`messages` below: a schema per message); one reader
// and one writer walk it. A message decodes to exactly the object `JSON.parse` gives for the
// same message in JSON (an `Option` that is none is `null`; ids are lowercase UUID strings;
// unit enums are their names; a sample is `[x, y, t, p]`), and encodes from it.
//
// A frame that does not decode (empty, a version byte other than the connection's, an unknown
// variant, a truncated value, a bad tag, invalid UTF-8, bytes left over) throws a `FrameError`
// naming the field and what is wrong: never a partial message. Integers are JavaScript numbers;
// a `u64` past 2^53 reads as the same rounded number `JSON.parse` gives for it. What the codec
// does not check is the proxy's business (a placement's similarity, a sample's range): it
// checks the layout, and that a placement is finite with the last row 0 0 0 1, which JSON
// cannot say otherwise either.

import { FrameError, describe } from "./frame-error.js";
import { encodeBatch, readBatch } from "./pointbatch.js";

export { FrameError };
export { MAX_BATCH_SAMPLES, STEPS, encodeBatch, readBatch } from "./pointbatch.js";

/// The version this page speaks, and the versions this codec can read and write.
export const PROTOCOL_VERSION = 6;
export const VERSIONS = [4, 5, 6];

// ---------------------------------------------------------------------------------------------
// The types on the wire ("Every message, field by field").

const U16 = { kind: "uint", max: 0xffff, widest: 251 };
const U32 = { kind: "uint", max: 0xffffffff, widest: 252 };
const U64 = { kind: "uint", max: 2 ** 64 - 1, widest: 253 };
const F64 = { kind: "f64" };
const BOOL = { kind: "bool" };
const STRING = { kind: "string" };
const UUID = { kind: "uuid" };
const BATCH = { kind: "batch" };
const PLACEMENT = { kind: "placement" };
const opt = (of) => ({ kind: "opt", of });
const list = (of) => ({ kind: "list", of });
/// A struct: its fields in wire order, each `[name, type]` or `[name, type, absent]` where
/// `absent()` is the value JSON may leave out (an `Option` may always be left out: none).
const struct = (fields) => ({ kind: "struct", fields });
/// An enum whose variants have no fields: JSON writes the name as a string.
const names = (list) => ({ kind: "names", names: list });
/// An enum whose variants hold one value each: JSON `{"name": value}`.
const variants = (list) => ({ kind: "variants", variants: list });

const BRUSH = struct([
  ["size", F64],
  ["pressure_response", F64],
  ["min_radius", F64],
  ["color", opt(U32)],
]);
const defaultBrush = () => ({ size: 8.0, pressure_response: 0.5, min_radius: 0.25, color: null });
const PRESSURE_GATE = variants([
  ["variance", F64],
  ["interpolation", F64],
]);
const ACUTS_PARAMS = struct([
  ["tolerance", F64],
  ["angle_deg", F64],
  ["angle_near_anchor", BOOL],
  ["pressure", PRESSURE_GATE],
]);
const STROKE_STATUS = names(["open", "done", "interrupted", "unknown"]);
const RESUME_STATE = struct([
  ["stroke", UUID],
  ["next_seq", U64],
  ["status", STROKE_STATUS],
]);
/// `ErrorCode`, in the order of docs/protocol.md's "Errors" index table.
export const ERROR_CODES = [
  "malformed", "bad_json", "unknown_message", "protocol", "bad_sample", "bad_brush", "bad_params",
  "unknown_stroke", "not_owner", "stroke_finished", "stroke_conflict", "seq_gap", "count_mismatch",
  "frame_too_large", "batch_too_large", "stroke_too_long", "too_many_open_strokes",
  "too_many_connections", "idle_timeout", "lagged", "shutting_down", "internal", "stroke_open",
  "bad_solid",
];
const ERROR_CODE = names(ERROR_CODES);
/// What a stroke becomes (version 6): its kind and its depth in px (none only for a line).
const SOLID = struct([
  ["kind", names(["line", "filled", "hole"])],
  ["depth", opt(F64)],
]);
export const ROD = Object.freeze({ kind: "line", depth: null });
const IDENTITY = () => ({ matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1] });
/// A history's stroke; version 6 adds its placement and its solid.
const historyStroke = (v6) => struct([
  ["participant", UUID],
  ["stroke", UUID],
  ["brush", BRUSH],
  ["points", BATCH],
  ["done", BOOL],
  ["mesh", BOOL],
  ...(v6 ? [["placement", PLACEMENT, IDENTITY], ["solid", SOLID, () => ({ ...ROD })]] : []),
]);

const stroke = ["stroke", UUID];
const participant = ["participant", UUID];

/// The messages of `version`, by direction, in variant index order.
function messagesOf(version) {
  const v5 = version >= 5;
  const v6 = version >= 6;
  const client = [
    ["hello", [["protocol", U16], ["client", STRING], ["name", opt(STRING)], ["resume", list(UUID), () => []], ["key", opt(STRING)]]],
    ["stroke_begin", [stroke, ["brush", BRUSH, defaultBrush], ["device", opt(STRING)], ["params", opt(ACUTS_PARAMS)], ...(v5 ? [["placement", opt(PLACEMENT)]] : []), ...(v6 ? [["solid", opt(SOLID)]] : [])]],
    ["points", [stroke, ["seq", U64], ["points", BATCH]]],
    ["stroke_end", [stroke, ["n_points", U64]]],
    ["ping", [["nonce", U64]]],
    ["remove_stroke", [stroke]],
    ["restore_stroke", [stroke]],
    ["rename", [["name", STRING]]],
    ...(v5 ? [["set_placement", [stroke, ["placement", PLACEMENT]]]] : []),
    ...(v6 ? [["set_solid", [stroke, ["solid", SOLID]]]] : []),
  ];
  const server = [
    ["welcome", [["protocol", U16], ["session", UUID], participant, ["resume", list(RESUME_STATE)]]],
    ["ack", [stroke, ["upto_seq", U64]]],
    ["retained", [stroke, ["first", U64], ["points", BATCH]]],
    ["stroke_done", [stroke, ["n_retained", U64], ["url", STRING]]],
    ["pong", [["nonce", U64]]],
    ["error", [["code", ERROR_CODE], ["message", STRING], ["stroke", opt(UUID)]]],
    ["peer_joined", [participant, ["name", STRING]]],
    ["peer_left", [participant]],
    ["peer_stroke_begin", [participant, stroke, ["brush", BRUSH]]],
    ["peer_retained", [participant, stroke, ["first", U64], ["points", BATCH]]],
    ["peer_stroke_done", [participant, stroke, ["n_retained", U64], ["url", STRING]]],
    ["peer_mesh", [participant, stroke, ["url", STRING]]],
    ["synced", [["n_strokes", U64]]],
    ["stroke_removed", [participant, stroke, ["by", UUID]]],
    ["stroke_restored", [participant, stroke, ["by", UUID]]],
    ["peer_renamed", [participant, ["name", STRING]]],
    ["peer_strokes", [["strokes", list(historyStroke(v6))]]],
    ...(v5 ? [["peer_placement", [participant, stroke, ["placement", PLACEMENT]]]] : []),
    ...(v6 ? [["peer_solid", [participant, stroke, ["solid", SOLID]]]] : []),
  ];
  const table = (list) => {
    const byIndex = list.map(([name, fields]) => ({ name, type: struct(fields) }));
    return { byIndex, byName: new Map(byIndex.map((m, index) => [m.name, { ...m, index }])) };
  };
  return { client: table(client), server: table(server) };
}

const MESSAGES = new Map(VERSIONS.map((v) => [v, messagesOf(v)]));

/// The message names of `version` from `side` ("client" or "server"), in variant index order.
export function messageNames(side, version = PROTOCOL_VERSION) {
  return tables(side, version).byIndex.map((m) => m.name);
}

function tables(side, version) {
  const m = MESSAGES.get(version);
  if (!m) throw new FrameError(`protocol version ${version} is not one this codec speaks (${VERSIONS.join(", ")})`);
  if (side !== "client" && side !== "server") throw new Error(`side ${side}: "client" or "server"`);
  return m[side];
}

// ---------------------------------------------------------------------------------------------
// Frames.

/// The message of a binary frame the proxy sent (`bytes`: an ArrayBuffer or a Uint8Array) on a
/// connection of protocol `version`.
export function decodeServer(bytes, version = PROTOCOL_VERSION) {
  return decodeFrame("server", bytes, version);
}

/// The message of a binary frame a client sent.
export function decodeClient(bytes, version = PROTOCOL_VERSION) {
  return decodeFrame("client", bytes, version);
}

/// The binary frame (a Uint8Array) of a client's message, given as its JSON object.
export function encodeClient(message, version = PROTOCOL_VERSION) {
  return encodeFrame("client", message, version);
}

/// The binary frame of a proxy's message (for tests and other implementations).
export function encodeServer(message, version = PROTOCOL_VERSION) {
  return encodeFrame("server", message, version);
}

function decodeFrame(side, bytes, version) {
  const table = tables(side, version);
  const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const r = new Reader(data);
  if (data.length === 0) throw new FrameError("empty frame: no version byte");
  const got = r.byte("the version byte");
  if (got !== version) throw new FrameError(`version byte ${got}: this connection speaks protocol ${version}`);
  const index = r.varint(`${side} message variant`, U32);
  const entry = table.byIndex[index];
  if (!entry) {
    throw new FrameError(`unknown ${side} message variant ${index} (protocol ${version} has 0 to ${table.byIndex.length - 1})`);
  }
  const value = r.read(entry.type, entry.name);
  if (r.pos !== data.length) {
    throw new FrameError(`${data.length - r.pos} byte(s) left over after ${entry.name} (its ${r.pos} bytes of a ${data.length}-byte frame)`);
  }
  return { [entry.name]: value };
}

function encodeFrame(side, message, version) {
  const table = tables(side, version);
  if (message === null || typeof message !== "object" || Array.isArray(message)) {
    throw new FrameError(`a message is an object with one key, its name; got ${describe(message)}`);
  }
  const keys = Object.keys(message);
  if (keys.length !== 1) throw new FrameError(`a message has exactly one key, its name; got ${keys.length} (${keys.join(", ")})`);
  const entry = table.byName.get(keys[0]);
  if (!entry) throw new FrameError(`unknown ${side} message "${keys[0]}" in protocol ${version}`);
  const w = new Writer();
  w.byte(version);
  w.varint(entry.index);
  w.write(entry.type, message[keys[0]], entry.name);
  return w.bytes();
}


// ---------------------------------------------------------------------------------------------
// Reading.

const utf8 = new TextDecoder("utf-8", { fatal: true });
const HEX = Array.from({ length: 256 }, (_, i) => i.toString(16).padStart(2, "0"));

class Reader {
  constructor(data) {
    this.data = data;
    this.view = new DataView(data.buffer, data.byteOffset, data.byteLength);
    this.pos = 0;
  }

  need(n, what) {
    if (this.pos + n > this.data.length) {
      throw new FrameError(`${what}: truncated frame: ${n} byte(s) needed at byte ${this.pos}, ${this.data.length - this.pos} left`);
    }
  }

  byte(what) {
    this.need(1, what);
    return this.data[this.pos++];
  }

  /// A varint of `type` (U16, U32 or U64): one byte up to 250, else 251/252/253 and the value
  /// as u16/u32/u64 little endian; a wider form than the type's is refused.
  varint(what, type) {
    const first = this.byte(what);
    if (first <= 250) return first;
    if (first > type.widest) {
      const form = { 251: "u16", 252: "u32", 253: "u64" }[first];
      throw new FrameError(`${what}: ${form ? `a ${form} varint (byte ${first})` : `byte ${first}, not a varint`} where ${type === U16 ? "a u16" : type === U32 ? "a u32" : "a u64"} goes, at byte ${this.pos - 1}`);
    }
    if (first === 251) {
      this.need(2, what);
      const v = this.view.getUint16(this.pos, true);
      this.pos += 2;
      return v;
    }
    if (first === 252) {
      this.need(4, what);
      const v = this.view.getUint32(this.pos, true);
      this.pos += 4;
      return v;
    }
    this.need(8, what);
    const v = this.view.getBigUint64(this.pos, true);
    this.pos += 8;
    return Number(v); // exact up to 2^53; beyond, the nearest double, as JSON.parse reads it
  }

  f64(what) {
    this.need(8, what);
    const v = this.view.getFloat64(this.pos, true);
    this.pos += 8;
    return v;
  }

  read(type, path) {
    switch (type.kind) {
      case "uint":
        return this.varint(path, type);
      case "f64":
        return this.f64(path);
      case "bool": {
        const b = this.byte(path);
        if (b > 1) throw new FrameError(`${path}: bool byte ${b} at byte ${this.pos - 1} (0 or 1)`);
        return b === 1;
      }
      case "string": {
        const n = this.varint(`${path} (length)`, U64);
        this.need(n, path);
        const bytes = this.data.subarray(this.pos, this.pos + n);
        this.pos += n;
        try {
          return utf8.decode(bytes);
        } catch {
          throw new FrameError(`${path}: invalid UTF-8 in a string of ${n} bytes`);
        }
      }
      case "uuid": {
        const n = this.varint(`${path} (length)`, U64);
        if (n !== 16) throw new FrameError(`${path}: a UUID of length ${n} at byte ${this.pos - 1} (16)`);
        this.need(16, path);
        const h = [];
        for (let i = 0; i < 16; i++) h.push(HEX[this.data[this.pos + i]]);
        this.pos += 16;
        const s = h.join("");
        return `${s.slice(0, 8)}-${s.slice(8, 12)}-${s.slice(12, 16)}-${s.slice(16, 20)}-${s.slice(20)}`;
      }
      case "opt": {
        const tag = this.byte(path);
        if (tag === 0) return null;
        if (tag !== 1) throw new FrameError(`${path}: option tag ${tag} at byte ${this.pos - 1} (0 or 1)`);
        return this.read(type.of, path);
      }
      case "list": {
        const n = this.varint(`${path} (count)`, U64);
        // Each element takes a byte at least: a count past what is left is a truncated frame.
        this.need(Math.min(n, this.data.length + 1 - this.pos), `${path} (${n} elements)`);
        const out = [];
        for (let i = 0; i < n; i++) out.push(this.read(type.of, `${path}[${i}]`));
        return out;
      }
      case "struct": {
        const out = {};
        for (const [name, t] of type.fields) out[name] = this.read(t, `${path}.${name}`);
        return out;
      }
      case "names": {
        const i = this.varint(`${path} (variant)`, U32);
        if (i >= type.names.length) throw new FrameError(`${path}: unknown variant ${i} (0 to ${type.names.length - 1})`);
        return type.names[i];
      }
      case "variants": {
        const i = this.varint(`${path} (variant)`, U32);
        if (i >= type.variants.length) throw new FrameError(`${path}: unknown variant ${i} (0 to ${type.variants.length - 1})`);
        const [name, t] = type.variants[i];
        return { [name]: this.read(t, `${path}.${name}`) };
      }
      case "placement": {
        const matrix = [];
        for (let i = 0; i < 16; i++) matrix.push(this.f64(`${path}.matrix[${i}]`));
        checkPlacement(matrix, path);
        return { matrix };
      }
      case "batch": {
        const { points, end } = readBatch(this.data, this.pos, path);
        this.pos = end;
        return points;
      }
      default:
        throw new Error(`no reader for ${type.kind}`);
    }
  }
}

/// What both directions check of a placement: 16 finite numbers, the last row 0 0 0 1.
function checkPlacement(matrix, path) {
  matrix.forEach((v, i) => {
    if (!Number.isFinite(v)) throw new FrameError(`${path}.matrix[${i}]: ${v} is not finite`);
  });
  for (const [i, want] of [[3, 0], [7, 0], [11, 0], [15, 1]]) {
    if (matrix[i] !== want) throw new FrameError(`${path}.matrix[${i}]: ${matrix[i]}, the last row must be 0, 0, 0, 1`);
  }
}

// ---------------------------------------------------------------------------------------------
// Writing.

class Writer {
  constructor() {
    this.buf = new Uint8Array(256);
    this.view = new DataView(this.buf.buffer);
    this.len = 0;
  }

  room(n) {
    if (this.len + n <= this.buf.length) return;
    let size = this.buf.length * 2;
    while (size < this.len + n) size *= 2;
    const next = new Uint8Array(size);
    next.set(this.buf.subarray(0, this.len));
    this.buf = next;
    this.view = new DataView(next.buffer);
  }

  byte(b) {
    this.room(1);
    this.buf[this.len++] = b;
  }

  raw(bytes) {
    this.room(bytes.length);
    this.buf.set(bytes, this.len);
    this.len += bytes.length;
  }

  /// `v`: a non-negative integer (a number, or a BigInt past 2^53).
  varint(v) {
    if (v <= 250) return this.byte(Number(v));
    if (v <= 0xffff) {
      this.room(3);
      this.buf[this.len] = 251;
      this.view.setUint16(this.len + 1, Number(v), true);
      this.len += 3;
    } else if (v <= 0xffffffff) {
      this.room(5);
      this.buf[this.len] = 252;
      this.view.setUint32(this.len + 1, Number(v), true);
      this.len += 5;
    } else {
      this.room(9);
      this.buf[this.len] = 253;
      this.view.setBigUint64(this.len + 1, BigInt(v), true);
      this.len += 9;
    }
  }

  f64(v) {
    this.room(8);
    this.view.setFloat64(this.len, v, true);
    this.len += 8;
  }

  bytes() {
    return this.buf.slice(0, this.len);
  }

  write(type, value, path) {
    switch (type.kind) {
      case "uint": {
        const ok = (typeof value === "number" && Number.isInteger(value) && value >= 0 && value <= type.max) ||
          (typeof value === "bigint" && value >= 0n && value <= BigInt(type.max));
        if (!ok) throw new FrameError(`${path}: ${describe(value)} is not an integer in [0, ${type.max}]`);
        return this.varint(value);
      }
      case "f64":
        if (typeof value !== "number") throw new FrameError(`${path}: ${describe(value)} is not a number`);
        return this.f64(value);
      case "bool":
        if (typeof value !== "boolean") throw new FrameError(`${path}: ${describe(value)} is not a bool`);
        return this.byte(value ? 1 : 0);
      case "string": {
        if (typeof value !== "string") throw new FrameError(`${path}: ${describe(value)} is not a string`);
        const bytes = new TextEncoder().encode(value);
        this.varint(bytes.length);
        return this.raw(bytes);
      }
      case "uuid": {
        const hex = typeof value === "string" ? value.replace(/-/g, "") : "";
        if (!/^[0-9a-fA-F]{32}$/.test(hex) || !/^[0-9a-fA-F]{8}(-?)[0-9a-fA-F]{4}\1[0-9a-fA-F]{4}\1[0-9a-fA-F]{4}\1[0-9a-fA-F]{12}$/.test(value)) {
          throw new FrameError(`${path}: ${describe(value)} is not a UUID`);
        }
        this.byte(16);
        for (let i = 0; i < 16; i++) this.byte(parseInt(hex.slice(2 * i, 2 * i + 2), 16));
        return;
      }
      case "opt":
        if (value === null || value === undefined) return this.byte(0);
        this.byte(1);
        return this.write(type.of, value, path);
      case "list":
        if (!Array.isArray(value)) throw new FrameError(`${path}: ${describe(value)} is not a list`);
        this.varint(value.length);
        value.forEach((v, i) => this.write(type.of, v, `${path}[${i}]`));
        return;
      case "struct":
        if (value === null || typeof value !== "object" || Array.isArray(value)) {
          throw new FrameError(`${path}: ${describe(value)} is not an object`);
        }
        for (const [name, t, absent] of type.fields) {
          let v = value[name];
          if (v === undefined && absent) v = absent();
          if (v === undefined && t.kind !== "opt") throw new FrameError(`${path}.${name}: missing`);
          this.write(t, v, `${path}.${name}`);
        }
        return;
      case "names": {
        const i = type.names.indexOf(value);
        if (i < 0) throw new FrameError(`${path}: ${describe(value)} is not one of ${type.names.join(", ")}`);
        return this.varint(i);
      }
      case "variants": {
        const keys = value && typeof value === "object" ? Object.keys(value) : [];
        const i = keys.length === 1 ? type.variants.findIndex(([name]) => name === keys[0]) : -1;
        if (i < 0) throw new FrameError(`${path}: ${describe(value)} is not one of {${type.variants.map(([n]) => n).join("}, {")}}`);
        this.varint(i);
        return this.write(type.variants[i][1], value[keys[0]], `${path}.${keys[0]}`);
      }
      case "placement": {
        const m = value && value.matrix;
        if (!Array.isArray(m) || m.length !== 16 || m.some((v) => typeof v !== "number")) {
          throw new FrameError(`${path}: not {"matrix": [16 numbers]}`);
        }
        checkPlacement(m, path);
        for (const v of m) this.f64(v);
        return;
      }
      case "batch":
        return this.raw(encodeBatch(value, path));
      default:
        throw new Error(`no writer for ${type.kind}`);
    }
  }
}
