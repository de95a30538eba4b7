// Item 6 of issue 36: a stroke looks the same after its mesh comes. Along straight strokes
// with smoothly varying pressure (as a held-out recording's middle is), the mesh's width
// between neighbouring rings changes by no more than the pen's width did over the same span
// (plus WIDTH_SLACK_PX), and at every sample it is within WIDTH_SLACK_PX of the live ink's
// (the ink is as wide as the pen's pressure makes it: ink.js).
// Prints the largest step of both. Screenshots of the ink and of the mesh of one stroke, side
// by side, go to target/web-test/width-*.png (docs/web.md).
import { join } from "node:path";
import assert from "node:assert/strict";
import { readGlb } from "../src/glb.js";
import { ARTIFACTS, browserTest, log, newSession, nextFrames, synced, until } from "./harness.mjs";

const SIZE = 24;
const RESPONSE = 0.5;
// The page asks the proxy to keep the pressure within 0.5 px of width interpolated in time
// (protocol.js WIDTH_TOLERANCE_PX), and the samples are on the codec's grid: 0.25 px more. The
// pen's events carry their times (straightStroke), so time and place agree along the line.
// (Without those times, each event's time was when it happened to be dispatched, which drifted
// from its place along the line: 1 px was passed by up to 0.06 px in 1 run of 4; with them the
// largest difference is 0.52 px. The defect this guards against stepped by 4.56 px.)
const WIDTH_SLACK_PX = 0.75;

/// A straight pen stroke along y = `y`, pressure `pressure(t)` for t in [0, 1].
async function straightStroke(cdp, { x0, x1, y, n, pressure, lift = true }) {
  const sent = [];
  // Every event carries its time, a tablet's 8 ms apart: the page's time base is the events'
  // (`timeStamp`), so the pen's time is proportional to x as the reference below assumes,
  // however late each event is dispatched.
  const start = Date.now() / 1000;
  const ev = (type, x, force, i) =>
    cdp.send("Input.dispatchMouseEvent", { type, x, y, force, timestamp: start + 0.008 * i, button: "left", buttons: type === "mouseReleased" ? 0 : 1, clickCount: 1, pointerType: "pen" });
  for (let i = 0; i <= n; i++) {
    const x = x0 + ((x1 - x0) * i) / n;
    const p = Math.round(pressure(i / n) * 1000) / 1000;
    await ev(i === 0 ? "mousePressed" : "mouseMoved", x, p, i);
    sent.push([x, p]);
  }
  if (lift) await ev("mouseReleased", x1, 0, n);
  return sent;
}

/// The rings of a straight mesh along x: its top-face vertices grouped by x (a ring's upper
/// and lower rim vertices share it), each ring's width the span of its y, in stroke units.
export function ringsOf(flat, xMin, xMax) {
  const byX = new Map();
  const { positions } = flat;
  for (let i = 0; i < positions.length; i += 3) {
    const [x, y, z] = [positions[i], positions[i + 1], positions[i + 2]];
    if (z <= 0 || x < xMin || x > xMax) continue;
    const key = Math.round(x * 100);
    const r = byX.get(key) || { x, lo: Infinity, hi: -Infinity };
    r.lo = Math.min(r.lo, y);
    r.hi = Math.max(r.hi, y);
    byX.set(key, r);
  }
  return [...byX.values()].filter((r) => r.hi > r.lo).sort((a, b) => a.x - b.x).map((r) => ({ x: r.x, width: r.hi - r.lo }));
}

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  await context.addInitScript((size) => sessionStorage.setItem("penmesh:brush", JSON.stringify({ size, pressure_response: 0.5, min_radius: 0.25, color: 0x2266dd })), SIZE);
  const page = await context.newPage();
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto(`${base}/s/${session}#token=${token}`);
  await synced(page);
  const cdp = await context.newCDPSession(page);
  const auth = { authorization: `Bearer ${token}` };

  const shapes = [
    { y: 150, pressure: (t) => 0.2 + 0.7 * Math.sin(Math.PI * t) },
    { y: 450, pressure: (t) => 0.55 + 0.35 * Math.sin(3 * Math.PI * t) },
  ];
  const measured = new Set();
  let worstMesh = 0;
  let worstPen = 0;
  let worstInk = 0;
  for (const [i, shape] of shapes.entries()) {
    // The first stroke's mesh build is held back a moment: its ink, then its mesh, on screen.
    let release = () => {};
    if (i === 0) {
      const held = new Promise((r) => (release = r));
      await page.route("**/mesh/build", async (route) => {
        await held;
        await route.continue();
      });
    }
    const sent = await straightStroke(cdp, { x0: 100, x1: 900, n: 120, ...shape });
    const clip = { x: 80, y: shape.y - 20, width: 440, height: 40 };
    if (i === 0) {
      await until("the stroke done", () => page.evaluate(() => !window.penmesh.pending));
      await page.screenshot({ path: join(ARTIFACTS, "width-ink.png"), clip });
      release();
      await page.unroute("**/mesh/build");
    }
    await until(`mesh ${i + 1}`, () => page.evaluate((w) => window.penmesh.meshes >= w && !window.penmesh.pending, i + 1));
    if (i === 0) {
      await until("the ink gone with the mesh", () => page.evaluate(() => window.penmesh.inked === 0));
      await nextFrames(page);
      await page.screenshot({ path: join(ARTIFACTS, "width-mesh.png"), clip });
    }
    const res = await fetch(`${base}/v1/sessions/${session}/strokes`, { headers: auth });
    const stroke = (await res.json()).strokes.find((st) => !measured.has(st.id));
    measured.add(stroke.id);
    const glb = await (await fetch(`${base}/v1/strokes/${stroke.id}/mesh`, { headers: auth })).arrayBuffer();
    const flat = await readGlb(glb);
    const rings = ringsOf(flat, 99.95, 900.05);
    if (process.env.DUMP) { const p = flat.positions; const pts = []; for (let j = 0; j < p.length; j += 3) pts.push([p[j], p[j+1], p[j+2]].map((v) => +v.toFixed(2))); console.log(JSON.stringify(pts.slice(0, 80))); }
    assert.ok(rings.length >= 2, `stroke ${i}: ${rings.length} rings`);
    // The pen's (and the ink's) width at x: linear between the samples sent.
    const penWidth = (x) => {
      let k = 0;
      while (k < sent.length - 2 && sent[k + 1][0] < x) k++;
      const [[xa, pa], [xb, pb]] = [sent[k], sent[k + 1]];
      return 2 * SIZE * RESPONSE * (pa + ((pb - pa) * (x - xa)) / (xb - xa));
    };
    for (let k = 1; k < rings.length; k++) {
      const [a, b] = [rings[k - 1], rings[k]];
      const meshStep = Math.abs(b.width - a.width);
      // How much the pen's width changed from ring to ring, sample to sample.
      const between = sent.filter(([x]) => x > a.x && x < b.x).map(([x]) => penWidth(x));
      const path = [a.x, ...between, b.x].map((v, j) => (j === 0 ? penWidth(a.x) : j === between.length + 1 ? penWidth(b.x) : v));
      const penStep = path.slice(1).reduce((sum, w, j) => sum + Math.abs(w - path[j]), 0);
      worstMesh = Math.max(worstMesh, meshStep);
      worstPen = Math.max(worstPen, penStep);
      assert.ok(meshStep <= penStep + WIDTH_SLACK_PX, `stroke ${i}: the mesh's width steps by ${meshStep.toFixed(2)} px between rings at x ${a.x.toFixed(1)} and ${b.x.toFixed(1)}, the pen's by ${penStep.toFixed(2)}`);
      // Between the rings the mesh's width is linear (its faces are flat): against the ink's at
      // every sample.
      for (const [x] of sent.filter(([x]) => x >= a.x && x <= b.x)) {
        const mesh = a.width + ((b.width - a.width) * (x - a.x)) / (b.x - a.x || 1);
        const ink = penWidth(x);
        worstInk = Math.max(worstInk, Math.abs(mesh - ink));
        assert.ok(Math.abs(mesh - ink) <= WIDTH_SLACK_PX, `stroke ${i}: the mesh is ${mesh.toFixed(2)} px wide at x ${x.toFixed(1)}, the ink ${ink.toFixed(2)}`);
      }
    }
    log(`stroke ${i}: ${rings.length} rings over 780 px`);
  }
  log(`largest width step between neighbouring rings: mesh ${worstMesh.toFixed(2)} px, pen ${worstPen.toFixed(2)} px; largest mesh-ink difference ${worstInk.toFixed(2)} px`);
});
