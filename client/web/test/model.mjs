// The browser test of the page as a modelling tool (issue 37, docs/web.md "How to model"): two
// pages of one session (Ada draws, Bob watches) and a late joiner, as a person drives them
// (Debian's Chromium, playwright-core, a pen through CDP, the mouse on the gizmo's handle).
// Ada draws a chair's seat on the board, picks the front plane, moves it to the seat's edge,
// orbits 60° and draws the back on it (the view kept), selects the back and moves it with the
// gizmo, duplicates it, undoes both, redoes both, mirrors the copy and moves it with snapping. At each step the placements the proxy stores are the page's, bit for
// bit, and Bob's strokes have the same world-space boxes as Ada's; the late joiner (the mesh
// bundle with placements, PMB2) too. Screenshots from two angles go to target/web-test/model-*.png.
// Run by scripts/test.sh as `node client/web/test/model.mjs`.
import { join } from "node:path";
import assert from "node:assert/strict";
import { ARTIFACTS, browserTest, log, newSession, nextFrames, openPage, polyline, selectForGizmo, sessionUrl, storedStrokes, strokeMiddle, until } from "./harness.mjs";

const IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
const FRONT = [1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1];
// Orbit: radians per CSS pixel dragged (camera.js ORBIT_PER_PX).
const ORBIT_PER_PX = 0.006;

/// Pixels drawn on the ink canvas in the 9x9 around page point (`x`, `y`).
const inkAround = (page, [x, y]) =>
  page.evaluate(([x, y]) => {
    const d = document.getElementById("ink").getContext("2d").getImageData(Math.round(x) - 4, Math.round(y) - 4, 9, 9).data;
    let n = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
    return n;
  }, [x, y]);
const placements = (page) => page.evaluate(() => window.penmesh.placements);
const boxes = (page) => page.evaluate(() => window.penmesh.boxes());
const orIdentity = (m) => m || IDENTITY;

/// The placements the proxy stores, by stroke (taken-back strokes left out).
async function stored(base, s) {
  return Object.fromEntries((await storedStrokes(base, s)).map((x) => [x.id, x.placement.matrix]));
}

/// The page's placements equal the proxy's, bit for bit, for every stroke the proxy lists.
function assertSamePlacements(page, server, what) {
  for (const [id, matrix] of Object.entries(server)) {
    assert.ok(id in page, `${what}: stroke ${id} is not on the page`);
    assert.deepEqual(orIdentity(page[id]), matrix, `${what}: stroke ${id}'s placement`);
  }
}

/// Two pages' boxes of the shown strokes agree (the same strokes, within float rounding).
function assertSameBoxes(a, b, what) {
  assert.deepEqual(Object.keys(a).sort(), Object.keys(b).sort(), `${what}: the strokes shown`);
  for (const id of Object.keys(a)) {
    for (const k of ["min", "max"]) {
      a[id][k].forEach((v, i) => assert.ok(Math.abs(v - b[id][k][i]) < 1e-3, `${what}: stroke ${id}'s box ${k}[${i}]: ${v} against ${b[id][k][i]}`));
    }
  }
}

/// Waits until Bob's boxes equal Ada's and both pages' placements are the proxy's.
async function agree(base, s, ada, bob, what) {
  await until(`${what}: Bob's page like Ada's`, async () => {
    const [a, b] = [await boxes(ada), await boxes(bob)];
    try {
      assertSameBoxes(a, b, what);
      return true;
    } catch {
      return false;
    }
  });
  assertSameBoxes(await boxes(ada), await boxes(bob), what);
  const server = await stored(base, s);
  assertSamePlacements(await placements(ada), server, `${what} (Ada)`);
  assertSamePlacements(await placements(bob), server, `${what} (Bob)`);
  return server;
}

/// Drags with the mouse from `from` to `to` in `steps`.
async function drag(page, [x0, y0], [x1, y1], steps = 10) {
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  await page.mouse.move(x1, y1, { steps });
  await page.mouse.up();
}

browserTest(async ({ proxy, browser }) => {
  const base = proxy.base;
  const s = await newSession(base);
  const url = sessionUrl(base, s);
  const ada = await openPage(browser, url, { name: "ada" });
  const bob = await openPage(browser, url, { name: "bob" });
  assert.equal(await ada.evaluate(() => Number(document.querySelector('meta[name="penmesh-protocol"]').content)), 6, "the page speaks protocol 6");

  // 1. The seat on the board.
  await polyline(ada.cdp, [[320, 200], [480, 200], [480, 320], [320, 320], [320, 205]]);
  await until("the seat", () => ada.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending));
  const [seat] = Object.keys(await placements(ada));
  assert.deepEqual((await stored(base, s))[seat], IDENTITY, "a stroke on the board has the identity");

  // 2. The front plane, moved to the seat's far edge (y = 200: Shift+[ four times, a grid cell
  //    each), seen from 60° above: the pen draws the back on it, and the view stays.
  //    (Front goes through the model's centre, (400, 260): moved 60 along its normal, typed.)
  await ada.locator("#plane").selectOption("front");
  const through = [...FRONT];
  [through[12], through[13]] = [400, 260];
  assert.deepEqual((await ada.evaluate(() => window.penmesh.workPlane)).placement, through, "the front plane through the model's centre");
  await ada.fill("#plane-offset", "60");
  await ada.press("#plane-offset", "Enter");
  const onEdge = [...through];
  onEdge[13] = 200;
  assert.deepEqual((await ada.evaluate(() => window.penmesh.workPlane)).placement, onEdge, "the front plane moved to y = 200");
  await ada.keyboard.press("o");
  const pitch = Math.PI / 3;
  // (A drag up tilts the view from above toward the front: camera.js, a turntable.)
  await drag(ada, [500, 200 + pitch / ORBIT_PER_PX], [500, 200], 12);
  const turned = await ada.evaluate(() => window.penmesh.camera);
  assert.ok(Math.abs(turned.pitch - pitch) < 0.01, `orbited to ${turned.pitch} rad, not 60°`);
  await ada.keyboard.press("Escape");
  await until("Esc back to drawing", () => ada.evaluate(() => window.penmesh.tool === "draw"));
  // The back: a U standing on the seat's edge, 140 units high (its plane's y is the height, its
  // x from the plane's origin at the seat's middle).
  const back = await ada.evaluate((corners) => corners.map(([x, y]) => window.penmesh.toPage(x, y)), [[-70, 5], [-70, 140], [70, 140], [70, 5]]);
  const inkBefore = await ada.evaluate(() => window.penmesh.inked);
  await polyline(ada.cdp, back, false);
  // While the pen is down, the ink shows the stroke where it is drawn on the plane: along its
  // first side, under the pen.
  assert.equal(await ada.evaluate(() => window.penmesh.inked), inkBefore + 1, "the back is on the ink while it is drawn");
  const side = [(back[0][0] + back[1][0]) / 2, (back[0][1] + back[1][1]) / 2];
  assert.ok((await inkAround(ada, side)) > 0, `no ink at ${side}, on the back's first side`);
  const last = back[back.length - 1];
  await ada.cdp.send("Input.dispatchMouseEvent", { type: "mouseReleased", x: last[0], y: last[1], button: "left", buttons: 0, clickCount: 1, pointerType: "pen" });
  await until("the back", () => ada.evaluate(() => window.penmesh.meshes === 2 && !window.penmesh.pending));
  const kept = await ada.evaluate(() => window.penmesh.camera);
  assert.deepEqual(kept, turned, "drawing kept the view");
  let server = await agree(base, s, ada, bob, "drawn on two planes");
  const front = Object.keys(server).find((id) => id !== seat);
  assert.deepEqual(server[front], onEdge, "the stroke drawn on the front plane carries its placement");
  // Drawn where the pen was: the stroke's first point is under the pen's first sample.
  const [fx, fy] = await ada.evaluate((id) => {
    const s = window.penmesh.strokes.get(id);
    return window.penmesh.toPage(s.points[0].x, s.points[0].y, s.placement);
  }, front);
  assert.ok(Math.hypot(fx - back[0][0], fy - back[0][1]) < 3, `the back begins at (${fx}, ${fy}), not under the pen (${back[0]})`);
  const backBox = (await boxes(ada))[front];
  assert.ok(Math.abs(backBox.min[1] - 200) < 10 && Math.abs(backBox.max[1] - 200) < 10 && backBox.max[2] > 130, `the back stands on the seat's edge: ${JSON.stringify(backBox)}`);
  await ada.screenshot({ path: join(ARTIFACTS, "model-1-two-planes.png") });

  // 3. Select (V) the back with a click, move it with the gizmo's X handle.
  await ada.keyboard.press("v");
  assert.equal(await ada.evaluate(() => window.penmesh.tool), "select");
  assert.equal(await ada.evaluate(() => getComputedStyle(document.getElementById("stage")).cursor), "default", "Select's cursor");
  // The wheel zooms in Select as in every tool (in, then out again about the same point).
  await ada.mouse.move(700, 500);
  await ada.mouse.wheel(0, -100);
  await until("zoomed in", async () => (await ada.evaluate(() => window.penmesh.camera.scale)) > turned.scale * 1.1);
  await ada.mouse.wheel(0, 100);
  await until("zoomed out", async () => Math.abs((await ada.evaluate(() => window.penmesh.camera.scale)) - turned.scale) < 1e-9);
  const handle = await selectForGizmo(ada, front);
  const before = await placements(ada);
  await drag(ada, handle, [handle[0] + 150, handle[1]], 15);
  const moved = (await placements(ada))[front];
  assert.ok(moved[12] > 400 + 50 && moved[13] === 200 && moved[14] === 0, `the gizmo's X handle moved the back along x: ${JSON.stringify(moved)}`);
  assert.deepEqual(moved.slice(0, 12), onEdge.slice(0, 12), "the move did not turn the back");
  server = await agree(base, s, ada, bob, "moved with the gizmo");
  assert.deepEqual(server[front], moved);

  // The work plane: the selected stroke's, then through three points clicked on its grid (the
  // same plane, another origin), then the front plane again.
  await ada.locator("#plane").selectOption("stroke");
  assert.deepEqual((await ada.evaluate(() => window.penmesh.workPlane)).placement, moved, "the stroke's plane");
  await ada.locator("#plane").selectOption("points");
  for (const p of [[200, 560], [400, 560], [300, 640]]) await ada.mouse.click(...p);
  const picked = await ada.evaluate(() => window.penmesh.workPlane);
  assert.equal(picked.kind, "points");
  // Its normal (third column) is the stroke plane's, up to its sign: the points were on it.
  const dot = picked.placement[8] * moved[8] + picked.placement[9] * moved[9] + picked.placement[10] * moved[10];
  assert.ok(Math.abs(Math.abs(dot) - 1) < 1e-6, `the plane through three points of the grid is the grid's (normal · normal = ${dot})`);
  await ada.locator("#plane").selectOption("front");
  await ada.mouse.click(...(await strokeMiddle(ada, front)));
  assert.deepEqual(await ada.evaluate(() => window.penmesh.selected), [front], "the moved back selected again");

  // 4. Duplicate (Ctrl+D): a new stroke of Ada's, offset, selected.
  await ada.keyboard.press("Control+d");
  await until("the copy on both pages", async () => Object.keys(await boxes(bob)).length === 3 && Object.keys(await boxes(ada)).length === 3);
  const copy = Object.keys(await boxes(ada)).find((id) => id !== seat && id !== front);
  const listed = (await storedStrokes(base, s)).find((x) => x.id === copy);
  assert.equal(listed.duplicate_of, front, "the copy records its source");
  await until("the copy selected", async () => (await ada.evaluate(() => window.penmesh.selected)).includes(copy));
  server = await agree(base, s, ada, bob, "duplicated");

  // 5. Undo the duplicate, then the move: the exact placement before it.
  await ada.keyboard.press("Control+z");
  await until("the copy taken back", async () => !(copy in (await stored(base, s))) && !(copy in (await boxes(bob))));
  await until("the copy, taken back, no longer selected", async () => (await ada.evaluate(() => window.penmesh.selected)).length === 0);
  await ada.keyboard.press("Control+z");
  await until("the move undone", async () => (await stored(base, s))[front].every((v, i) => v === orIdentity(before[front])[i]));
  server = await agree(base, s, ada, bob, "the move undone");
  const history = await (await fetch(`${base}/v1/strokes/${front}/placements`, { headers: { authorization: `Bearer ${s.token}` } })).json();
  assert.deepEqual(history.placements.map((p) => p.cause), ["begin", "set", "set"], "the move and its undo, nothing overwritten");
  assert.deepEqual(history.placements[2].placement.matrix, history.placements[0].placement.matrix, "undo restored the placement exactly");

  // 6. Redo both, then mirror the copy (selected by a box around it).
  await ada.keyboard.press("Control+Shift+z");
  await until("the move again", async () => (await stored(base, s))[front].every((v, i) => v === moved[i]));
  await ada.keyboard.press("Control+Shift+z");
  await until("the copy back", async () => copy in (await stored(base, s)) && copy in (await boxes(bob)));
  server = await agree(base, s, ada, bob, "redone");
  await ada.keyboard.press("Escape");
  assert.equal(await ada.evaluate(() => window.penmesh.tool), "draw", "Esc goes back to drawing");
  assert.deepEqual(await ada.evaluate(() => window.penmesh.selected), [], "leaving Select lets go of the selection");
  await ada.keyboard.press("v");
  const copyPage = await ada.evaluate((id) => {
    const s = window.penmesh.strokes.get(id);
    return s.points.map((p) => window.penmesh.toPage(p.x, p.y, s.placement));
  }, copy);
  const xs = copyPage.map((p) => p[0]);
  const ys = copyPage.map((p) => p[1]);
  await drag(ada, [Math.min(...xs) - 15, Math.min(...ys) - 15], [Math.max(...xs) + 15, Math.max(...ys) + 15]);
  assert.ok((await ada.evaluate(() => window.penmesh.selected)).includes(copy), "the box selected the copy");
  await ada.locator("#mirror").click();
  await until("the copy mirrored", async () => {
    const m = (await stored(base, s))[copy];
    return m[0] < 0;
  });
  server = await agree(base, s, ada, bob, "mirrored");

  // Snap (S): a drag of the X handle puts the selection's low edge on the 10-unit grid (snap by
  // the bounds, issue 50).
  await ada.keyboard.press("s");
  assert.equal(await ada.locator("#snap").getAttribute("aria-pressed"), "true");
  const snapHandle = await ada.evaluate(() => window.penmesh.gizmoHandle("X"));
  await drag(ada, snapHandle, [snapHandle[0] + 37, snapHandle[1]], 8);
  await until("the snapped move stored", async () => (await stored(base, s))[copy][12] !== server[copy][12]);
  server = await agree(base, s, ada, bob, "moved with snapping");
  const lowX = await ada.evaluate(() => window.penmesh.selectionBounds().min[0]);
  assert.ok(Math.abs(lowX / 10 - Math.round(lowX / 10)) < 1e-3, `snapped, the selection's low edge is at x = ${lowX}, not on the 10-unit grid`);

  // Turn (R) with Snap: a drag along the Z ring turns the copy about z by a multiple of 15°.
  await ada.keyboard.press("r");
  const ring = await ada.evaluate(() => window.penmesh.gizmoHandle("Z"));
  const unturned = server[copy];
  await drag(ada, ring, [ring[0] - 50, ring[1] - 30], 12);
  await until("the turn stored", async () => (await stored(base, s))[copy][0] !== unturned[0]);
  server = await agree(base, s, ada, bob, "turned with snapping");
  // The turn about z: the angle between the copy's x axis before and after, in x-y.
  const turnedBy = Math.atan2(server[copy][1], server[copy][0]) - Math.atan2(unturned[1], unturned[0]);
  const steps = turnedBy / (Math.PI / 12);
  assert.ok(Math.abs(steps) >= 0.5 && Math.abs(steps - Math.round(steps)) < 1e-6, `turned by ${(turnedBy * 180) / Math.PI}°, not a multiple of 15°`);
  assert.ok(Math.abs(server[copy][2] - unturned[2]) < 1e-9, "the turn was about z only");

  // Bob cannot move Ada's stroke: the proxy refuses, the stroke goes back on his page, nothing
  // changes anywhere.
  const refused = [...server[seat]];
  refused[12] += 100;
  await bob.evaluate(([id, m]) => window.penmesh.place(id, m), [seat, refused]);
  await until("Bob's page puts the seat back", async () => (await placements(bob))[seat]?.[12] === server[seat][12]);
  assert.deepEqual(await stored(base, s), server, "Bob's refused move changed nothing");
  await agree(base, s, ada, bob, "a refused move");

  // 7. A late joiner: the mesh bundle with placements and the history's peer_placement.
  const cid = await openPage(browser, url, { name: "cid" });
  await until("Cid's meshes", async () => Object.keys(await boxes(cid)).length === Object.keys(await boxes(ada)).length);
  assertSameBoxes(await boxes(ada), await boxes(cid), "the late joiner");
  assertSamePlacements(await placements(cid), server, "the late joiner");

  // Two angles (Bob's page): as he sees it, and turned.
  await bob.bringToFront();
  await bob.keyboard.press("f");
  await bob.keyboard.press("o");
  await drag(bob, [500, 300], [500 - 0.5 / ORBIT_PER_PX, 300 + 1.0 / ORBIT_PER_PX], 12);
  await nextFrames(bob);
  await bob.screenshot({ path: join(ARTIFACTS, "model-2-bob-turned.png") });
  await drag(bob, [500, 300], [500 + 1.2 / ORBIT_PER_PX, 300 - 0.4 / ORBIT_PER_PX], 12);
  await nextFrames(bob);
  await bob.screenshot({ path: join(ARTIFACTS, "model-3-bob-other-side.png") });
  log("the model agrees on every page and the proxy");
});
