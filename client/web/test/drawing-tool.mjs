// The browser test of the drawing tool (docs/web.md, issue 29): two people in one session, each
// in a browser of their own (Debian's Chromium, playwright-core), driven as a person does.
// Ada names herself, picks a colour and draws three strokes with a pen; Ctrl+Z takes the last
// back on Bob's page within a second, Ctrl+Shift+Z brings it back; the pen's eraser end takes a
// stroke back; Bob's attempt to take one of Ada's strokes back is refused and changes nothing;
// a reload keeps the removal. Run by scripts/test.sh as `node client/web/test/drawing-tool.mjs`
// with PENMESH_BIN set. Screenshots go to target/web-test/. Any failure exits non-zero.
import { join } from "node:path";
import assert from "node:assert/strict";
import { ARTIFACTS, browserTest, drawStroke, isBackground, log, newSession, pixelsAt, synced, until } from "./harness.mjs";

// A removal or a restore on one page is on the other's screen within this long.
const ADA_COLOUR = 0x2266dd;

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const auth = { authorization: `Bearer ${token}` };
  const strokes = async (query = "") => {
    const res = await fetch(`${base}/v1/sessions/${session}/strokes${query}`, { headers: auth });
    assert.ok(res.ok, `GET strokes${query}: HTTP ${res.status}`);
    return (await res.json()).strokes;
  };
  const pageUrl = `${base}/s/${session}#token=${token}`;

  // Two people: a browser context each (their own storage, as on two machines).
  async function openPage(name) {
    const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
    const page = await context.newPage();
    page.on("pageerror", (e) => console.error(`[${name}] page error:`, e.message));
    await page.goto(pageUrl);
    await synced(page);
    page.cdp = await context.newCDPSession(page);
    return page;
  }
  const ada = await openPage("Ada");
  const bob = await openPage("Bob");
  const adaId = await ada.evaluate(() => window.penmesh.me);

  // --- her name, asked once, and her colour --------------------------------------------------
  assert.ok(await ada.locator("#name.ask").count(), "the name is asked on a first visit");
  await ada.locator("#name").fill("Ada");
  await ada.locator("#name").press("Enter");
  await until("Bob to see Ada's name", () => bob.evaluate((id) => window.penmesh.people.get(id) === "Ada", adaId));
  await ada.locator("#colour").fill(`#${ADA_COLOUR.toString(16)}`);
  await ada.locator("#size").fill("12");
  log("Ada named and coloured");

  // --- three strokes --------------------------------------------------------------------------
  await ada.bringToFront();
  const plans = [
    { x0: 150, y0: 150, dx: 5, dy: 2, n: 60 },
    { x0: 200, y0: 450, dx: 6, dy: -1, n: 60 },
    { x0: 750, y0: 120, dx: 0.5, dy: 5, n: 60 },
  ];
  const drawn = [];
  for (const plan of plans) {
    drawn.push(await drawStroke(ada.cdp, plan));
    const want = drawn.length;
    await until(`Ada's mesh ${want}`, () => ada.evaluate((w) => window.penmesh.shown >= w && !window.penmesh.pending, want));
  }
  await until("Bob to show Ada's three strokes", () => bob.evaluate(() => window.penmesh.shown === 3));
  // Bob's list of people shows Ada in the colour she draws with.
  const adaInList = await bob.evaluate(() => [...document.querySelectorAll("#people li")].find((li) => li.textContent === "Ada")?.style.getPropertyValue("--c"));
  assert.equal(adaInList, `#${ADA_COLOUR.toString(16)}`, "Ada's colour in Bob's list of people");
  const ids = (await strokes()).map((s) => s.id);
  assert.equal(ids.length, 3);
  for (const s of await strokes()) {
    assert.equal(s.brush.color, ADA_COLOUR, "the stroke's brush has Ada's colour");
    assert.equal(s.brush.size, 12, "and her size");
  }
  // Bob draws her strokes in her colour: bluish where her third stroke runs.
  const third = drawn[2];
  const onThird = [third[20], third[30], third[40]];
  await bob.bringToFront();
  for (const [r, g, b] of await pixelsAt(bob, onThird, join(ARTIFACTS, "tool-bob-three.png"))) {
    assert.ok(b > r + 30 && b > g, `Ada's stroke on Bob's page is not in her blue: ${[r, g, b]}`);
  }
  log("three strokes, in Ada's colour on both pages");

  // --- Ctrl+Z: the last stroke leaves Bob's screen within a second ---------------------------
  await ada.bringToFront();
  const undoAt = Date.now();
  await ada.keyboard.press("Control+z");
  await until("Bob to hide the undone stroke", () => bob.evaluate((id) => window.penmesh.removed.includes(id), ids[2]));
  const undoMs = Date.now() - undoAt;
  await bob.bringToFront();
  assert.equal(await bob.evaluate(() => window.penmesh.shown), 2);
  (await pixelsAt(bob, onThird, join(ARTIFACTS, "tool-bob-undone.png"))).forEach((px, i) =>
    assert.ok(isBackground(px), `the undone stroke is still on Bob's screen at ${onThird[i]}: ${px}`),
  );
  assert.deepEqual((await strokes()).map((s) => s.id), ids.slice(0, 2), "the list leaves it out");
  const withRemoved = await strokes("?include=removed");
  assert.equal(withRemoved[2].removed.by, adaId, "it is kept, with who took it back");
  log(`Ctrl+Z: gone from Bob's page in ${undoMs} ms`);

  // --- Ctrl+Shift+Z brings it back -------------------------------------------------------------
  await ada.bringToFront();
  await ada.keyboard.press("Control+Shift+z");
  await until("Bob to show the redone stroke", () => bob.evaluate(() => window.penmesh.shown === 3 && window.penmesh.removed.length === 0));
  assert.equal((await strokes()).length, 3);
  log("Ctrl+Shift+Z: back on Bob's page");

  // --- the pen's eraser end takes the first stroke back ----------------------------------------
  // CDP's pen events cannot carry the eraser button, so these are Pointer Events as Chromium
  // makes them for a pen's eraser end (button 5, buttons 32), dispatched on the page.
  await ada.bringToFront();
  const first = drawn[0];
  await ada.evaluate((points) => {
    const ink = document.getElementById("ink");
    const at = (type, [x, y]) =>
      ink.dispatchEvent(new PointerEvent(type, { pointerId: 7, pointerType: "pen", isPrimary: true, button: type === "pointermove" ? -1 : 5, buttons: type === "pointerup" ? 0 : 32, clientX: x, clientY: y, pressure: 0.5, bubbles: true }));
    at("pointerdown", [points[0][0], points[0][1] + 40]); // beside the stroke: nothing
    at("pointermove", points[25]); // across it
    at("pointerup", points[25]);
  }, first);
  await until("Bob to hide the erased stroke", () => bob.evaluate((id) => window.penmesh.removed.includes(id), ids[0]));
  assert.equal(await ada.evaluate(() => window.penmesh.shown), 2);
  assert.equal(await ada.evaluate(() => window.penmesh.pending), null, "the eraser drew no stroke");
  assert.deepEqual((await strokes()).map((s) => s.id), ids.slice(1));
  log("the pen's eraser end took the first stroke back");

  // --- Bob may not take Ada's strokes back -------------------------------------------------------
  await bob.bringToFront();
  const bobErrors = await bob.evaluate(() => window.penmesh.errors.length);
  await bob.evaluate((id) => window.penmesh.setRemoved(id, true), ids[1]);
  await until("Bob's page to report the refusal", () => bob.evaluate((n) => window.penmesh.errors.slice(n).some((e) => e.includes("not_owner")), bobErrors));
  // His eraser over her stroke touches nothing of hers.
  await bob.locator("#tool-erase").click();
  const second = drawn[1];
  await drawStroke(bob.cdp, { x0: second[30][0] - 5, y0: second[30][1] - 20, dx: 0, dy: 1, n: 40 });
  // The page refuses on the spot (a notice naming whose stroke it is); nothing is sent.
  await until("Bob's page to say the stroke is Ada's", () => bob.getByText(/Ada's/).isVisible());
  assert.equal(await bob.evaluate(() => window.penmesh.shown), 2, "Bob's page changed");
  assert.equal(await ada.evaluate(() => window.penmesh.shown), 2, "Ada's page changed");
  assert.deepEqual((await strokes()).map((s) => s.id), ids.slice(1), "the stored strokes changed");
  assert.equal(await bob.evaluate(() => window.penmesh.pending), null, "Bob's eraser drew a stroke");
  log("Bob's attempts were refused and changed nothing");

  // --- a reload keeps the removal, and the name ----------------------------------------------------
  await ada.reload();
  await ada.waitForFunction(() => window.penmesh && window.penmesh.synced);
  await until("Ada's reloaded page to show her two strokes", () => ada.evaluate(() => window.penmesh.shown === 2));
  assert.ok(!(await ada.evaluate((id) => window.penmesh.strokes.has(id), ids[0])), "the erased stroke came back with the reload");
  assert.equal(await ada.locator("#name").inputValue(), "Ada");
  assert.equal(await ada.locator("#name.ask").count(), 0, "the name was asked again");
  await ada.screenshot({ path: join(ARTIFACTS, "tool-ada-reloaded.png") });
  // After the reload, undo takes back her last stroke of the history.
  await ada.keyboard.press("Control+z");
  await until("Bob to hide the stroke undone after the reload", () => bob.evaluate((id) => window.penmesh.removed.includes(id), ids[2]));
  log("a reload keeps the removal and the name; undo still works");

  const errors = await ada.evaluate(() => window.penmesh.errors);
  assert.deepEqual(errors, [], "Ada's page reported errors");
});
