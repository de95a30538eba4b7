// What a move costs the page on the wire (issue 37: at most 200 bytes), measured in Debian's
// Chromium: two pages of one session (Ada draws and moves, Bob watches), every WebSocket frame
// of both read through CDP (Network.webSocketFrameSent / Received; a binary payload comes in
// base64). Ada moves her stroke with the gizmo's X handle, then turns it by an odd angle with
// its Z ring; each time her `set_placement` and Bob's `peer_placement` are binary frames
// (src/codec.js) of at most 200 bytes with the WebSocket framing (RFC 6455: 2 header bytes, 2
// more for a payload of 126 to 65535, and a client's 4 mask bytes), and both pages end with the
// proxy's placement. Undo and redo are moves too. Then the page reads both encodings at every
// moment: Bob switches to JSON (the proxy answers him in text from his next frame) and Ada's
// moves still reach him, then back to binary; Ada sends the turn once more in JSON, for the
// comparison. Last, the page's decoder against the proxy's encoder on a long batch: the
// stroke's `/raw` as one binary `retained` frame decodes to the samples of its JSON.
// Run by scripts/test.sh as `node client/web/test/move-bytes.mjs`.
import assert from "node:assert/strict";
import { decodeClient, decodeServer } from "../src/codec.js";
import { browserTest, drawStroke, log, newSession, openPage, selectForGizmo, sessionUrl, storedStrokes, until } from "./harness.mjs";

const GOAL = 200;
const IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];

/// Bytes on the wire of a WebSocket message of `n` payload bytes (RFC 6455, section 5.2).
const onWire = (n, fromClient) => n + 2 + (n < 126 ? 0 : n < 65536 ? 2 : 8) + (fromClient ? 4 : 0);

/// Records every WebSocket frame `page` sends and receives from its start (harness.mjs `openPage`'s
/// `prepare`): `page.frames`, each {dir, binary, bytes, message}.
function recordFrames(page) {
  page.frames = [];
  const record = (dir) => (e) => {
    const { opcode, payloadData } = e.response;
    if (opcode !== 1 && opcode !== 2) return; // a close or a control frame
    const binary = opcode === 2;
    const bytes = binary ? Buffer.from(payloadData, "base64") : Buffer.from(payloadData, "utf8");
    const message = binary ? (dir === "sent" ? decodeClient : decodeServer)(bytes) : JSON.parse(payloadData);
    page.frames.push({ dir, binary, bytes: bytes.length, message, kind: Object.keys(message)[0] });
  };
  page.cdp.on("Network.webSocketFrameSent", record("sent"));
  page.cdp.on("Network.webSocketFrameReceived", record("received"));
  return page.cdp.send("Network.enable");
}

/// The frames of `kind` that `page` sent or received (`dir`) since `from` (an index of its frames).
const framesOf = (page, dir, kind, from = 0) => page.frames.slice(from).filter((f) => f.dir === dir && f.kind === kind);
const placements = (page) => page.evaluate(() => window.penmesh.placements);
const orIdentity = (m) => m || IDENTITY;

async function stored(base, s) {
  return Object.fromEntries((await storedStrokes(base, s)).map((x) => [x.id, x.placement.matrix]));
}

/// Both pages and the proxy have `want` as the stroke's placement, bit for bit.
async function agree(base, s, pages, stroke, want, what) {
  await until(`${what}: the proxy and both pages`, async () => {
    const server = (await stored(base, s))[stroke];
    if (JSON.stringify(server) !== JSON.stringify(want)) return false;
    for (const page of pages) if (JSON.stringify(orIdentity((await placements(page))[stroke])) !== JSON.stringify(want)) return false;
    return true;
  });
}

/// One move's frames: Ada's `set_placement` and Bob's `peer_placement` since the marks, each
/// exactly one, of the form wanted; returns their payload and wire bytes.
function oneMove(ada, bob, marks, stroke, { adaBinary, bobBinary, what }) {
  const sent = framesOf(ada, "sent", "set_placement", marks.ada);
  const got = framesOf(bob, "received", "peer_placement", marks.bob).filter((f) => f.message.peer_placement.stroke === stroke);
  assert.equal(sent.length, 1, `${what}: Ada sent one set_placement`);
  assert.equal(got.length, 1, `${what}: Bob received one peer_placement`);
  assert.equal(sent[0].binary, adaBinary, `${what}: Ada's set_placement is a ${adaBinary ? "binary" : "text"} frame`);
  assert.equal(got[0].binary, bobBinary, `${what}: Bob's peer_placement is a ${bobBinary ? "binary" : "text"} frame`);
  assert.deepEqual(got[0].message.peer_placement.placement, sent[0].message.set_placement.placement, `${what}: Bob got the placement Ada sent`);
  return {
    set_placement: { payload: sent[0].bytes, wire: onWire(sent[0].bytes, true) },
    peer_placement: { payload: got[0].bytes, wire: onWire(got[0].bytes, false) },
  };
}
const marksOf = (ada, bob) => ({ ada: ada.frames.length, bob: bob.frames.length });

browserTest(async ({ proxy, browser }) => {
  const base = proxy.base;
  const s = await newSession(base);
  const url = sessionUrl(base, s);
  const ada = await openPage(browser, url, { name: "ada", prepare: recordFrames });
  const bob = await openPage(browser, url, { name: "bob", prepare: recordFrames });
  for (const [name, page] of [["Ada", ada], ["Bob", bob]]) {
    const [hello] = framesOf(page, "sent", "hello");
    assert.ok(hello && hello.binary, `${name}'s hello is a binary frame`);
    assert.equal(hello.message.hello.protocol, 6, `${name} says protocol 6`);
    assert.ok(framesOf(page, "received", "welcome")[0].binary, `${name}'s welcome comes binary`);
  }

  // Ada draws a stroke of 150 pen events (binary points), and it reaches Bob.
  await drawStroke(ada.cdp, { x0: 300, y0: 250, dx: 3, dy: 1.2, n: 150 });
  await until("Ada's stroke done with its mesh", () => ada.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending));
  const [stroke] = Object.keys(await placements(ada));
  await until("the stroke on Bob's page", async () => stroke in (await placements(bob)));
  const points = framesOf(ada, "sent", "points");
  assert.ok(points.length && points.every((f) => f.binary), "Ada's points went as binary frames");
  // What they cost against the same messages in JSON (what the page sent before codec.js).
  const drawn = points.reduce((n, f) => n + f.message.points.points.length, 0);
  const drawing = {
    samples: drawn,
    frames: points.length,
    binary_bytes: points.reduce((n, f) => n + f.bytes, 0),
    json_bytes: points.reduce((n, f) => n + Buffer.byteLength(JSON.stringify(f.message)), 0),
  };
  log(`drawing: ${drawn} samples in ${points.length} points frames, ${drawing.binary_bytes} B binary against ${drawing.json_bytes} B as JSON`);

  // 1. The move, with the gizmo's X handle (Select, a click on the stroke, a drag).
  await ada.keyboard.press("v");
  const handle = await selectForGizmo(ada, stroke);
  let marks = marksOf(ada, bob);
  await ada.mouse.move(...handle);
  await ada.mouse.down();
  await ada.mouse.move(handle[0] + 137, handle[1] + 11, { steps: 15 });
  await ada.mouse.up();
  const moved = (await placements(ada))[stroke];
  assert.ok(moved && moved[12] !== 0, `the gizmo moved the stroke: ${JSON.stringify(moved)}`);
  await agree(base, s, [ada, bob], stroke, moved, "moved");
  const move = oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: true, what: "the gizmo's move" });
  // Ada's page placed the stroke itself, so the pages agree before her answer need have come.
  const answers = () => framesOf(ada, "received", "peer_placement", marks.ada).filter((f) => f.message.peer_placement.stroke === stroke);
  await until("Ada's answer to her move", () => answers().length > 0);
  const echo = answers();
  assert.ok(echo.length === 1 && echo[0].binary, `Ada's answer, the peer_placement of her move, comes binary, once: ${echo.length} answers`);
  log(`a move: set_placement ${move.set_placement.payload} B (${move.set_placement.wire} B on the wire), peer_placement ${move.peer_placement.payload} B (${move.peer_placement.wire} B)`);
  for (const [what, m] of Object.entries(move)) {
    assert.ok(m.wire <= GOAL, `${what}: ${m.wire} bytes on the wire, over ${GOAL}`);
  }

  // 2. A turn (R, a drag along the Z ring, no snap): the matrix's elements are 17-digit cosines
  //    and sines, which JSON writes out in full and binary in 8 bytes as any.
  await ada.keyboard.press("r");
  const ring = await ada.evaluate(() => window.penmesh.gizmoHandle("Z"));
  assert.ok(ring, "no Z ring on the selected stroke");
  marks = marksOf(ada, bob);
  await ada.mouse.move(...ring);
  await ada.mouse.down();
  await ada.mouse.move(ring[0] - 43, ring[1] - 29, { steps: 12 });
  await ada.mouse.up();
  const turned = (await placements(ada))[stroke];
  assert.ok(turned[1] !== 0 && String(turned[0]).length > 10, `the ring turned the stroke by an odd angle: ${JSON.stringify(turned)}`);
  await agree(base, s, [ada, bob], stroke, turned, "turned");
  const turn = oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: true, what: "the gizmo's turn" });
  log(`a turn: set_placement ${turn.set_placement.payload} B (${turn.set_placement.wire} B on the wire), peer_placement ${turn.peer_placement.payload} B (${turn.peer_placement.wire} B)`);

  // 3. Undo and redo are moves too.
  marks = marksOf(ada, bob);
  await ada.keyboard.press("Control+z");
  await agree(base, s, [ada, bob], stroke, moved, "the turn undone");
  const undo = oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: true, what: "undo" });
  marks = marksOf(ada, bob);
  await ada.keyboard.press("Control+Shift+z");
  await agree(base, s, [ada, bob], stroke, turned, "the turn redone");
  const redo = oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: true, what: "redo" });
  for (const m of [move, turn, undo, redo]) {
    for (const [what, b] of Object.entries(m)) assert.ok(b.wire <= GOAL, `${what}: ${b.wire} bytes on the wire, over ${GOAL}`);
  }

  // 4. Both encodings at every moment: Bob says JSON (a Ping in text), so the proxy answers him
  //    in text; Ada's binary moves still reach him. Then Ada sends the turn again in JSON: the
  //    same move as in 2, for the comparison.
  await bob.evaluate(() => {
    window.penmesh.encoding = "json";
    window.penmesh.ping();
  });
  await until("Bob's pong in text", () => framesOf(bob, "received", "pong").some((f) => !f.binary));
  marks = marksOf(ada, bob);
  await ada.keyboard.press("Control+z");
  await agree(base, s, [ada, bob], stroke, moved, "undone, Bob in JSON");
  const textIn = oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: false, what: "undo, Bob in JSON" });
  await ada.evaluate(() => {
    window.penmesh.encoding = "json";
  });
  marks = marksOf(ada, bob);
  await ada.keyboard.press("Control+Shift+z");
  await agree(base, s, [ada, bob], stroke, turned, "redone in JSON");
  const json = oneMove(ada, bob, marks, stroke, { adaBinary: false, bobBinary: false, what: "redo, both in JSON" });
  log(`the move in JSON: set_placement ${textIn.set_placement.payload} B binary, Bob's peer_placement ${textIn.peer_placement.payload} B (${textIn.peer_placement.wire} B) in text`);
  log(`the turn in JSON: set_placement ${json.set_placement.payload} B (${json.set_placement.wire} B on the wire), peer_placement ${json.peer_placement.payload} B (${json.peer_placement.wire} B)`);
  // Back to binary: the next frame each page sends says so.
  for (const page of [ada, bob]) {
    await page.evaluate(() => {
      window.penmesh.encoding = "binary";
      window.penmesh.ping();
    });
  }
  await until("pongs in binary again", () => [ada, bob].every((p) => framesOf(p, "received", "pong").some((f) => f.binary)));
  marks = marksOf(ada, bob);
  await ada.keyboard.press("Control+z");
  await agree(base, s, [ada, bob], stroke, moved, "undone, both in binary again");
  oneMove(ada, bob, marks, stroke, { adaBinary: true, bobBinary: true, what: "undo, binary again" });
  for (const [name, page] of [["Ada", ada], ["Bob", bob]]) {
    const errors = await page.evaluate(() => window.penmesh.errors);
    assert.deepEqual(errors, [], `${name}'s page reported no error`);
  }

  // 5. The page's decoder against the proxy's encoder: the stroke's samples (150 and more, a
  //    batch past the order's 64-sample halving) as one binary `retained` frame, and as JSON.
  const headers = { authorization: `Bearer ${s.token}` };
  const asJson = await (await fetch(`${base}/v1/strokes/${stroke}/raw`, { headers })).json();
  const res = await fetch(`${base}/v1/strokes/${stroke}/raw`, { headers: { ...headers, accept: "application/octet-stream" } });
  assert.equal(res.status, 200);
  const frame = new Uint8Array(await res.arrayBuffer());
  const decoded = decodeServer(frame);
  assert.ok(asJson.samples.length > 100, `a long stroke: ${asJson.samples.length} samples`);
  assert.deepStrictEqual(decoded, { retained: { stroke, first: 0, points: asJson.samples } }, "/raw's binary frame decodes to its JSON samples");
  log(`/raw: ${asJson.samples.length} samples in a ${frame.length}-byte frame decode to the JSON's`);

  const report = { move, turn, undo, redo, move_bob_text: textIn, turn_json: json, drawing, raw: { samples: asJson.samples.length, frame_bytes: frame.length } };
  console.log(`move-bytes: ${JSON.stringify(report)}`);
});
