// The camera keeps "up" (issue 50; docs/web.md "The view"): a model of a flat L on the board
// and a stroke standing on the Front plane, then, through the page's own UI:
// 1. an orbit drag up tilts the view and a sideways drag of 240 px turns it about the up axis:
//    the up axis stays vertical on screen (the session's z projected at the point looked at:
//    no roll), the standing stroke's top above its foot; a drag far
//    past the top stops at the view from above (no flip over the pole);
// 2. each view button (and its number key) shows the model from its side: Top (1) the board as
//    the page draws it (x right, y down), Front (2) the board edge-on and the standing stroke
//    upright, Side (3) seen along x (the L's x run collapses, up stays up), 3D (4) the board
//    spread and up vertical; the button of the view shown is pressed;
// 3. the wheel zooms toward the pointer: the point under it stays under it;
// 4. the ground's grid shows from a turned view (pixels of the grid off the model).
// Screenshots of each view go to target/web-test/camera-*.png.
// Run by scripts/test.sh as `node client/web/test/camera.mjs`.
import assert from "node:assert/strict";
import { join } from "node:path";
import { ARTIFACTS, VIEW, browserTest, isBackground, log, newSession, openPage, pixelsAt, polyline, sessionUrl, until } from "./harness.mjs";

async function drag(page, [x0, y0], [x1, y1], steps = 12) {
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  await page.mouse.move(x1, y1, { steps });
  await page.mouse.up();
}

/// Where session points are on the page now.
const onPage = (page, points) => page.evaluate((points) => points.map(([x, y, z]) => window.penmesh.view.rig.toPage(x, y, z)), points);

/// The screen direction of the up axis (session +z) at session point `p`: [dx, dy] per unit.
async function upOnScreen(page, [x, y, z]) {
  const [[ax, ay], [bx, by]] = await onPage(page, [[x, y, z], [x, y, z + 100]]);
  return [(bx - ax) / 100, (by - ay) / 100];
}

function assertUpVertical(up, what) {
  assert.ok(up[1] < 0, `${what}: up points up the screen: ${up}`);
  assert.ok(Math.abs(up[0]) < 1e-6 * Math.abs(up[1]) + 1e-9, `${what}: up leans sideways on screen: ${up}`);
}

const pressedView = (page) => page.evaluate(() => [...document.querySelectorAll("[data-view]")].filter((b) => b.getAttribute("aria-pressed") === "true").map((b) => b.dataset.view));

browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const s = await newSession(base);
  const page = await openPage(browser, sessionUrl(base, s));
  const cdp = page.cdp;

  // The model: an L on the board (its long arm along x), and a stroke up the Front plane.
  await polyline(cdp, [[300, 200], [300, 400], [600, 400]]);
  await until("the L", () => page.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending));
  await page.locator("#plane").selectOption("front");
  await page.keyboard.press("4");
  const plane = (await page.evaluate(() => window.penmesh.workPlane)).placement;
  // (The plane goes through the L's centre: its own x from there; its y is the height.)
  const up = await page.evaluate((plane) => [[700 - plane[12], 0], [700 - plane[12], 150]].map(([x, y]) => window.penmesh.toPage(x, y, plane)), plane);
  await polyline(cdp, up);
  await until("the standing stroke", () => page.evaluate(() => window.penmesh.meshes === 2 && !window.penmesh.pending));
  await page.locator("#plane").selectOption("board");
  // Its foot and top in session coordinates (the Front plane takes its y to z).
  const [foot, top] = [[700, plane[13], 0], [700, plane[13], 150]];

  // 1. The orbit: from above, a drag up tilts, a sideways drag turns about up.
  await page.keyboard.press("1");
  await page.keyboard.press("o");
  await drag(page, [500, 500], [500, 300]);
  let camera = await page.evaluate(() => window.penmesh.camera);
  assert.ok(Math.abs(camera.pitch - 200 * 0.006) < 0.02, `a drag up of 200 px tilts by 1.2 rad: ${camera.pitch}`);
  await drag(page, [300, 350], [540, 350]);
  camera = await page.evaluate(() => window.penmesh.camera);
  assert.ok(Math.abs(Math.abs(camera.yaw) - 240 * 0.006) < 0.02, `a sideways drag of 240 px turns by 1.44 rad: ${camera.yaw}`);
  assert.ok(Math.abs(camera.pitch - 1.2) < 0.02, `the sideways drag did not tilt: ${camera.pitch}`);
  const target = [camera.x, camera.y, camera.z];
  assertUpVertical(await upOnScreen(page, target), "after a sideways drag, at the target");
  // (Off the centre, perspective leans verticals toward their vanishing point: not a roll.)
  const [f, t] = await onPage(page, [foot, top]);
  assert.ok(t[1] < f[1] - 50, `the standing stroke's top above its foot on screen: foot ${f}, top ${t}`);
  await page.screenshot({ path: join(ARTIFACTS, "camera-orbited.png") });
  // 4. The ground's grid: from this turned view, some pixels of the grid in an empty corner.
  const corner = [];
  for (let x = 20; x < 300; x += 7) for (let y = 480; y < 640; y += 7) corner.push([x, y]);
  const off = await onPage(page, [[300, 200, 0], [600, 400, 0], foot, top]);
  const far = corner.filter(([x, y]) => off.every(([a, b]) => Math.hypot(a - x, b - y) > 60));
  const gridPixels = (await pixelsAt(page, far, join(ARTIFACTS, "camera-orbited-gl.png"))).filter((px) => !isBackground(px)).length;
  assert.ok(gridPixels > 0, "the ground's grid shows in a turned view");
  // Dragged far down: it stops at the view from above, never past it.
  await drag(page, [500, 100], [500, 650], 20);
  camera = await page.evaluate(() => window.penmesh.camera);
  assert.equal(camera.pitch, 0, "a drag far down stops at the view from above");
  await page.keyboard.press("Escape");

  // 2. The named views, by button and by key: the screen direction of each session axis at the
  //    point looked at (x and y on the board, z up).
  const axesOnScreen = async () => {
    const c = await page.evaluate(() => window.penmesh.camera);
    const p = [c.x, c.y, c.z];
    const [o, x, y, z] = await onPage(page, [p, [p[0] + 1, p[1], p[2]], [p[0], p[1] + 1, p[2]], [p[0], p[1], p[2] + 1]]);
    return { x: [x[0] - o[0], x[1] - o[1]], y: [y[0] - o[0], y[1] - o[1]], z: [z[0] - o[0], z[1] - o[1]] };
  };
  const along = (v, [dx, dy], what) => {
    const [n, m] = [Math.hypot(...v), Math.hypot(dx, dy)];
    assert.ok(n > 1e-3 && (v[0] * dx + v[1] * dy) / (n * m) > 0.999, `${what}: ${v} is not along ${[dx, dy]}`);
  };
  const checks = {
    top: async () => {
      const a = await axesOnScreen();
      along(a.x, [1, 0], "Top: x runs right");
      along(a.y, [0, 1], "Top: y runs down the screen, as on the page");
    },
    front: async () => {
      const a = await axesOnScreen();
      along(a.x, [1, 0], "Front: x runs right");
      along(a.z, [0, -1], "Front: up is up");
      assert.ok(Math.hypot(...a.y) < 0.01 * Math.hypot(...a.x), `Front: y runs away from the camera: ${a.y}`);
    },
    side: async () => {
      const a = await axesOnScreen();
      along(a.y, [-1, 0], "Side (from the right): the board's y (toward its front) runs left");
      along(a.z, [0, -1], "Side: up is up");
      assert.ok(Math.hypot(...a.x) < 0.01 * Math.hypot(...a.y), `Side: x runs away from the camera: ${a.x}`);
    },
    three: async () => {
      const a = await axesOnScreen();
      along(a.z, [0, -1], "3D: up is up");
      assert.ok(a.x[0] > 0.3 * Math.hypot(...a.x) && Math.hypot(...a.y) > 0.2 * Math.hypot(...a.x), `3D: the board spread: x ${a.x}, y ${a.y}`);
    },
  };
  const keys = { top: "1", front: "2", side: "3", three: "4" };
  for (const [name, check] of Object.entries(checks)) {
    await page.click(`#view-${name}`);
    assert.deepEqual(await pressedView(page), [name], `the ${name} button pressed`);
    await check();
    // The whole model in sight.
    for (const [x, y] of await onPage(page, [[300, 200, 0], [300, 400, 0], [600, 400, 0], foot, top])) assert.ok(x > 0 && x < VIEW.width && y > 0 && y < VIEW.height, `${name}: the model in sight (${x}, ${y})`);
    await page.screenshot({ path: join(ARTIFACTS, `camera-${name}.png`) });
    await page.click("#view-top").then(() => page.keyboard.press(keys[name]));
    assert.deepEqual(await pressedView(page), [name], `key ${keys[name]}: the ${name} view`);
    await check();
  }

  // 3. Zoom toward the pointer, in the 3D view: the point under the pointer stays.
  await page.keyboard.press("4");
  const [px, py] = (await onPage(page, [[600, 400, 0]]))[0];
  await page.mouse.move(px, py);
  const scale0 = (await page.evaluate(() => window.penmesh.camera)).scale;
  await page.mouse.wheel(0, -300);
  await until("zoomed in", async () => (await page.evaluate(() => window.penmesh.camera.scale)) > scale0 * 1.5);
  const [qx, qy] = (await onPage(page, [[600, 400, 0]]))[0];
  assert.ok(Math.hypot(qx - px, qy - py) < 2, `the L's corner stays under the pointer: (${px}, ${py}) -> (${qx}, ${qy})`);
  assert.deepEqual(await pressedView(page), ["three"], "a zoom keeps the view's direction");
  log("the camera keeps up: orbit, views by button and key, zoom to the pointer, the ground shown");
});
