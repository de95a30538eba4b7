// The browser test of a stroke whose end is lost with the connection (docs/web.md): a fast
// hand lifts the pen and puts it down again before the proxy has answered the first stroke's
// end, and the connection drops in between. The page keeps every stroke of its own until the
// proxy says it is done, and resumes them all on the next connection: each is ended, stored
// whole and gets its mesh. Playwright's WebSocket routing stands between the page and the
// proxy, to lose the first `stroke_end` and to drop the connection. Run by scripts/test.sh.
import assert from "node:assert/strict";
import { browserTest, drawStroke, log, newSession, until } from "./harness.mjs";

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const strokes = async () => {
    const res = await fetch(`${base}/v1/sessions/${session}/strokes`, { headers: { authorization: `Bearer ${token}` } });
    assert.ok(res.ok, `GET strokes: HTTP ${res.status}`);
    return (await res.json()).strokes;
  };

  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  // Every connection of the page goes through here. While `loseEnd` is set, the first
  // `stroke_end` the page sends is dropped, as if the connection had died with it in flight.
  let loseEnd = true;
  let lost = null;
  let connections = 0;
  let current = null; // both ends of the latest connection
  await context.routeWebSocket(/\/ws$/, (page) => {
    connections += 1;
    const server = page.connectToServer();
    current = { page, server };
    page.onMessage((message) => {
      if (loseEnd && lost === null && String(message).includes('"stroke_end"')) {
        lost = JSON.parse(message).stroke_end.stroke;
        return;
      }
      server.send(message);
    });
    server.onMessage((message) => page.send(message));
  });

  const page = await context.newPage();
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto(`${base}/s/${session}#token=${token}`);
  await page.waitForFunction(() => window.penmesh && window.penmesh.me && window.penmesh.synced);
  const cdp = await context.newCDPSession(page);

  // The first stroke: drawn whole, but its end never reaches the proxy.
  const first = await drawStroke(cdp, { x0: 150, y0: 200, dx: 5, dy: 1, n: 60 });
  await until("the first stroke's end to be lost", () => lost !== null);
  // The pen comes down again: the page may begin the next stroke, as the first has ended on
  // its side, and draws it whole.
  const second = await drawStroke(cdp, { x0: 200, y0: 450, dx: 5, dy: -1, n: 60 });
  await until("the second stroke to be done with its mesh", () => page.evaluate(() => window.penmesh.meshes >= 1));
  const before = await strokes();
  assert.equal(before.length, 2, "two strokes stored");
  assert.equal(before.find((s) => s.id === lost).status, "open", "the first stroke is still open: its end was lost");
  assert.equal(await page.evaluate(() => window.penmesh.unfinished), 1, "the page still has the first stroke to finish");
  log("the first stroke's end lost, the second drawn");

  // The connection drops, at both ends. The page reconnects and resumes what it has not seen
  // done.
  loseEnd = false;
  // (A page's WebSocket may close with 1000 or 3000-4999 only.)
  await current.server.close({ code: 4000, reason: "test: connection lost" });
  await current.page.close({ code: 4000, reason: "test: connection lost" });
  await until("the page to reconnect", () => connections >= 2);
  await until("both strokes done with meshes", () => page.evaluate(() => window.penmesh.meshes >= 2 && !window.penmesh.pending), 30000).catch(async (err) => {
    const state = await page.evaluate(() => ({ unfinished: window.penmesh.unfinished, meshes: window.penmesh.meshes, errors: window.penmesh.errors }));
    throw new Error(`${err.message}; the page: ${JSON.stringify(state)}; stored: ${JSON.stringify((await strokes()).map((s) => [s.id, s.status, s.n_points]))}`);
  });
  const after = await strokes();
  assert.equal(after.length, 2, "no stroke added or lost");
  for (const [label, s, drawn] of [["first", after.find((s) => s.id === lost), first], ["second", after.find((s) => s.id !== lost), second]]) {
    assert.equal(s.status, "done", `the ${label} stroke is done`);
    assert.ok(s.has_mesh, `the ${label} stroke has a mesh`);
    // Every sample once (no two of these strokes' samples are equal, so stage 1 drops none).
    assert.equal(s.n_points, drawn.length, `the ${label} stroke: ${s.n_points} samples stored, ${drawn.length} drawn`);
  }
  assert.deepEqual(await page.evaluate(() => window.penmesh.errors), [], "the page reported errors");
  log("after the reconnect: the first stroke ended, both stored whole with meshes");
});
