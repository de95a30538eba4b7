// The page's connection (client/web/src/protocol.js) with both kinds of frame, in Node with a
// stand-in WebSocket (no browser, no proxy): what the page sends is binary (a hello, a move) or,
// switched to JSON, text; frames from the proxy, binary and text in any order, reach `on` in
// that order as the same objects; a binary frame that does not decode is said as an error and
// dropped, never thrown nor half applied; a message the codec refuses is said and not sent.
// Run by scripts/test.sh as `node client/web/test/connection.mjs`.
import assert from "node:assert/strict";
import { decodeClient, encodeServer } from "../src/codec.js";

// What protocol.js reads of the browser.
const store = new Map();
globalThis.sessionStorage = {
  getItem: (k) => (store.has(k) ? store.get(k) : null),
  setItem: (k, v) => store.set(k, String(v)),
  removeItem: (k) => store.delete(k),
};
globalThis.location = { protocol: "http:", host: "127.0.0.1:1" };
class FakeSocket {
  static OPEN = 1;
  static last = null;
  constructor(url, protocols) {
    Object.assign(this, { url, protocols, sent: [], readyState: FakeSocket.OPEN, binaryType: "blob" });
    FakeSocket.last = this;
  }
  send(frame) {
    this.sent.push(frame);
  }
}
globalThis.WebSocket = FakeSocket;
const { Connection } = await import("../src/protocol.js");

const session = "5f0c2a8e-7d41-4b6a-9e3f-1c2d3e4f5a6b";
const me = "8a1b2c3d-4e5f-4a6b-8c7d-9e0f1a2b3c4d";
const stroke = "0b9e2f7a-5c1d-4e8b-9a3f-2d6c8e1b7f40";
const heard = [];
const conn = new Connection({
  session,
  token: "t",
  protocol: 6,
  grid: [1 / 16, 1 / 8, 1 / 1024],
  params: [1.74, 45, 0.2],
  name: "Ada",
  on: (kind, m) => heard.push([kind, m]),
});
conn.connect();
const ws = FakeSocket.last;
assert.equal(ws.binaryType, "arraybuffer", "binary frames arrive as ArrayBuffers");
ws.onopen();
const [hello] = ws.sent;
assert.ok(hello instanceof Uint8Array, "the hello is a binary frame");
assert.equal(decodeClient(hello).hello.protocol, 6);
assert.equal(decodeClient(hello).hello.name, "Ada");

// Frames from the proxy, binary and text mixed: each reaches `on` in order, the same object.
const binary = (m) => {
  const bytes = encodeServer(m);
  return { data: bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength) };
};
const text = (m) => ({ data: JSON.stringify(m) });
const placement = { matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 250, 0, 0, 1] };
const messages = [
  { welcome: { protocol: 6, session, participant: me, resume: [] } },
  { peer_joined: { participant: stroke, name: "Bo" } },
  { peer_stroke_begin: { participant: stroke, stroke, brush: { size: 8, pressure_response: 0.5, min_radius: 0.25, color: null } } },
  { peer_retained: { participant: stroke, stroke, first: 0, points: [[100, 200, 0, 0.5], [101.5, 200.25, 8, 0.5625]] } },
  { peer_placement: { participant: stroke, stroke, placement } },
  { synced: { n_strokes: 1 } },
];
messages.forEach((m, i) => ws.onmessage(i % 2 ? text(m) : binary(m)));
assert.deepEqual(heard.map(([kind]) => kind), messages.map((m) => Object.keys(m)[0]), "every frame heard, in order");
heard.forEach(([kind, m], i) => assert.deepStrictEqual(m, messages[i][kind], `${kind} as sent`));
assert.equal(conn.me, me);
assert.ok(conn.synced);
const bytes = messages.reduce((n, m, i) => n + (i % 2 ? JSON.stringify(m).length : encodeServer(m).length), 0);
assert.equal(conn.wsBytes, bytes, "wsBytes counts both kinds of payload");

// A binary frame that does not decode: an error said, nothing thrown, nothing else heard.
heard.length = 0;
const bad = encodeServer({ peer_placement: { participant: stroke, stroke, placement } });
bad[0] = 4;
assert.doesNotThrow(() => ws.onmessage({ data: bad.buffer }));
assert.equal(heard.length, 1);
assert.equal(heard[0][0], "error");
assert.equal(heard[0][1].code, "malformed");
assert.match(heard[0][1].message, /does not decode: version byte 4: this connection speaks protocol 6/);

// A move goes binary, then in JSON when the page is switched to it.
heard.length = 0;
assert.ok(conn.setPlacement(stroke, placement.matrix));
assert.deepEqual(decodeClient(ws.sent.at(-1)), { set_placement: { stroke, placement } });
assert.equal(ws.sent.at(-1).length, 147, "a move: 147 bytes");
conn.encoding = "json";
assert.ok(conn.setPlacement(stroke, placement.matrix));
assert.deepEqual(JSON.parse(ws.sent.at(-1)), { set_placement: { stroke, placement } });
conn.encoding = "binary";

// A move the codec refuses (a NaN: JSON would have sent null): said, not sent.
const before = ws.sent.length;
const broken = [...placement.matrix];
broken[5] = NaN;
assert.equal(conn.setPlacement(stroke, broken), false);
assert.equal(ws.sent.length, before, "nothing sent");
assert.equal(heard.at(-1)[0], "error");
assert.match(heard.at(-1)[1].message, /not sent: set_placement.placement.matrix\[5\]: NaN is not finite/);
assert.equal(heard.at(-1)[1].stroke, stroke);

// Moves answered late: three moves of one of our strokes, then the proxy's answers. Only the
// answer to the latest one reaches the page (it already shows that one; an earlier answer would
// take the stroke back until the next came); a refusal counts as an answer; a move of another
// stroke, and a peer_placement no move of ours asked for (a copy's, another page's), are heard.
const moved = "3c4d5e6f-7a8b-4c9d-8e0f-1a2b3c4d5e6f";
const at = (x) => ({ matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, 0, 0, 1] });
const answer = (x, s = moved) => binary({ peer_placement: { participant: me, stroke: s, placement: at(x) } });
heard.length = 0;
for (const x of [10, 20, 30]) assert.ok(conn.setPlacement(moved, at(x).matrix));
ws.onmessage(answer(10));
ws.onmessage(answer(5, "4d5e6f7a-8b9c-4dae-9f01-2b3c4d5e6f7a")); // another stroke's: heard
ws.onmessage(answer(20));
assert.deepEqual(heard.map(([kind, m]) => [kind, m.placement.matrix[12]]), [["peer_placement", 5]], "the answers to overtaken moves are not heard");
ws.onmessage(answer(30));
assert.deepEqual(heard.at(-1), ["peer_placement", { participant: me, stroke: moved, placement: at(30) }], "the latest move's answer is heard");
ws.onmessage(answer(40));
assert.equal(heard.at(-1)[1].placement.matrix[12], 40, "a peer_placement no move asked for is heard");
// Two moves, the second refused: its error (which overtakes the first's answer) answers it, so
// the first's answer is heard, as the stroke is where the proxy has it.
heard.length = 0;
for (const x of [50, 60]) assert.ok(conn.setPlacement(moved, at(x).matrix));
ws.onmessage(binary({ error: { code: "not_owner", message: "not yours", stroke: moved } }));
ws.onmessage(answer(50));
assert.deepEqual(heard.map(([kind]) => kind), ["error", "peer_placement"], "a refused move is answered by its error");

console.log("PASS connection: binary and text frames in one receive, in order; a bad frame said and dropped; moves binary or JSON; the answers to overtaken moves left out");
process.exit(0); // the connection's keepalive timer would keep Node running
