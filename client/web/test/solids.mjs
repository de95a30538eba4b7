// Solids on the page (issue 51), from user actions only (pen strokes, clicks, typed numbers,
// keys; the page is read only to wait for it). Ada draws; Bob watches on a second page.
// 1. A closed square drawn with the pen, made Filled in the selection's panel and given a depth
//    typed in px: the proxy stores the solid, and Bob's page shows the plate live (its middle,
//    empty before, is covered: read from a screenshot).
// 2. Undo and redo of the two solid changes: the proxy's solid and Bob's pixels follow each.
// 3. A small closed square drawn as a Hole directly (the choice beside the brush): stored with
//    its begin, and shown on both pages as a hole (see-through grey over the plate).
// 4. Bob reloads: the plate and the hole are as before.
// 5. An open stroke made Filled is refused in the proxy's words, shown to Ada; nothing changes
//    (the proxy's solid, and the history: the next undo takes the open stroke back).
// 6. The STL through the Export menu: PrusaSlicer reads one manifold part with the hole cut out,
//    as thick as the panel said in mm.
// 7. A depth typed in mm (issue 51): the print that the Export menu makes is that thick; at
//    another size in the Export menu, the panel's mm follow it, and so does the print.
// Screenshots: target/web-test/solids-*.png. Run by scripts/test.sh as
// `node client/web/test/solids.mjs`.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { join } from "node:path";
import { ARTIFACTS, adaAndBob, browserTest, isBackground, log, pixelsAt, polyline, storedStrokes, synced, until } from "./harness.mjs";

// The plate, in page pixels (one unit of the board each at the page's first view).
const [X0, X1, Y0, Y1] = [300, 500, 250, 450];
// The hole: a small square inside the plate.
const [H0, H1, K0, K1] = [400, 440, 330, 370];
const HOLE_MIDDLE = [(H0 + H1) / 2, (K0 + K1) / 2];
const PLATE_INSIDE = [340, 290]; // inside the plate, away from its ink and the hole
const PLATE_DEPTH = 20; // px: the hole's default depth (24) goes through it
const ROD = { kind: "line", depth: null };
// A depth typed in the print's mm, and half the Export menu's default size.
const TYPED_MM = 6;
const HALF_MM = 50;
// How far the print's thickness may be from the panel's mm: the panel rounds to 0.1 mm.
const MM_TOLERANCE = 0.06;

const square = (x0, x1, y0, y1) => [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]];

/// The proxy's shown strokes: id -> solid.
async function solids(base, s) {
  return Object.fromEntries((await storedStrokes(base, s)).map((x) => [x.id, x.solid]));
}

/// The triangles of a stroke's stored mesh (GET /v1/strokes/{id}/mesh).
async function meshTriangles(base, s, stroke) {
  const res = await fetch(`${base}/v1/strokes/${stroke}/mesh`, { headers: { authorization: `Bearer ${s.token}` } });
  assert.equal(res.status, 200);
  await res.arrayBuffer();
  return Number(res.headers.get("x-penmesh-triangles"));
}

const sameSolid = (a, b) => a.kind === b.kind && a.depth === b.depth;

/// Waits until the proxy has `want` (id -> solid) for every stroke it shows.
async function stored(base, s, want, what) {
  await until(`${what}: the proxy's solids`, async () => {
    const got = await solids(base, s);
    return Object.keys(got).length === Object.keys(want).length && Object.entries(want).every(([id, solid]) => got[id] && sameSolid(got[id], solid)) ? got : false;
  });
}

/// The colours of `page`'s canvas at the plate's inside and the hole's middle (points of the
/// board: where the page shows them is asked, as a reload fits the view to the drawing), from a
/// screenshot.
async function look(page, file) {
  const at = await page.evaluate((points) => points.map(([x, y]) => window.penmesh.toPage(x, y, null)), [PLATE_INSIDE, HOLE_MIDDLE]);
  const [plate, hole] = await pixelsAt(page, at, join(ARTIFACTS, file));
  return { plate, hole };
}

const differ = (a, b) => Math.abs(a[0] - b[0]) + Math.abs(a[1] - b[1]) + Math.abs(a[2] - b[2]) >= 30;

/// Waits until `page` shows the plate filled (or, `filled` false, its inside empty) with no
/// mesh being replaced: checked on screen.
async function showsPlate(page, filled, file, what) {
  return until(`${what}: the plate ${filled ? "filled" : "empty"} on the page`, async () => {
    const seen = await look(page, file);
    return isBackground(seen.plate) !== filled ? seen : false;
  });
}

browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { s, ada, bob } = await adaAndBob(browser, base);

  // --- 1. a closed square, Filled, its depth typed -----------------------------------------
  await polyline(ada.cdp, square(X0, X1, Y0, Y1));
  await until("the square's mesh on both pages", async () => (await ada.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending)) && (await bob.evaluate(() => window.penmesh.meshes === 1)));
  const [plate] = Object.keys(await solids(base, s));
  await stored(base, s, { [plate]: ROD }, "a stroke is the rod");
  const rodTriangles = await meshTriangles(base, s, plate);
  await showsPlate(bob, false, "solids-0-rod.png", "the rod");
  await ada.keyboard.press("v");
  await ada.mouse.click(X0, (Y0 + Y1) / 2);
  await until("the square selected", async () => JSON.stringify(await ada.evaluate(() => window.penmesh.selected)) === JSON.stringify([plate]));
  assert.ok(await ada.isVisible("#selection-solid"), "the selection's panel has a solid row");
  assert.equal(await ada.getAttribute("#solid-line", "aria-pressed"), "true", "the row says the stroke is a line");
  await ada.click("#solid-filled");
  await stored(base, s, { [plate]: { kind: "filled", depth: 24 } }, "Filled");
  await until("the row says Filled", async () => (await ada.getAttribute("#solid-filled", "aria-pressed")) === "true");
  await ada.fill("#selection-solid-depth", String(PLATE_DEPTH));
  await ada.press("#selection-solid-depth", "Enter");
  const filled = { kind: "filled", depth: PLATE_DEPTH };
  await stored(base, s, { [plate]: filled }, "the depth typed");
  await showsPlate(bob, true, "solids-1-bob-filled.png", "Filled, live on Bob's page");
  await showsPlate(ada, true, "solids-1-ada-filled.png", "Filled on Ada's page");
  // The panel's mm are read once Ada's page knows the typed depth as stored (its peer_solid,
  // which may come after the proxy's strokes list has it): until then they are the last
  // depth's (24 px, the default of Filled), as a person would see for that moment.
  await until("Ada's page knows the depth typed", () =>
    ada.evaluate(([id, depth]) => window.penmesh.strokes.get(id).solid?.depth === depth, [plate, PLATE_DEPTH]),
  );
  const mm = Number(await ada.inputValue("#selection-solid-depth-mm"));
  assert.ok(mm > 0, `the depth in the print's mm: ${mm}`);
  log(`the square filled ${PLATE_DEPTH} px deep (${mm} mm of the print); Bob's page shows the plate`);

  // --- 2. undo and redo of the solid, two steps each --------------------------------------------
  await ada.keyboard.press("Control+z");
  await stored(base, s, { [plate]: { kind: "filled", depth: 24 } }, "the depth undone");
  await ada.keyboard.press("Control+z");
  await stored(base, s, { [plate]: ROD }, "Filled undone");
  // The proxy stores the rod's mesh again (the page shows what it stores).
  await until("the proxy's mesh the rod's again", async () => (await meshTriangles(base, s, plate)) === rodTriangles);
  await showsPlate(bob, false, "solids-2-bob-undone.png", "Filled undone, on Bob's page");
  await ada.keyboard.press("Control+Shift+z");
  await stored(base, s, { [plate]: { kind: "filled", depth: 24 } }, "Filled redone");
  await ada.keyboard.press("Control+Shift+z");
  await stored(base, s, { [plate]: filled }, "the depth redone");
  await showsPlate(bob, true, "solids-2-bob-redone.png", "redone, on Bob's page");
  log("undo and redo of Filled and of its depth: the proxy and Bob's page followed each");

  // --- 3. a hole drawn as a hole --------------------------------------------------------------
  await ada.keyboard.press("Escape");
  await ada.click("#tool-draw");
  await ada.selectOption("#draw-solid", "hole");
  const plateSeen = await look(bob, "solids-3-before-hole.png");
  await polyline(ada.cdp, square(H0, H1, K0, K1));
  const hole = await until("the hole stored", async () => Object.keys(await solids(base, s)).find((id) => id !== plate));
  const holeSolid = { kind: "hole", depth: 24 };
  await stored(base, s, { [plate]: filled, [hole]: holeSolid }, "the hole drawn as one");
  for (const [page, name] of [[bob, "bob"], [ada, "ada"]]) {
    await until(`the hole on ${name}'s page`, async () => {
      const seen = await look(page, `solids-3-${name}-hole.png`);
      // Over the plate, another colour than the plate's; the plate around it as it was.
      return !isBackground(seen.hole) && differ(seen.hole, plateSeen.plate) && !isBackground(seen.plate);
    });
  }
  log("the hole, drawn as one, shows on both pages over the plate");

  // --- 4. a reload keeps both ------------------------------------------------------------------
  const beforeReload = await look(bob, "solids-4-before-reload.png");
  await bob.reload();
  await synced(bob);
  await until("Bob's meshes after the reload", () => bob.evaluate(() => window.penmesh.meshes === 2));
  await until("the plate and the hole after Bob's reload", async () => {
    const seen = await look(bob, "solids-4-bob-reloaded.png");
    return !differ(seen.plate, beforeReload.plate) && !differ(seen.hole, beforeReload.hole);
  });
  log("after a reload, Bob's page shows the plate and the hole as before");

  // --- 5. an open stroke made Filled is refused in words ---------------------------------------
  await ada.selectOption("#draw-solid", "line");
  await polyline(ada.cdp, [[600, 250], [750, 250], [750, 400]]);
  const open = await until("the open stroke stored", async () => Object.keys(await solids(base, s)).find((id) => id !== plate && id !== hole));
  await until("the open stroke's mesh", () => ada.evaluate(() => window.penmesh.meshes === 3 && !window.penmesh.pending));
  await ada.keyboard.press("v");
  await ada.mouse.click(675, 250);
  await until("the open stroke selected", async () => JSON.stringify(await ada.evaluate(() => window.penmesh.selected)) === JSON.stringify([open]));
  await ada.click("#solid-filled");
  const said = await until("the refusal said on screen", async () => {
    const [text, shown] = await ada.$eval("#notice", (n) => [n.textContent, n.classList.contains("shown")]);
    if (!shown || !/cannot make it filled: .*an open stroke cannot be filled: its ends are [\d.]+ px apart/.test(text)) throw new Error(`the notice says "${text}"${shown ? "" : " (not shown)"}`);
    return text;
  });
  await ada.screenshot({ path: join(ARTIFACTS, "solids-5-refused.png") });
  await stored(base, s, { [plate]: filled, [hole]: holeSolid, [open]: ROD }, "nothing changed");
  assert.equal(await ada.getAttribute("#solid-line", "aria-pressed"), "true", "the row still says Line");
  // The refusal is no step of the history: undo takes the open stroke itself back.
  await ada.keyboard.press("Escape");
  await ada.keyboard.press("Control+z");
  await stored(base, s, { [plate]: filled, [hole]: holeSolid }, "undo after a refusal takes the open stroke back");
  log(`an open stroke filled: refused, "${said}"`);

  // --- 6. the STL, through the Export menu ----------------------------------------------------
  await ada.keyboard.press("4");
  await ada.screenshot({ path: join(ARTIFACTS, "solids-6-3d.png") });
  const stl = await exportStl(ada, "solids.stl");
  const box = stl.size_x * stl.size_y * stl.size_z;
  // The hole (about 5 % of the plate's area, through it) is cut out: the plate's rounded
  // corners alone lose well under 1 %.
  assert.ok(stl.volume < 0.97 * box, `the hole is cut out of the plate: volume ${stl.volume} of a ${box.toFixed(0)} mm³ box`);
  assert.ok(Math.abs(stl.size_z - mm) <= MM_TOLERANCE, `the print is ${stl.size_z} mm thick, the panel said ${mm} mm`);
  log(`the STL: one manifold part, ${stl.volume.toFixed(0)} mm³ of a ${box.toFixed(0)} mm³ box (the hole cut out), ${stl.size_z} mm thick as the panel said`);

  // --- 7. a depth typed in mm -------------------------------------------------------------------
  await ada.keyboard.press("1");
  await ada.keyboard.press("v");
  await ada.mouse.click(...(await ada.evaluate(([x, y]) => window.penmesh.toPage(x, y, null), PLATE_INSIDE)));
  await until("the plate selected", async () => JSON.stringify(await ada.evaluate(() => window.penmesh.selected)) === JSON.stringify([plate]));
  await ada.fill("#selection-solid-depth-mm", String(TYPED_MM));
  await ada.press("#selection-solid-depth-mm", "Enter");
  const depth = await until("the depth typed in mm stored", async () => (await solids(base, s))[plate].depth !== PLATE_DEPTH && (await solids(base, s))[plate].depth);
  await until("the panel shows the mm typed", async () => Number(await ada.inputValue("#selection-solid-depth-mm")) === TYPED_MM);
  const typed = await exportStl(ada, "solids-typed-mm.stl");
  assert.ok(Math.abs(typed.size_z - TYPED_MM) <= MM_TOLERANCE, `${TYPED_MM} mm typed (${depth.toFixed(2)} px): the print is ${typed.size_z} mm thick`);
  // The Export menu at half the size: the panel's mm halve, and so does the print.
  await openExportMenu(ada);
  await ada.fill("#export-size", String(HALF_MM));
  await until("the panel's mm at the Export menu's size", async () => Number(await ada.inputValue("#selection-solid-depth-mm")) === TYPED_MM / 2);
  const half = await exportStl(ada, "solids-half.stl");
  assert.ok(Math.abs(half.size_z - TYPED_MM / 2) <= MM_TOLERANCE, `at ${HALF_MM} mm the print is ${half.size_z} mm thick, the panel said ${TYPED_MM / 2}`);
  log(`${TYPED_MM} mm typed: ${depth.toFixed(2)} px, a print ${typed.size_z} mm thick; at ${HALF_MM} mm the panel said ${TYPED_MM / 2} and the print is ${half.size_z}`);
});

/// Opens the Export menu (behind ⋯ in a narrow window).
async function openExportMenu(page) {
  if (await page.isVisible("#export-menu")) return;
  if (!(await page.isVisible("#download"))) await page.click("#toggle-more");
  await page.click("#download");
}

/// The STL print through the Export menu (at the size it shows), saved as `file`: PrusaSlicer's
/// figures of it (size_x, size_y, size_z in mm, volume in mm³), checked one manifold part.
async function exportStl(page, file) {
  await openExportMenu(page);
  const [download] = await Promise.all([page.waitForEvent("download"), page.click("#export-stl")]);
  const path = join(ARTIFACTS, file);
  await download.saveAs(path);
  const info = execFileSync("prusa-slicer", ["--loglevel", "1", "--info", path], { encoding: "utf8" });
  assert.match(info, /manifold = yes/, info);
  assert.match(info, /number_of_parts =\s+1\b/, info);
  const value = (name) => Number(new RegExp(`${name} = ([\\d.]+)`).exec(info)[1]);
  return Object.fromEntries(["size_x", "size_y", "size_z", "volume"].map((k) => [k, value(k)]));
}