// The browser test of the page (docs/web.md): a real proxy (`penmesh-proxy`), Debian's
// Chromium driven by playwright-core, a pen through the DevTools protocol. Run by
// scripts/test.sh as `node client/web/test/browser.mjs` with PENMESH_BIN set to the built
// `penmesh` binary. Screenshots go to target/web-test/. Any failure exits non-zero; a missing
// Chromium is a failure, never a skip.
import { writeFileSync } from "node:fs";
import { join } from "node:path";
import assert from "node:assert/strict";
import { ARTIFACTS, browserTest, drawStroke, isBackground, log, newSession, pixelsAt, runPenmesh, synced, until } from "./harness.mjs";

// The page sends JSON (exact values); the native client's binary frames are on this grid.
const POSITION_STEP = 1 / 16;
const PRESSURE_STEP = 1 / 1024;

await browserTest(async ({ proxy, browser, children }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const auth = { authorization: `Bearer ${token}` };
  const getJson = async (path) => {
    const res = await fetch(`${base}${path}`, { headers: auth });
    assert.ok(res.ok, `GET ${path}: HTTP ${res.status}`);
    return res.json();
  };
  const pageUrl = `${base}/s/${session}#token=${token}`;

  // The token must not be in the page's URL path or query, nor in the WebSocket's URL.
  assert.ok(!new URL(pageUrl).pathname.includes(token) && !new URL(pageUrl).search.includes(token));

  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  const wsUrls = [];
  async function openPage(name) {
    const page = await context.newPage();
    page.on("pageerror", (e) => console.error(`[${name}] page error:`, e.message));
    page.on("websocket", (ws) => wsUrls.push(ws.url()));
    page.paths = []; // the HTTP paths it asked for
    page.on("request", (r) => page.paths.push(new URL(r.url()).pathname));
    await page.goto(pageUrl);
    await synced(page);
    return page;
  }

  function assertSamples(label, stored, sent) {
    assert.equal(stored.length, sent.length, `${label}: ${stored.length} samples stored, ${sent.length} drawn`);
    stored.forEach(([x, y, , p], i) => {
      const [sx, sy, sp] = sent[i];
      assert.ok(Math.abs(x - sx) <= POSITION_STEP && Math.abs(y - sy) <= POSITION_STEP, `${label} sample ${i}: stored (${x}, ${y}), drawn (${sx}, ${sy})`);
      // The page snaps pressure to the protocol's grid before sending; the proxy stores that.
      const sentP = Math.round(sp / PRESSURE_STEP) * PRESSURE_STEP;
      assert.ok(Math.abs(p - sentP) < 1e-12, `${label} sample ${i}: stored pressure ${p}, sent ${sentP} (drawn ${sp})`);
    });
  }

  // --- 1. three pen strokes in page A ------------------------------------------------------
  const a = await openPage("A");
  const cdpA = await context.newCDPSession(a);
  const drawn = [];
  const plans = [
    { x0: 150, y0: 150, dx: 5, dy: 2, n: 80 },
    { x0: 200, y0: 400, dx: 6, dy: -1, n: 70 },
    { x0: 700, y0: 120, dx: 0.5, dy: 5, n: 90 },
  ];
  for (const plan of plans) {
    drawn.push(await drawStroke(cdpA, plan));
    const want = drawn.length;
    await until(`page A to show mesh ${want}`, () => a.evaluate((w) => window.penmesh.meshes >= w && !window.penmesh.pending, want));
  }
  log("three strokes drawn");
  const errorsA = await a.evaluate(() => window.penmesh.errors);
  assert.deepEqual(errorsA, [], "page A reported errors");

  const list = (await getJson(`/v1/sessions/${session}/strokes`)).strokes;
  assert.equal(list.length, 3, "three strokes stored");
  for (const [i, s] of list.entries()) {
    assert.equal(s.status, "done", `stroke ${i} is done`);
    assert.ok(s.has_mesh, `stroke ${i} has a mesh`);
    assert.equal(s.device, "web:pen");
    const raw = await getJson(`/v1/strokes/${s.id}/raw`);
    assertSamples(`stroke ${i}`, raw.samples, drawn[i]);
    const mesh = await fetch(`${base}/v1/strokes/${s.id}/mesh`, { headers: auth });
    assert.equal(mesh.status, 200);
    assert.ok((await mesh.arrayBuffer()).byteLength > 100, "a real GLB");
  }
  log("stored samples and meshes checked");

  // The meshes are on screen where the strokes were drawn, and the rest is background.
  const onStroke = drawn.flatMap((s) => [s[10], s[Math.floor(s.length / 2)], s[s.length - 10]]);
  const onPixels = await pixelsAt(a, onStroke, join(ARTIFACTS, "page-a.png"));
  onPixels.forEach((px, i) => assert.ok(!isBackground(px), `no mesh on screen at drawn point ${i} (${onStroke[i]}): ${px}`));
  const empty = [[950, 650], [500, 650], [950, 400]];
  (await pixelsAt(a, empty, join(ARTIFACTS, "page-a.png"))).forEach((px, i) => assert.ok(isBackground(px), `something drawn at empty point ${empty[i]}: ${px}`));
  log("page A shows the three meshes");

  // --- 2. a later page sees the history, and a native client drawing live ------------------
  const b = await openPage("B");
  await until("page B to show the history", () => b.evaluate(() => window.penmesh.meshes >= 3));
  // The history's meshes came in one request, not one per mesh.
  assert.deepEqual(b.paths.filter((p) => p.includes("/mesh")), [`/v1/sessions/${session}/meshes`], "page B's mesh requests");
  const native = runPenmesh(["draw", "--server", base, "--session", session, "--token", token, "--synth", "leaf", "--realtime", "--name", "native"], children);
  native.catch(() => {}); // awaited below; this only keeps an early failure from going unhandled
  // Live: the native stroke's retained points reach page B before its mesh does.
  await until("page B to see the native stroke grow", () => b.evaluate(() => [...window.penmesh.strokes.values()].some((s) => s.line && !s.mesh)));
  await native;
  await until("page B to show the native mesh", () => b.evaluate(() => window.penmesh.meshes >= 4));
  assert.equal((await getJson(`/v1/sessions/${session}/strokes`)).strokes.length, 4);
  await b.screenshot({ path: join(ARTIFACTS, "page-b.png") });
  assert.ok(await b.evaluate(() => [...window.penmesh.people.values()].length >= 2), "page B lists who is here");
  log("page B: history and the native stroke live");

  // --- 3. reload in the middle of a stroke --------------------------------------------------
  // The pen draws on the page in front (a page behind, which has no frame to draw, gets its
  // input late: about a second per event in headless Chromium).
  await a.bringToFront();
  const half = await drawStroke(cdpA, { x0: 600, y0: 500, dx: 4, dy: -1, n: 40, lift: false });
  const meA = await a.evaluate(() => window.penmesh.me);
  assert.notEqual(meA, await b.evaluate(() => window.penmesh.me), "two tabs are two participants");
  await a.reload();
  await a.waitForFunction(() => window.penmesh && window.penmesh.synced);
  assert.equal(await a.evaluate(() => window.penmesh.me), meA, "a reload is the same participant");
  await until("the resumed stroke to be done with a mesh", () => a.evaluate(() => !window.penmesh.pending && window.penmesh.meshes >= 5));
  const after = (await getJson(`/v1/sessions/${session}/strokes`)).strokes;
  assert.equal(after.length, 5);
  const resumed = after.find((s) => s.device === "web:pen" && !list.some((l) => l.id === s.id));
  assert.equal(resumed.status, "done");
  assert.ok(resumed.has_mesh);
  assertSamples("resumed stroke", (await getJson(`/v1/strokes/${resumed.id}/raw`)).samples, half);
  await a.screenshot({ path: join(ARTIFACTS, "page-a-after-reload.png") });
  log("reload mid-stroke: resumed, every sample once");

  // --- 4. palm rejection: a touch while the pen is down draws nothing ----------------------
  const meshesBefore = await a.evaluate(() => window.penmesh.meshes);
  const pen = drawStroke(cdpA, { x0: 300, y0: 600, dx: 5, dy: 0, n: 30 });
  await cdpA.send("Input.dispatchTouchEvent", { type: "touchStart", touchPoints: [{ x: 900, y: 300 }] });
  await cdpA.send("Input.dispatchTouchEvent", { type: "touchMove", touchPoints: [{ x: 850, y: 320 }] });
  await cdpA.send("Input.dispatchTouchEvent", { type: "touchEnd", touchPoints: [] });
  await pen;
  await until("the pen stroke's mesh", () => a.evaluate((n) => !window.penmesh.pending && window.penmesh.meshes > n, meshesBefore));
  const last = (await getJson(`/v1/sessions/${session}/strokes`)).strokes;
  assert.equal(last.length, 6, "one stroke more: the pen's, not the palm's");
  assert.deepEqual(last.filter((s) => s.device !== "web:pen" && s.device !== null && !s.device.startsWith("synth")), [], "a touch stroke was stored");
  log("palm rejection: the touch drew nothing");

  // --- 5. the merged view: a stroke drawn on page A joins its person's meshes on page B ----
  const meshesB = await b.evaluate(() => window.penmesh.meshes);
  await drawStroke(cdpA, { x0: 400, y0: 250, dx: 3, dy: 3, n: 50 });
  await b.bringToFront();
  await until("page B to show page A's new stroke", () => b.evaluate((n) => window.penmesh.meshes > n, meshesB));
  // Every finished mesh of a person is one draw call: page B's two people (page A and the
  // native client) are two, however many strokes each drew.
  const peopleWithMeshes = new Set((await getJson(`/v1/sessions/${session}/strokes`)).strokes.map((s) => s.participant)).size;
  assert.equal(peopleWithMeshes, 2);
  await until("page B to draw the merged view", () => b.evaluate(() => [...window.penmesh.strokes.values()].every((s) => s.mesh && !s.line)));
  await b.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  // (And the ground's grid and axes, ground.js: two more.)
  assert.equal(await b.evaluate(() => window.penmesh.drawCalls), peopleWithMeshes + 2, "draw calls of page B's last frame");
  await b.screenshot({ path: join(ARTIFACTS, "page-b-merged.png") });
  // Nothing changes, nothing is rendered.
  const framesB = await b.evaluate(() => window.penmesh.frames);
  assert.ok(framesB > 0, "page B rendered");
  // Watched for 1.5 s: what is checked is that nothing happens (an observation window, not a
  // wait for something to happen; a busy machine only renders fewer frames).
  await b.waitForTimeout(1500);
  assert.equal(await b.evaluate(() => window.penmesh.frames), framesB, "an idle page rendered frames");
  log("merged view: one draw call per person, no frame while idle");

  for (const url of wsUrls) assert.ok(!url.includes(token), `the token is in a WebSocket URL: ${url}`);
  assert.ok(wsUrls.length >= 3);
  writeFileSync(join(ARTIFACTS, "result.json"), JSON.stringify({ ok: true }));
});
