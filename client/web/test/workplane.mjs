// The work plane at the model and the small traps of issue 50, through the page's own UI (Ada
// works, Bob draws one stroke):
// 1. the Plane tool (W) on the ground: Front next goes through the point clicked;
// 2. Front through the selection's centre, its offset typed, `]` away from the camera and `[`
//    toward it (seen from the front); a stroke drawn on it carries its placement;
// 3. the Plane tool on that stroke: the work plane is the stroke's;
// 4. the eraser rubs the standing stroke from a 3D view, the work plane being the board;
// 5. a handle's drag shows its distance beside the gizmo; arrow keys nudge the selection
//    (Shift: ten times), each one undo step;
// 6. Ada copies Bob's stroke: her dot in the people list keeps her colour.
// Run by scripts/test.sh as `node client/web/test/workplane.mjs`.
import assert from "node:assert/strict";
import { join } from "node:path";
import { ARTIFACTS, adaAndBob, browserTest, log, polyline, storedStrokes, until } from "./harness.mjs";

const plane = (page) => page.evaluate(() => window.penmesh.workPlane);
const stored = async (base, s) => Object.fromEntries((await storedStrokes(base, s)).map((x) => [x.id, x.placement.matrix]));
const myDot = (page) => page.evaluate(() => [...document.querySelectorAll("#people li")].find((li) => li.textContent.endsWith("(you)")).style.getPropertyValue("--c"));

browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { s, ada, bob } = await adaAndBob(browser, base);
  await polyline(ada.cdp, [[300, 250], [500, 250], [500, 450], [300, 450], [300, 255]]);
  await until("the square", () => ada.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending));
  const [square] = Object.keys(await stored(base, s));

  // 1. The Plane tool on the ground, then Front: through the point clicked.
  await ada.keyboard.press("w");
  assert.equal(await ada.evaluate(() => window.penmesh.tool), "plane");
  await ada.mouse.click(700, 550);
  assert.equal(await ada.evaluate(() => window.penmesh.tool), "draw", "a click of the Plane tool goes back to drawing");
  assert.equal((await plane(ada)).kind, "board");
  await ada.locator("#plane").selectOption("front");
  let p = (await plane(ada)).placement;
  assert.ok(Math.abs(p[12] - 700) < 1e-6 && Math.abs(p[13] - 550) < 1e-6, `Front goes through the ground's point clicked: ${p}`);

  // 2. Front through the selection's centre; its offset typed; ] away from the camera.
  await ada.keyboard.press("v");
  await ada.mouse.click(300, 350);
  assert.deepEqual(await ada.evaluate(() => window.penmesh.selected), [square]);
  await ada.locator("#plane").selectOption("side");
  await ada.locator("#plane").selectOption("front");
  p = (await plane(ada)).placement;
  assert.ok(Math.abs(p[12] - 400) < 1e-6 && Math.abs(p[13] - 350) < 1e-6, `Front goes through the selection's centre: ${p}`);
  await ada.fill("#plane-offset", "100");
  await ada.press("#plane-offset", "Enter");
  p = (await plane(ada)).placement;
  assert.ok(Math.abs(p[13] - 250) < 1e-6, `the typed offset puts it 100 along its normal (y = 250): ${p}`);
  assert.equal(await ada.inputValue("#plane-offset"), "100", "the offset shown");
  await ada.keyboard.press("Escape"); // drawing again (the selection let go)
  await ada.keyboard.press("2"); // the front view: the camera south of the model
  await ada.keyboard.press("BracketRight");
  assert.ok(Math.abs((await plane(ada)).placement[13] - 240) < 1e-6, "] moves it away from the camera (north, y down)");
  await ada.keyboard.press("BracketLeft");
  await ada.keyboard.press("BracketLeft");
  assert.ok(Math.abs((await plane(ada)).placement[13] - 260) < 1e-6, "[ moves it toward the camera");
  const drawnOn = (await plane(ada)).placement;
  // A stroke up the plane, seen from the front.
  const up = await ada.evaluate((m) => [[0, 20], [0, 180]].map(([x, y]) => window.penmesh.toPage(x, y, m)), drawnOn);
  await polyline(ada.cdp, up);
  await until("the standing stroke", () => ada.evaluate(() => window.penmesh.meshes === 2 && !window.penmesh.pending));
  const standing = Object.keys(await stored(base, s)).find((id) => id !== square);
  assert.deepEqual((await stored(base, s))[standing], drawnOn, "the stroke carries the work plane's placement");
  await ada.screenshot({ path: join(ARTIFACTS, "workplane-front.png") });

  // 3. The Plane tool on the stroke: its plane.
  await ada.locator("#plane").selectOption("board");
  await ada.keyboard.press("w");
  const middle = await ada.evaluate((m) => window.penmesh.toPage(0, 100, m), drawnOn);
  await ada.mouse.click(...middle);
  assert.equal((await plane(ada)).kind, "stroke");
  assert.deepEqual((await plane(ada)).placement, drawnOn, "the Plane tool put the work plane on the stroke's plane");

  // 4. The eraser from a 3D view, the work plane being the board: the standing stroke goes.
  await ada.locator("#plane").selectOption("board");
  await ada.keyboard.press("4");
  const [a, b] = await ada.evaluate((m) => [window.penmesh.toPage(-30, 100, m), window.penmesh.toPage(30, 100, m)], drawnOn);
  await ada.keyboard.press("e");
  await ada.mouse.move(...a);
  await ada.mouse.down();
  await ada.mouse.move(...b, { steps: 10 });
  await ada.mouse.up();
  await until("the standing stroke erased", async () => !(standing in (await stored(base, s))));
  assert.ok(square in (await stored(base, s)), "only what was under the eraser");

  // 5. Arrows nudge the selection along the work plane's x and y; Shift ten times; one undo each.
  await ada.keyboard.press("1"); // (the view from above, fitted: aimed through the page's projection)
  await ada.keyboard.press("v");
  await ada.mouse.click(...(await ada.evaluate(() => window.penmesh.toPage(300, 350, null))));
  assert.deepEqual(await ada.evaluate(() => window.penmesh.selected), [square]);
  // While a handle is dragged, the distance shows beside the gizmo (px and the print's mm).
  const handle = await ada.evaluate(() => window.penmesh.gizmoHandle("X"));
  await ada.mouse.move(...handle);
  await ada.mouse.down();
  await ada.mouse.move(handle[0] + 40, handle[1], { steps: 5 });
  const readout = await ada.evaluate(() => { const el = document.getElementById("gizmo-readout"); return el && el.style.display !== "none" ? el.textContent : null; });
  assert.match(readout || "", /^\d+(\.\d)? px · \d+(\.\d)? mm$/, `the drag's distance beside the gizmo: ${readout}`);
  await ada.mouse.move(...handle, { steps: 5 }); // back where it was: no move
  await ada.mouse.up();
  assert.equal(await ada.evaluate(() => document.getElementById("gizmo-readout").style.display), "none", "the readout goes with the drag");
  await until("the readout's drag stored, if it moved at all", async () => !(await ada.evaluate(() => window.penmesh.pending)));
  const m0 = await ada.evaluate((id) => window.penmesh.placements[id] || [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], square);
  const near = (a, b) => Math.abs(a - b) < 1e-6;
  await ada.keyboard.press("ArrowRight");
  await ada.keyboard.press("Shift+ArrowDown");
  await until("nudged", async () => {
    const m = (await stored(base, s))[square];
    return near(m[12], m0[12] + 1) && near(m[13], m0[13] + 10);
  });
  await ada.keyboard.press("Control+z");
  await until("one nudge undone", async () => near((await stored(base, s))[square][13], m0[13]));
  assert.ok(near((await stored(base, s))[square][12], m0[12] + 1), "the other nudge stays");

  // 6. Bob draws; Ada copies his stroke: her dot keeps her colour.
  await bob.bringToFront();
  await polyline(bob.cdp, [[600, 150], [800, 150]]);
  await until("Bob's stroke on Ada's page", () => ada.evaluate(() => window.penmesh.meshes === 3));
  await ada.bringToFront();
  const before = await myDot(ada);
  const bobs = Object.keys(await stored(base, s)).find((id) => id !== square);
  await ada.mouse.click(...(await ada.evaluate(() => window.penmesh.toPage(700, 150, null))));
  assert.deepEqual(await ada.evaluate(() => window.penmesh.selected), [bobs]);
  await ada.keyboard.press("Control+d");
  await until("the copy", async () => Object.keys(await stored(base, s)).length === 3);
  await until("the copy shown", () => ada.evaluate(() => window.penmesh.meshes === 4));
  assert.equal(await myDot(ada), before, "Ada's dot keeps her colour after copying Bob's stroke");
  log("the work plane goes where it is put; erase, nudge and the people list hold");
});
