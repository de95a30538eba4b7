// The browser test of strokes whose end is lost with the connection (docs/web.md), with
// Playwright's WebSocket routing between the page and the proxy:
// 1. a fast hand lifts the pen and puts it down again before the proxy has answered the first
//    stroke's end, and the connection drops in between (the `stroke_end` lost with it). The
//    page keeps every stroke of its own until the proxy says it is done, and resumes them all
//    on the next connection: each is ended, stored whole and gets its mesh;
// 2. the connection is lost at the page's end only (a network gone without a close): the proxy
//    still holds the old connection and refuses the resume (`stroke_conflict`) until its
//    heartbeat lets it go; the page tries again on its new connection and ends the stroke then;
// 3. the same while the pen is down: the page keeps what it draws meanwhile and sends it once
//    the stroke is taken over.
// Run by scripts/test.sh.
import assert from "node:assert/strict";
import { decodeClient, decodeServer } from "../src/codec.js";
import { browserTest, drawStroke, log, newSession, storedStrokes, synced, until } from "./harness.mjs";

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const strokes = () => storedStrokes(base, { session, token });

  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  // Every connection of the page goes through here. While `loseEnd` is set, the next
  // `stroke_end` the page sends is dropped (its stroke in `lost`), as if the connection had died
  // with it in flight.
  let loseEnd = false;
  let lost = null;
  const connections = []; // both ends of each, the latest last
  const conflicts = []; // strokes named by a `stroke_conflict` the proxy sent
  await context.routeWebSocket(/\/ws$/, (page) => {
    const server = page.connectToServer();
    const connection = { page, server, keepServer: false };
    connections.push(connection);
    // A close at the page's end is passed on to the proxy unless `keepServer` (the routing's
    // default, once this handler is set, is not to).
    page.onClose((code, reason) => {
      if (!connection.keepServer) server.close({ code, reason });
    });
    // The page speaks binary frames (src/codec.js); a text frame is JSON.
    page.onMessage((message) => {
      const m = typeof message === "string" ? JSON.parse(message) : decodeClient(message);
      if (loseEnd && m.stroke_end) {
        loseEnd = false;
        lost = m.stroke_end.stroke;
        return;
      }
      server.send(message);
    });
    server.onMessage((message) => {
      const m = typeof message === "string" ? JSON.parse(message) : decodeServer(message);
      if (m.error && m.error.code === "stroke_conflict") conflicts.push(m.error.stroke);
      page.send(message);
    });
  });
  // Closes the latest connection at the page's end and, unless `pageOnly`, at the proxy's (a
  // page's WebSocket may close with 1000 or 3000-4999 only).
  const drop = async ({ pageOnly = false } = {}) => {
    const connection = connections[connections.length - 1];
    connection.keepServer = pageOnly;
    if (!pageOnly) await connection.server.close({ code: 4000, reason: "test: connection lost" });
    await connection.page.close({ code: 4000, reason: "test: connection lost" });
    return connection;
  };

  const page = await context.newPage();
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto(`${base}/s/${session}#token=${token}`);
  await synced(page);
  const cdp = await context.newCDPSession(page);
  const drawnOf = new Map(); // stroke id -> the samples drawn
  const waitAllDone = async (what, meshes) =>
    until(what, () => page.evaluate((n) => window.penmesh.meshes >= n && !window.penmesh.pending, meshes)).catch(async (err) => {
      const state = await page.evaluate(() => ({ unfinished: window.penmesh.unfinished, meshes: window.penmesh.meshes, errors: window.penmesh.errors }));
      throw new Error(`${err.message}; the page: ${JSON.stringify(state)}; stored: ${JSON.stringify((await strokes()).map((s) => [s.id, s.status, s.n_points]))}`);
    });
  // Every stroke done with its mesh and every sample drawn stored once (no two of these
  // strokes' samples are equal, so stage 1 drops none).
  const checkStored = async (count) => {
    const stored = await strokes();
    assert.equal(stored.length, count, "no stroke added or lost");
    for (const s of stored) {
      assert.equal(s.status, "done", `stroke ${s.id} is done`);
      assert.ok(s.has_mesh, `stroke ${s.id} has a mesh`);
      if (drawnOf.has(s.id)) assert.equal(s.n_points, drawnOf.get(s.id).length, `stroke ${s.id}: ${s.n_points} samples stored, ${drawnOf.get(s.id).length} drawn`);
    }
    assert.deepEqual(await page.evaluate(() => window.penmesh.errors), [], "the page reported errors");
  };

  // --- 1. a stroke's end lost, the next stroke drawn, then the connection drops -------------
  loseEnd = true;
  const first = await drawStroke(cdp, { x0: 150, y0: 200, dx: 5, dy: 1, n: 60 });
  await until("the first stroke's end to be lost", () => lost !== null);
  drawnOf.set(lost, first);
  // The pen comes down again: the page may begin the next stroke, as the first has ended on
  // its side, and draws it whole.
  const second = await drawStroke(cdp, { x0: 200, y0: 450, dx: 5, dy: -1, n: 60 });
  await until("the second stroke to be done with its mesh", () => page.evaluate(() => window.penmesh.meshes >= 1));
  const before = await strokes();
  assert.equal(before.length, 2, "two strokes stored");
  assert.equal(before.find((s) => s.id === lost).status, "open", "the first stroke is still open: its end was lost");
  drawnOf.set(before.find((s) => s.id !== lost).id, second);
  assert.equal(await page.evaluate(() => window.penmesh.unfinished), 1, "the page still has the first stroke to finish");
  log("the first stroke's end lost, the second drawn");

  await drop();
  await until("the page to reconnect", () => connections.length >= 2);
  await waitAllDone("both strokes done with meshes", 2);
  await checkStored(2);
  log("after the reconnect: the first stroke ended, both stored whole with meshes");

  // --- 2. the end lost again, and the connection lost at the page's end only ----------------
  loseEnd = true;
  lost = null;
  const third = await drawStroke(cdp, { x0: 550, y0: 150, dx: 1, dy: 5, n: 60 });
  await until("the third stroke's end to be lost", () => lost !== null);
  drawnOf.set(lost, third);
  const { server: old } = await drop({ pageOnly: true });
  await until("the proxy to refuse the resume while the old connection holds the stroke", () => conflicts.includes(lost));
  assert.equal((await strokes()).find((s) => s.id === lost).status, "open");
  // The proxy's heartbeat would let the old connection go within seconds; here it goes now.
  await old.close({ code: 4000, reason: "test: the heartbeat gave up" });
  await waitAllDone("the third stroke done with its mesh, taken over on the new connection", 3);
  assert.equal(connections.length, 3, "taken over without another reconnect");
  await checkStored(3);
  log("a resume refused while the old connection held the stroke: tried again, ended, stored whole");

  // --- 3. the same with the pen down -------------------------------------------------------
  const pen = (type, [x, y, force]) =>
    cdp.send("Input.dispatchMouseEvent", { type, x, y, force, button: "left", buttons: type === "mouseReleased" ? 0 : 1, clickCount: 1, pointerType: "pen" });
  const path = (from, n) => Array.from({ length: n }, (_, k) => [700 + 3 * (from + k), 450 + 25 * Math.sin((from + k) / 8), 0.3 + 0.5 * Math.abs(Math.sin((from + k) / 9))]);
  const fourth = [];
  const move = async (from, n) => {
    for (const sample of path(from, n)) {
      await pen(fourth.length === 0 ? "mousePressed" : "mouseMoved", sample);
      fourth.push(sample);
    }
  };
  await move(0, 30);
  const drawing = await page.evaluate(() => window.penmesh.pending.stroke);
  drawnOf.set(drawing, fourth);
  const { server: held } = await drop({ pageOnly: true });
  await move(30, 30);
  await until("the proxy to refuse the resume of the stroke being drawn", () => conflicts.includes(drawing));
  await move(60, 30);
  await held.close({ code: 4000, reason: "test: the heartbeat gave up" });
  // Taken over with the pen still down: what was drawn meanwhile reaches the proxy.
  const storedCount = async () => (await strokes()).find((s) => s.id === drawing).n_points;
  await until("the stroke being drawn to be taken over, with what was drawn meanwhile", async () => (await storedCount()) === fourth.length);
  await move(90, 30);
  await pen("mouseReleased", fourth[fourth.length - 1]);
  await waitAllDone("the fourth stroke done with its mesh", 4);
  assert.equal(connections.length, 4, "taken over without another reconnect");
  await checkStored(4);
  log("the pen down while its stroke was held by the old connection: every sample stored once");
});
