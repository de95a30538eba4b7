// The page's binary codec (client/web/src/codec.js) against docs/protocol.md, in Node, no
// browser. It executes the doc's examples: every ```frames``` block (a JSON line, then its frame
// in hex) decodes to exactly what JSON.parse gives and encodes back to the same bytes, both
// directions; every ```json``` message goes through a binary round trip unchanged; the compact
// batch's worked example gives its bytes; the index tables name the codec's variants. Long
// batches the proxy wrote (test/raw-frames.json) decode to their JSON and encode back to the
// proxy's bytes: a fault the encoder and decoder share shows there. Then a
// round trip of generated messages of every variant (seeded), and frames that must not decode
// (each with the words of its error). Run by scripts/test.sh as `node client/web/test/codec.mjs`.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import {
  ERROR_CODES, FrameError, PROTOCOL_VERSION, decodeClient, decodeServer, encodeBatch, encodeClient, encodeServer,
  messageNames, readBatch,
} from "../src/codec.js";

// The checkout (no harness.mjs: this test needs no browser and no npm package).
const root = resolve(dirname(fileURLToPath(import.meta.url)), "../../..");

const DOC = readFileSync(join(root, "docs/protocol.md"), "utf8");
const hex = (bytes) => Buffer.from(bytes).toString("hex").replace(/(..)(?!$)/g, "$1 ");
const fromHex = (text) => Uint8Array.from(Buffer.from(text.replace(/\s+/g, ""), "hex"));
const decode = { client: decodeClient, server: decodeServer };
const encode = { client: encodeClient, server: encodeServer };
let checks = 0;
const check = (what, fn) => {
  try {
    fn();
    checks++;
  } catch (e) {
    e.message = `${what}: ${e.message}`;
    throw e;
  }
};

/// The fenced blocks of the doc whose info string starts with `kind`: [{side, lines}].
function blocks(kind) {
  const out = [];
  const re = /^```(\S+)(.*)\n([\s\S]*?)^```$/gm;
  for (const m of DOC.matchAll(re)) {
    if (m[1] !== kind) continue;
    const words = m[2].trim().split(/\s+/);
    out.push({ side: words[0], lines: m[3].split("\n").filter((l) => l.trim()) });
  }
  return out;
}

// 1. Every frame of the doc: JSON line, then its hex.
const frames = [];
for (const { side, lines } of blocks("frames")) {
  assert.ok(side === "client" || side === "server", `a frames block's side: ${side}`);
  for (const line of lines) {
    if (line.startsWith("{")) frames.push({ side, json: line, hex: "" });
    else {
      assert.ok(frames.length && /^[0-9a-f ]+$/.test(line), `a hex line after a JSON line: ${line}`);
      frames[frames.length - 1].hex += ` ${line}`;
    }
  }
}
assert.ok(frames.length >= 20, `the doc's frames (${frames.length}) cover both directions`);
const seen = { client: new Set(), server: new Set() };
for (const { side, json, hex: text } of frames) {
  const message = JSON.parse(json);
  const bytes = fromHex(text);
  const name = Object.keys(message)[0];
  seen[side].add(name);
  check(`the doc's ${side} frame of ${name}: decoded`, () => assert.deepStrictEqual(decode[side](bytes), message));
  check(`the doc's ${side} frame of ${name}: encoded`, () => assert.equal(hex(encode[side](message)), hex(bytes)));
  // Every prefix of a frame is a truncated frame, and one byte more is a byte left over.
  check(`the doc's ${side} frame of ${name}: truncated`, () => {
    for (let n = 0; n < bytes.length; n++) assert.throws(() => decode[side](bytes.subarray(0, n)), FrameError, `its first ${n} bytes`);
  });
  check(`the doc's ${side} frame of ${name}: a byte left over`, () =>
    assert.throws(() => decode[side](Uint8Array.from([...bytes, 0])), /1 byte\(s\) left over after/));
}
// Every server message has a frame in the doc (all 18 variants decode as the doc shows them).
assert.deepEqual([...seen.server].sort(), messageNames("server").sort(), "every server message has a frame in the doc");

// 2. Every JSON message of the doc: binary and back gives the same object (the client's with
// the defaults of what JSON may leave out: the brush, `resume`, options as null).
for (const { side, lines } of blocks("json")) {
  for (const line of lines) {
    const message = JSON.parse(line);
    const name = Object.keys(message)[0];
    check(`the doc's JSON ${side} message ${name}: a binary round trip`, () => {
      const back = decode[side](encode[side](message));
      assert.deepStrictEqual(back, side === "client" ? withDefaults(message) : message);
    });
  }
}

/// A client message with what JSON may leave out filled in as the binary form says it.
function withDefaults(message) {
  const [[name, m]] = Object.entries(message);
  const full = structuredClone(m);
  if (name === "hello") Object.assign(full, { name: m.name ?? null, resume: m.resume ?? [], key: m.key ?? null });
  if (name === "stroke_begin") {
    full.brush = { size: 8.0, pressure_response: 0.5, min_radius: 0.25, ...m.brush, color: m.brush?.color ?? null };
    for (const k of ["device", "params", "placement", "solid"]) full[k] = m[k] ?? null;
  }
  return { [name]: full };
}

// 3. The compact batch's worked example ("The compact point batch"): its samples, its bytes.
{
  const example = DOC.match(/The batch of the JSON conversation's first `points` message, `(\[\[[^`]*\]\])`/);
  const bytesOf = DOC.match(/That is `([0-9a-f ]+)`\./);
  assert.ok(example && bytesOf, "the compact batch's worked example is in the doc");
  const points = JSON.parse(example[1].replace(/\s+/g, ""));
  check("the batch's worked example: encoded", () => assert.equal(hex(encodeBatch(points)), bytesOf[1]));
  check("the batch's worked example: decoded", () => assert.deepStrictEqual(readBatch(fromHex(bytesOf[1]), 0), { points, end: fromHex(bytesOf[1]).length }));
}

// The first binary `points` frame, "byte by byte": its batch is the frame's tail.
{
  const said = DOC.match(/The first `points` frame above, byte by byte:[\s\S]*?then the point batch\s+`([0-9a-f ]+)`/);
  assert.ok(said, "the doc takes the first points frame byte by byte");
  const first = frames.find((f) => f.side === "client" && f.json.startsWith('{"points"'));
  check("the first points frame, byte by byte", () => assert.ok(hex(fromHex(first.hex)).endsWith(` 00 ${said[1]}`), `its batch ${said[1]} after seq 00`));
}

// Frames the proxy's Rust codec wrote (test/raw-frames.json, recorded by record-raw.mjs):
// three long strokes' `/raw` as one `retained` frame each, 948 to 1,660 samples, far past the
// doc's examples (the running order's sum is halved every 32 second differences). Each decodes
// to its JSON samples, and its JSON encodes to the proxy's very bytes (the same shifts chosen).
{
  const { frames: recorded } = JSON.parse(readFileSync(join(root, "client/web/test/raw-frames.json"), "utf8"));
  assert.ok(recorded.length >= 3 && recorded.every((f) => f.message.retained.points.length > 900), "three long recorded frames");
  for (const { message, hex: text } of recorded) {
    const bytes = fromHex(text);
    const n = message.retained.points.length;
    // Recorded in version 5, whose `retained` version 6 lays out the same: read and written as
    // the version its byte names.
    const version = bytes[0];
    check(`the proxy's frame of ${n} samples: decoded`, () => assert.deepStrictEqual(decodeServer(bytes, version), message));
    check(`the proxy's frame of ${n} samples: encoded`, () => assert.ok(Buffer.from(encodeServer(message, version)).equals(Buffer.from(bytes)), "not the proxy's bytes"));
  }
}

// 4. The doc's index tables are the codec's variants, in order.
for (const [marker, names] of [
  ["client message indices", messageNames("client")],
  ["server message indices", messageNames("server")],
  ["error code indices", ERROR_CODES],
]) {
  const table = DOC.split(`<!-- ${marker} -->`)[1].split("\n\n")[0];
  const rows = [...table.matchAll(/^\| (\d+) \| `(\w+)` \|$/gm)].map((r) => [Number(r[1]), r[2]]);
  check(`the doc's ${marker}`, () => assert.deepEqual(rows, names.map((n, i) => [i, n])));
}

// 5. Generated messages of every variant, both directions, through both ways (seeded: the same
// cases on every run).
let seed = 20261127;
const random = () => {
  seed = (seed * 1103515245 + 12345) % 2 ** 31;
  return seed / 2 ** 31;
};
const int = (n) => Math.floor(random() * n);
const pick = (list) => list[int(list.length)];
const uuid = () => Array.from({ length: 16 }, () => int(256).toString(16).padStart(2, "0")).join("").replace(/^(.{8})(.{4})(.{4})(.{4})/, "$1-$2-$3-$4-");
// Integers at the varint's edges, and a few anywhere.
const EDGES = [0, 1, 250, 251, 255, 0xffff, 0x10000, 0xffffffff, 2 ** 32, 2 ** 53 - 1];
const u64 = () => (random() < 0.5 ? pick(EDGES) : int(2 ** 40));
const u16 = () => pick([0, 4, 5, 250, 251, 0xffff]);
const text = () => pick(["", "a", "Ada L.", "名前 ✍️", "x".repeat(300), "\u0000nul", "/v1/strokes/x/simplified"]);
const brush = () => ({ size: random() * 64, pressure_response: random(), min_radius: 0.25, color: random() < 0.5 ? null : int(0x1000000) });
const params = () => ({ tolerance: random() * 4, angle_deg: random() * 90, angle_near_anchor: random() < 0.5, pressure: random() < 0.5 ? { interpolation: random() } : { variance: random() / 100 } });
const placement = () => {
  const [c, s] = [Math.cos(random() * 6), Math.sin(random() * 6)];
  const k = pick([1, 0.5, 3]) * pick([1, -1]);
  return { matrix: [k * c, k * s, 0, 0, -k * s, k * c, 0, 0, 0, 0, k, 0, random() * 1e4 - 5e3, random() * 100, 40, 1] };
};
/// A solid: the rod, or a kind with a depth.
const solid = () => (random() < 0.25 ? { kind: "line", depth: null } : { kind: pick(["line", "filled", "hole"]), depth: random() * 100 + 0.125 });
/// Samples as the proxy sends them (on the grid): a walk, with now and then a jump, a negative
/// coordinate or a long pause; sometimes a value beyond the grid's range (the raw group).
function points() {
  const n = pick([0, 1, 2, 3, 5, 40, 300]);
  const out = [];
  let [x, y, t, p] = [int(4000) - 500, int(3000) - 500, random() < 0.2 ? int(1e6) : 0, int(1025) / 1024];
  for (let i = 0; i < n; i++) {
    out.push([x, y, t, p]);
    x += (int(400) - 200) / 16;
    y += (int(400) - 200) / 16;
    t += random() < 0.05 ? int(2 ** 20) / 8 : int(200) / 8;
    p = Math.min(1, Math.max(0, p + (int(64) - 32) / 1024));
    if (random() < 0.02) x = -x * 3;
  }
  if (n && random() < 0.1) out[int(n)][pick([0, 1, 2, 3])] = pick([2 ** 50, -(2 ** 49) - 0.5, 1e300, 123.456789]);
  return out.map((s) => s.map((v) => v + 0));
}
const GENERATED = {
  hello: () => ({ protocol: u16(), client: text(), name: pick([null, text()]), resume: Array.from({ length: int(3) }, uuid), key: pick([null, "3f2a9c0d5e7b41a68c1f0e9d2b7a4c55"]) }),
  stroke_begin: () => ({ stroke: uuid(), brush: brush(), device: pick([null, "web:pen"]), params: pick([null, params()]), placement: pick([null, placement()]), solid: pick([null, solid()]) }),
  points: () => ({ stroke: uuid(), seq: u64(), points: points() }),
  stroke_end: () => ({ stroke: uuid(), n_points: u64() }),
  ping: () => ({ nonce: u64() }),
  remove_stroke: () => ({ stroke: uuid() }),
  restore_stroke: () => ({ stroke: uuid() }),
  rename: () => ({ name: text() }),
  set_placement: () => ({ stroke: uuid(), placement: placement() }),
  set_solid: () => ({ stroke: uuid(), solid: solid() }),
  welcome: () => ({ protocol: u16(), session: uuid(), participant: uuid(), resume: Array.from({ length: int(4) }, () => ({ stroke: uuid(), next_seq: u64(), status: pick(["open", "done", "interrupted", "unknown"]) })) }),
  ack: () => ({ stroke: uuid(), upto_seq: u64() }),
  retained: () => ({ stroke: uuid(), first: u64(), points: points() }),
  stroke_done: () => ({ stroke: uuid(), n_retained: u64(), url: text() }),
  pong: () => ({ nonce: u64() }),
  error: () => ({ code: pick(ERROR_CODES), message: text(), stroke: pick([null, uuid()]) }),
  peer_joined: () => ({ participant: uuid(), name: text() }),
  peer_left: () => ({ participant: uuid() }),
  peer_stroke_begin: () => ({ participant: uuid(), stroke: uuid(), brush: brush() }),
  peer_retained: () => ({ participant: uuid(), stroke: uuid(), first: u64(), points: points() }),
  peer_stroke_done: () => ({ participant: uuid(), stroke: uuid(), n_retained: u64(), url: text() }),
  peer_mesh: () => ({ participant: uuid(), stroke: uuid(), url: text() }),
  synced: () => ({ n_strokes: u64() }),
  stroke_removed: () => ({ participant: uuid(), stroke: uuid(), by: uuid() }),
  stroke_restored: () => ({ participant: uuid(), stroke: uuid(), by: uuid() }),
  peer_renamed: () => ({ participant: uuid(), name: text() }),
  peer_strokes: () => ({ strokes: Array.from({ length: int(4) }, () => ({ participant: uuid(), stroke: uuid(), brush: brush(), points: points(), done: random() < 0.5, mesh: random() < 0.5, placement: placement(), solid: solid() })) }),
  peer_placement: () => ({ participant: uuid(), stroke: uuid(), placement: placement() }),
  peer_solid: () => ({ participant: uuid(), stroke: uuid(), solid: solid() }),
};
/// What the binary form keeps of generated samples: each on the grid (rounded half away from
/// zero), except a group with a value past 2^48 steps, which travels raw (as it is).
const STEPS = [1 / 16, 1 / 16, 1 / 8, 1 / 1024];
function onGrid(samples) {
  const far = (c) => samples.some((s) => Math.abs(s[c] / STEPS[c]) > 2 ** 48);
  const raw = [far(0) || far(1), far(0) || far(1), far(2), far(3)];
  return samples.map((s) => s.map((v, c) => (raw[c] ? v : Math.sign(v) * Math.round(Math.abs(v / STEPS[c])) * STEPS[c] + 0)));
}
function kept(message) {
  const copy = structuredClone(message);
  const m = Object.values(copy)[0];
  if (m.points) m.points = onGrid(m.points);
  for (const s of m.strokes || []) s.points = onGrid(s.points);
  return copy;
}
for (const side of ["client", "server"]) {
  for (const name of messageNames(side)) {
    for (let i = 0; i < 60; i++) {
      const message = { [name]: GENERATED[name]() };
      check(`generated ${side} ${name} #${i}`, () => {
        const bytes = encode[side](message);
        const back = decode[side](bytes);
        assert.deepStrictEqual(back, kept(message));
        assert.equal(hex(encode[side](back)), hex(bytes), "encoding the decoded message gives the same bytes");
      });
    }
  }
}

// Batches at the grid's edges: heads of ±2^48 steps (codes of 85 bits), second differences of
// 2^50 steps (the order's running sum past 2^53), a value one step past 2^48 (travels raw),
// -0 (becomes 0), a NaN (raw, as it is).
const EDGE = 2 ** 48;
const swing = (steps) => Array.from({ length: 200 }, (_, i) => [((i % 2 ? 1 : -1) * steps) / 16, ((i % 2 ? -1 : 1) * steps) / 16, i / 8, (i % 1025) / 1024]);
for (const [what, samples, want] of [
  ["a swing of ±2^48 steps", swing(EDGE)],
  ["a swing of ±(2^48 − 1) steps", swing(EDGE - 1)],
  ["a head of −2^48 steps", [[-EDGE / 16, EDGE / 16, EDGE / 8, 1]]],
  ["a value one step past 2^48", [[(EDGE + 1) / 16, 0, 0, 0], [0, 0, 1, 0]]],
  ["−0", [[-0, -0, 0, -0]], [[0, 0, 0, 0]]],
  ["a NaN and an infinity", [[NaN, 1, 0, 0], [2, Infinity, 1, 0]]],
  ["time going back (heads signed)", [[1, 1, 5, 0.5], [1, 1, 4, 0.5]]],
]) {
  check(`a batch at the edge: ${what}`, () => {
    const bytes = encodeBatch(samples);
    assert.deepStrictEqual(readBatch(bytes, 0), { points: want || samples, end: bytes.length });
  });
}

// 6. Frames that must not decode, each with an error that names what is wrong.
const placementFrame = encodeClient({ set_placement: { stroke: uuid(), placement: placement() } });
const peerPlacement = encodeServer({ peer_placement: { participant: uuid(), stroke: uuid(), placement: placement() } });
const retained = encodeServer({ retained: { stroke: uuid(), first: 0, points: [[1, 2, 0, 0.5], [2, 3, 8, 0.5]] } });
const emptyRetained = encodeServer({ retained: { stroke: uuid(), first: 0, points: [] } });
const errorFrame = encodeServer({ error: { code: "seq_gap", message: "é", stroke: null } });
const peerSolid = encodeServer({ peer_solid: { participant: uuid(), stroke: uuid(), solid: { kind: "hole", depth: 3 } } });
const at = (bytes, i, b) => {
  const copy = Uint8Array.from(bytes);
  copy[i] = b;
  return copy;
};
const BAD = [
  ["an empty frame", new Uint8Array(0), /empty frame/],
  ["a version byte 4 on a version-6 connection", at(peerPlacement, 0, 4), /version byte 4: this connection speaks protocol 6/],
  ["a version byte 7", at(peerPlacement, 0, 7), /version byte 7/],
  ["an unknown server variant", at(peerPlacement, 1, 19), /unknown server message variant 19 \(protocol 6 has 0 to 18\)/],
  ["an unknown variant past 250", Uint8Array.from([6, 251, 0x10, 0x01]), /unknown server message variant 272/],
  ["a varint tag that is none", Uint8Array.from([6, 12, 254]), /synced.n_strokes: byte 254, not a varint/],
  ["a u32 varint where a u16 goes", Uint8Array.from([6, 0, 252, 5, 0, 0, 0]), /welcome.protocol: a u32 varint \(byte 252\) where a u16 goes/],
  ["a truncated peer_placement", peerPlacement.subarray(0, 100), /peer_placement.placement.matrix\[8\]: truncated frame/],
  ["a byte left over", Uint8Array.from([...peerPlacement, 7]), /1 byte\(s\) left over after peer_placement/],
  ["a UUID of 15 bytes", at(peerPlacement, 2, 15), /peer_placement.participant: a UUID of length 15/],
  ["an option tag 2", at(errorFrame, errorFrame.length - 1, 2), /error.stroke: option tag 2/],
  ["an unknown error code", at(errorFrame, 2, 24), /error.code: unknown variant 24 \(0 to 23\)/],
  ["an unknown solid kind", at(peerSolid, peerSolid.length - 10, 3), /peer_solid.solid.kind: unknown variant 3 \(0 to 2\)/],
  ["invalid UTF-8", at(errorFrame, 4, 0xff), /error.message: invalid UTF-8/],
  ["a bool byte 2", (() => {
    // Version 6: the placement's 128 bytes and the rod's 2 follow `mesh`.
    const rod = { kind: "line", depth: null };
    const f = encodeServer({ peer_strokes: { strokes: [{ participant: uuid(), stroke: uuid(), brush: brush(), points: [], done: true, mesh: false, placement: placement(), solid: rod }] } });
    return at(f, f.length - 1 - 130, 2);
  })(), /peer_strokes.strokes\[0\].mesh: bool byte 2/],
  ["a list count past the frame", Uint8Array.from([6, 16, 252, 0, 0, 0, 1]), /peer_strokes.strokes \(16777216 elements\): truncated frame/],
  ["a batch cut short", retained.subarray(0, retained.length - 1), /retained.points: sample 1.s first difference of t: truncated frame/],
  // An empty batch is '00' and six bits of padding: byte 00; 01 has a padding bit set.
  ["a batch whose padding is not zero", at(emptyRetained, emptyRetained.length - 1, 1), /retained.points: the point batch's padding bits are not zero/],
  ["a batch of more samples than the frame holds", Uint8Array.from([...retained.subarray(0, 20), 0b10000000, 0b00000000, 0b00000100, 0]), /samples cannot fit|truncated/],
  ["a placement whose last row is not 0 0 0 1", (() => {
    const f = Uint8Array.from(peerPlacement);
    new DataView(f.buffer).setFloat64(f.length - 8, 2, true);
    return f;
  })(), /peer_placement.placement.matrix\[15\]: 2, the last row must be 0, 0, 0, 1/],
  ["a placement with a NaN", (() => {
    const f = Uint8Array.from(peerPlacement);
    new DataView(f.buffer).setFloat64(36, NaN, true);
    return f;
  })(), /peer_placement.placement.matrix\[0\]: NaN is not finite/],
];
for (const [what, bytes, words] of BAD) {
  check(`a frame that must not decode: ${what}`, () => assert.throws(() => decodeServer(bytes), (e) => e instanceof FrameError && words.test(e.message), `${what} (${hex(bytes).slice(0, 60)}…)`));
}
check("a version-4 connection: a set_placement does not exist", () => assert.throws(() => decodeClient(at(placementFrame, 0, 4), 4), /unknown client message variant 8 \(protocol 4 has 0 to 7\)/));
check("the version byte is the connection's", () => assert.throws(() => decodeClient(placementFrame, 4), /version byte 6: this connection speaks protocol 4/));
check("a version-5 connection: a set_solid does not exist", () => assert.throws(() => decodeClient(at(encodeClient({ set_solid: { stroke: uuid(), solid: { kind: "filled", depth: 2 } } }), 0, 5), 5), /unknown client message variant 9 \(protocol 5 has 0 to 8\)/));
check("a version-5 peer_strokes has no placement nor solid", () => {
  const s = { participant: uuid(), stroke: uuid(), brush: brush(), points: [], done: true, mesh: false };
  const v5 = encodeServer({ peer_strokes: { strokes: [s] } }, 5);
  assert.deepStrictEqual(decodeServer(v5, 5), { peer_strokes: { strokes: [s] } });
  const v6 = encodeServer({ peer_strokes: { strokes: [{ ...s, placement: placement(), solid: { kind: "filled", depth: 3 } }] } });
  assert.equal(v6.length, v5.length + 128 + 1 + 1 + 8, "a placement and a solid more");
});
// Messages that must not encode.
for (const [what, message, words] of [
  ["two keys", { ping: { nonce: 1 }, pong: { nonce: 1 } }, /exactly one key/],
  ["a server message from a client", { peer_placement: {} }, /unknown client message "peer_placement"/],
  ["a missing field", { set_placement: { stroke: uuid() } }, /set_placement.placement: missing/],
  ["a matrix of 15", { set_placement: { stroke: uuid(), placement: { matrix: Array(15).fill(0) } } }, /not \{"matrix": \[16 numbers\]\}/],
  ["a bad UUID", { remove_stroke: { stroke: "not-a-uuid" } }, /remove_stroke.stroke: the string "not-a-uuid" is not a UUID/],
  ["a negative seq", { points: { stroke: uuid(), seq: -1, points: [] } }, /points.seq: number -1 is not an integer/],
  ["a u16 past its range", { hello: { protocol: 70000, client: "c" } }, /hello.protocol: number 70000 is not an integer in \[0, 65535\]/],
  ["a sample of three", { points: { stroke: uuid(), seq: 0, points: [[1, 2, 3]] } }, /points.points\[0\]: a sample is \[x, y, t, p\]/],
]) {
  check(`a message that must not encode: ${what}`, () => assert.throws(() => encodeClient(message), (e) => e instanceof FrameError && words.test(e.message), what));
}

// 7. What a move costs the page: set_placement and peer_placement of a turned, moved matrix.
const move = { stroke: "67e55044-10b1-426f-9247-bb680e5fe0c8", placement: { matrix: [0.8660254037844387, 0.5, 0, 0, -0.5, 0.8660254037844387, 0, 0, 0, 0, 1, 0, 123.4375, -56.25, 40, 1] } };
const sent = encodeClient({ set_placement: move }).length;
const received = encodeServer({ peer_placement: { participant: "8a1b2c3d-4e5f-4a6b-8c7d-9e0f1a2b3c4d", ...move } }).length;
assert.equal(sent, 147, "set_placement: 147 bytes");
assert.equal(received, 164, "peer_placement: 164 bytes");
assert.equal(PROTOCOL_VERSION, 6);

console.log(`PASS codec: ${checks} checks (${frames.length} frames of docs/protocol.md, both ways; every JSON example; 3 long frames the proxy wrote, both ways; generated messages of all ${messageNames("client").length} client and ${messageNames("server").length} server variants; ${BAD.length} malformed frames); a move: ${sent} B sent, ${received} B received`);
