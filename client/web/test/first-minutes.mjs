// The browser tests of a new user's first minutes (issue 36, docs/web.md): one check per
// numbered item of the issue, each driven as a person does (Debian's Chromium, playwright-core,
// a pen and fingers through CDP) against a real proxy. Each check passes with the page of this
// commit and fails with the page before it (run one against another build with
// PENMESH_PROXY_BIN). Run by scripts/test.sh as `node client/web/test/first-minutes.mjs`; pick
// checks by number: `node client/web/test/first-minutes.mjs 2 5`. Screenshots go to
// target/web-test/first-*.png. Exits 1 when any check fails, naming each.
import { join } from "node:path";
import assert from "node:assert/strict";
import { ARTIFACTS, browserTest, drawStroke, isBackground, log, newSession, nextFrames, openPage as open, pixelsAt, resizeTo, sessionUrl, storedStrokes, synced, until } from "./harness.mjs";

const PHONE = { width: 390, height: 844 };

const button = (page, name) => page.getByRole("button", { name, exact: false });
const toolButton = (page, name) => page.locator("#bar button").filter({ hasText: name });

/// Opens the session as another person (harness.mjs `openPage`), not waiting for it: the checks
/// wait for what each needs (a refused link never syncs).
const openPage = (browser, url, options = {}) => open(browser, url, { wait: false, ...options });

/// Checks that `page`'s toolbar is one row: its visible controls (buttons, inputs, selects) in
/// the window, none overlapping another, the status, the model bar or the people list. Returns
/// their ids.
async function toolbarFits(page, what) {
  const { controls, others, width } = await page.evaluate(() => {
    const box = (e) => {
      const r = e.getBoundingClientRect();
      return { id: e.id || e.textContent, x: r.x, y: r.y, width: r.width, height: r.height };
    };
    const shown = (e) => e.getClientRects().length > 0;
    return {
      controls: [...document.querySelectorAll("#bar button, #bar input, #bar select")].filter(shown).map(box),
      others: ["status", "modelbar", "people"].map((id) => document.getElementById(id)).filter(shown).map(box),
      width: innerWidth,
    };
  });
  const overlap = (a, b) => a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
  const top = Math.min(...controls.map((c) => c.y));
  for (const [i, a] of controls.entries()) {
    assert.ok(a.x >= 0 && a.x + a.width <= width, `${what}: #${a.id} is not inside the window: ${JSON.stringify(a)}`);
    assert.ok(a.y < top + 24, `${what}: #${a.id} is on a second row: ${JSON.stringify(a)}`);
    for (const b of [...controls.slice(i + 1), ...others]) assert.ok(!overlap(a, b), `${what}: #${a.id} overlaps #${b.id}: ${JSON.stringify([a, b])}`);
  }
  return controls.map((c) => c.id);
}

/// Non-transparent pixels of the ink canvas, in the rectangle (all of it when none is given).
function inkPixels(page, rect = null) {
  return page.evaluate((rect) => {
    const c = document.getElementById("ink");
    const [x, y, w, h] = rect || [0, 0, c.width, c.height];
    const d = c.getContext("2d").getImageData(x, y, w, h).data;
    let n = 0;
    for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
    return n;
  }, rect);
}

/// A horizontal pen stroke from (x0, y) to (x1, y) at a constant pressure.
const line = (cdp, x0, x1, y, n = 30) => drawStroke(cdp, { x0, y0: y, dx: (x1 - x0) / n, dy: 0, n, wobble: 0 });

/// Two fingers: one lands and moves a little, the second lands, both spread apart, both lift.
async function pinch(cdp, [cx, cy], from, to) {
  const touch = (type, points) => cdp.send("Input.dispatchTouchEvent", { type, touchPoints: points });
  const pair = (d) => [{ x: cx - d, y: cy, id: 0 }, { x: cx + d, y: cy, id: 1 }];
  await touch("touchStart", [{ x: cx - from, y: cy, id: 0 }]);
  await touch("touchMove", [{ x: cx - from - 3, y: cy + 2, id: 0 }]);
  await touch("touchStart", pair(from));
  for (let i = 1; i <= 10; i++) await touch("touchMove", pair(from + ((to - from) * i) / 10));
  await touch("touchEnd", []);
}

const checks = {
  // 1. Tools are one group: Draw turns the eraser off, one button pressed, the eraser's cursor,
  //    E and Esc.
  async 1({ base, browser }) {
    const s = await newSession(base);
    const page = await openPage(browser, sessionUrl(base, s));
    await synced(page);
    for (const y of [200, 300, 400]) await line(page.cdp, 300, 500, y);
    await until("three meshes", () => page.evaluate(() => window.penmesh.shown === 3 && !window.penmesh.pending));
    await toolButton(page, "Eras").click();
    const cursor = await page.evaluate(() => getComputedStyle(document.getElementById("ink")).cursor);
    assert.match(cursor, /url\(/, `the eraser's cursor: ${cursor}`);
    await toolButton(page, "Draw").click();
    const pressed = await page.locator('#bar button[aria-pressed="true"]').allTextContents();
    assert.deepEqual(pressed, ["Draw"], "the pressed tool buttons after Eraser then Draw");
    // A stroke across the three: drawn, none erased.
    await drawStroke(page.cdp, { x0: 400, y0: 150, dx: 0, dy: 10, n: 30, wobble: 0 });
    await until("the crossing stroke's mesh", () => page.evaluate(() => window.penmesh.meshes === 4 && !window.penmesh.pending));
    // The page erases as the pen moves, before the stroke ends; the proxy took the stroke's end
    // (its mesh is here) after anything the page sent before it, on the one WebSocket.
    assert.equal(await page.evaluate(() => window.penmesh.shown), 4, "Draw after the eraser erased strokes on the page");
    assert.equal((await storedStrokes(base, s)).length, 4, "Draw after the eraser erased strokes");
    await page.keyboard.press("e");
    assert.deepEqual(await page.locator('#bar button[aria-pressed="true"]').allTextContents(), ["Erase"], "E picks the eraser");
    await page.keyboard.press("Escape");
    assert.deepEqual(await page.locator('#bar button[aria-pressed="true"]').allTextContents(), ["Draw"], "Esc goes back to drawing");
  },

  // 2. Zoom and pan while drawing (wheel, space-drag), the view kept across tool changes and a
  //    resize. Checked by where the strokes are stored.
  async 2({ base, browser }) {
    const s = await newSession(base);
    const page = await openPage(browser, sessionUrl(base, s));
    await synced(page);
    // Nothing drawn yet: one page pixel is one unit, page (x, y) is stroke (x, y).
    await page.mouse.move(500, 350);
    for (let i = 0; i < 3; i++) await page.mouse.wheel(0, -100);
    const zoom = 1.2 ** 3;
    const firstX = async (n) => {
      await until(`stroke ${n} stored`, async () => (await storedStrokes(base, s)).length >= n);
      const strokes = await storedStrokes(base, s);
      const raw = await (await fetch(`${base}/v1/strokes/${strokes[n - 1].id}/raw`, { headers: { authorization: `Bearer ${s.token}` } })).json();
      return raw.samples[0];
    };
    await line(page.cdp, 700, 900, 350);
    let [x, y] = await firstX(1);
    assert.ok(Math.abs(x - (500 + 200 / zoom)) < 2 && Math.abs(y - 350) < 2, `after zooming in about (500, 350), page (700, 350) drew at (${x}, ${y}), not (${(500 + 200 / zoom).toFixed(1)}, 350)`);
    // Space-drag pans by 100 px; Orbit then Draw keeps the view.
    await page.keyboard.down("Space");
    await page.mouse.move(500, 350);
    await page.mouse.down();
    await page.mouse.move(450, 350, { steps: 3 });
    await page.mouse.move(400, 350, { steps: 3 });
    await page.mouse.up();
    await page.keyboard.up("Space");
    await toolButton(page, "Orbit").click();
    await toolButton(page, "Draw").click();
    await line(page.cdp, 700, 900, 350);
    [x, y] = await firstX(2);
    const want = 500 + (200 + 100) / zoom;
    assert.ok(Math.abs(x - want) < 2 && Math.abs(y - 350) < 2, `after a space-drag and Orbit then Draw, page (700, 350) drew at (${x}, ${y}), not (${want.toFixed(1)}, 350)`);
    // A phone's width: what was in the middle stays in the middle.
    const centre = 500 + 100 / zoom;
    await resizeTo(page, PHONE);
    await line(page.cdp, PHONE.width / 2, PHONE.width / 2 + 60, PHONE.height / 2);
    [x, y] = await firstX(3);
    assert.ok(Math.abs(x - centre) < 2 && Math.abs(y - 350) < 2, `after the resize, the middle of the page drew at (${x}, ${y}), not (${centre.toFixed(1)}, 350)`);
    await page.screenshot({ path: join(ARTIFACTS, "first-2-phone.png") });
  },

  // 3. No leftover ink: a two-finger touch draws nothing; the ink moves with the view; once the
  //    meshes are in, the ink is empty.
  async 3({ base, browser }) {
    const s = await newSession(base);
    const page = await openPage(browser, sessionUrl(base, s), { touch: true });
    await synced(page);
    await pinch(page.cdp, [500, 350], 40, 160);
    // The touch events are handled when CDP answers: a stroke begun would be on the page now.
    assert.equal(await page.evaluate(() => window.penmesh.pending), null, "a two-finger touch began a stroke");
    assert.equal(await inkPixels(page), 0, "a two-finger touch left ink");
    // Hold the mesh build: the ink is all there is of the stroke, and turns with the view.
    let release;
    const held = new Promise((r) => (release = r));
    await page.route("**/mesh/build", async (route) => {
      await held;
      await route.continue();
    });
    const lineStart = await page.evaluate(() => window.penmesh.toStroke(650, 200));
    await line(page.cdp, 650, 850, 200);
    await until("the stroke done", async () => (await storedStrokes(base, s)).length >= 1 && !(await page.evaluate(() => window.penmesh.pending)));
    // The line's end came after anything the pinch sent: one stroke stored, and it is the line.
    const stored = await storedStrokes(base, s);
    assert.equal(stored.length, 1, "a two-finger touch stored a stroke");
    const first = await (await fetch(`${base}/v1/strokes/${stored[0].id}/raw`, { headers: { authorization: `Bearer ${s.token}` } })).json();
    const [x0, y0] = first.samples[0];
    assert.ok(Math.hypot(x0 - lineStart[0], y0 - lineStart[1]) < 2, `the stored stroke begins at (${x0}, ${y0}), not at the line's (${lineStart})`);
    assert.ok((await inkPixels(page, [740, 195, 20, 10])) > 0, "no ink under the pen");
    await toolButton(page, "Orbit").click();
    await page.mouse.move(500, 500);
    await page.mouse.down();
    await page.mouse.move(300, 450, { steps: 5 });
    await page.mouse.up();
    await page.screenshot({ path: join(ARTIFACTS, "first-3-orbit-held.png") });
    assert.equal(await inkPixels(page, [740, 195, 20, 10]), 0, "the ink stayed where it was on the page while the view turned");
    release();
    await until("the mesh", () => page.evaluate(() => window.penmesh.meshes === 1));
    await page.keyboard.press("Escape");
    for (const y of [300, 400, 500]) await line(page.cdp, 200, 400, y);
    await until("four meshes", () => page.evaluate(() => window.penmesh.meshes === 4 && !window.penmesh.pending));
    await nextFrames(page);
    await until("the ink empty once every mesh came", async () => (await inkPixels(page)) === 0);
  },

  // 4. The landing page at /, and a link that opens nothing said in words, with no retry.
  async 4({ base, browser }) {
    const home = await openPage(browser, `${base}/`);
    assert.ok(!(await home.locator("#bar").isVisible()), "the landing page shows the drawing toolbar");
    await home.screenshot({ path: join(ARTIFACTS, "first-4-landing.png") });
    await home.setViewportSize(PHONE);
    await home.screenshot({ path: join(ARTIFACTS, "first-4-landing-phone.png") });
    await button(home, "Start a new session").click();
    await home.waitForURL(/\/s\/[0-9a-f-]{36}#token=/);
    await synced(home);
    const s = await newSession(base);
    const other = await newSession(base);
    // Joining by a pasted link; a pasted text that is not one is said so.
    const joiner = await openPage(browser, `${base}/`);
    await joiner.locator("#join-link").fill("not a link");
    await button(joiner, "Join").click();
    await until("the pasted text refused in words", () => joiner.getByText("not a session link").isVisible());
    await joiner.locator("#join-link").fill(sessionUrl(base, s));
    await button(joiner, "Join").click();
    await synced(joiner);
    await joiner.context().close();
    for (const [label, url] of [
      ["a wrong token", `${base}/s/${s.session}#token=not-the-token`],
      ["an unknown session", `${base}/s/${crypto.randomUUID()}#token=${s.token}`],
      ["another session's token", `${base}/s/${s.session}#token=${other.token}`],
    ]) {
      const page = await openPage(browser, url);
      const sockets = [];
      page.on("websocket", (ws) => sockets.push(ws.url()));
      await until(`${label}: said in words`, () => page.getByRole("heading", { name: /does not open a session/ }).isVisible());
      // What is checked here is that the page does not try again: it is watched for 3 s once
      // it said so (an observation window, not a wait for something to happen).
      await page.waitForTimeout(3000);
      assert.ok(await button(page, "Start a new session").isVisible(), `${label}: no way out`);
      assert.ok(!(await page.locator("#bar").isVisible()), `${label}: the toolbar is shown`);
      assert.ok(sockets.length <= 1, `${label}: ${sockets.length} WebSocket connections in 3 s`);
      assert.doesNotMatch(await page.locator("body").innerText(), /HTTP 401|reconnecting/, `${label}: the page says HTTP 401 or reconnecting`);
      if (label === "a wrong token") {
        await page.screenshot({ path: join(ARTIFACTS, "first-4-refused.png") });
        await page.setViewportSize(PHONE);
        await page.screenshot({ path: join(ARTIFACTS, "first-4-refused-phone.png") });
      }
      await page.context().close();
    }
  },

  // 5. The toolbar is one row whatever the width: at 1000 px every control, at 800 px the rest
  //    behind ⋯, no two controls overlapping, none over the status, the model bar or the people.
  //    A phone: one row of large buttons, nothing covering the name or the status, a pinch
  //    zooms and draws nothing.
  async 5({ base, browser }) {
    const s = await newSession(base);
    const desktop = await openPage(browser, sessionUrl(base, s));
    await synced(desktop);
    const all = await toolbarFits(desktop, "at 1000 px");
    for (const id of ["undo", "colour", "size", "name", "fit", "copy-link", "download", "new"]) assert.ok(all.includes(id), `at 1000 px the toolbar shows #${id}: ${all}`);
    await desktop.screenshot({ path: join(ARTIFACTS, "first-5-desktop.png") });
    await resizeTo(desktop, { width: 800, height: 700 });
    const narrow = await toolbarFits(desktop, "at 800 px");
    assert.ok(narrow.includes("toggle-more") && !narrow.includes("new"), `at 800 px the rest is behind ⋯: ${narrow}`);
    const page = await openPage(browser, sessionUrl(base, s), { viewport: PHONE, touch: true });
    await synced(page);
    await toolbarFits(page, "on a phone");
    const bar = await page.locator("#bar").boundingBox();
    assert.ok(bar.height <= 56, `the toolbar is ${bar.height} px high: more than one row`);
    for (const b of await page.locator("#bar button:visible").all()) {
      const box = await b.boundingBox();
      assert.ok(box.height >= 40 && box.width >= 40, `a ${box.width}x${box.height} px button (${await b.getAttribute("id")})`);
    }
    await button(page, "more").click();
    const boxes = {};
    for (const id of ["people", "name", "status", "views"]) {
      assert.ok(await page.locator(`#${id}`).isVisible(), `#${id} is not shown`);
      boxes[id] = await page.locator(`#${id}`).boundingBox();
    }
    const overlap = (a, b) => a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
    assert.ok(!overlap(boxes.people, boxes.name) && !overlap(boxes.people, boxes.status), `the people list covers the name or the status: ${JSON.stringify(boxes)}`);
    assert.ok(!overlap(boxes.views, boxes.status) && !overlap(boxes.views, boxes.people), `the views cover the status or the people list: ${JSON.stringify(boxes)}`);
    await page.screenshot({ path: join(ARTIFACTS, "first-5-phone-menu.png") });
    await button(page, "more").click();
    await pinch(page.cdp, [195, 500], 30, 120);
    // The touch events are handled when CDP answers: a stroke begun would be on the page now,
    // and would be the page's first message after its hello.
    assert.equal(await page.evaluate(() => window.penmesh.pending), null, "the pinch began a stroke");
    assert.equal(await page.evaluate(() => window.penmesh.inked), 0, "the pinch left ink");
    const scale = await page.evaluate(() => window.penmesh.camera.scale);
    assert.ok(scale > 2, `the pinch did not zoom in (scale ${scale})`);
    // A stroke after it: once it is stored, anything the pinch sent before it would be too.
    await line(page.cdp, 100, 300, 300);
    await until("the stroke after the pinch stored", async () => (await storedStrokes(base, s)).length >= 1 && !(await page.evaluate(() => window.penmesh.pending)));
    assert.equal((await storedStrokes(base, s)).length, 1, "the pinch drew a stroke");
    await page.screenshot({ path: join(ARTIFACTS, "first-5-phone.png") });
  },

  // 6. The other person sees a live stroke at its width; a thin stroke seen zoomed out is one
  //    line, not dashes. (The mesh's width against the ink: stroke-width.mjs.)
  async 6({ base, browser }) {
    const s = await newSession(base);
    const url = sessionUrl(base, s);
    const ada = await openPage(browser, url, { brush: { size: 24, pressure_response: 0.5, min_radius: 0.25, color: 0x2266dd }, name: "Ada" });
    const bob = await openPage(browser, url, { name: "Bob" });
    await synced(ada);
    await synced(bob);
    await ada.bringToFront();
    // Held down: live on Bob's page, no mesh yet. Pressure 0.5 at the middle: 12 px wide.
    await drawStroke(ada.cdp, { x0: 200, y0: 300, dx: 10, dy: 0, n: 60, lift: false, wobble: 0 });
    await until("Bob to see the live stroke", () => bob.evaluate(() => [...window.penmesh.strokes.values()].some((s) => s.points.length >= 2 && !s.mesh)));
    await bob.bringToFront();
    await nextFrames(bob);
    const across = Array.from({ length: 21 }, (_, i) => [500, 290 + i]);
    // pixelsAt takes the darkest of 5x5: a 1-px line covers 5 rows, a 12-px ribbon about 16.
    // Until the live points up to x = 500 have reached Bob's page and been drawn.
    let covered = 0;
    await until("Bob to draw Ada's live stroke about 12 px wide", async () => {
      covered = (await pixelsAt(bob, across, join(ARTIFACTS, "first-6-live.png"))).filter((px) => !isBackground(px)).length;
      return covered >= 12;
    }).catch((e) => assert.fail(`Bob sees Ada's live stroke ${covered - 4} px wide, not about 12 (${e.message})`));
    await ada.bringToFront();
    await ada.cdp.send("Input.dispatchMouseEvent", { type: "mouseReleased", x: 800, y: 300, button: "left", buttons: 0, clickCount: 1, pointerType: "pen" });
    await until("Ada's mesh", () => ada.evaluate(() => window.penmesh.meshes === 1 && !window.penmesh.pending));
    // A size-2 stroke, seen zoomed out to a quarter: still one unbroken line.
    await ada.evaluate(() => {
      const b = window.penmesh.brush;
      b.size = 2;
    });
    await line(ada.cdp, 100, 900, 500, 80);
    await until("the thin stroke's mesh", () => ada.evaluate(() => window.penmesh.meshes === 2 && !window.penmesh.pending));
    await toolButton(ada, "Orbit").click();
    await ada.mouse.move(500, 350);
    for (let i = 0; i < 8; i++) await ada.mouse.wheel(0, 100);
    // Eight wheel steps out: a scale of 1.2^-8 (0.23); then what it drew is on the screen.
    await until("the view zoomed out to a quarter", () => ada.evaluate(() => window.penmesh.camera.scale < 0.25));
    await nextFrames(ada);
    const [a, b] = await ada.evaluate(() => [window.penmesh.toPage(150, 500), window.penmesh.toPage(850, 500)]);
    const along = Array.from({ length: Math.floor(b[0] - a[0]) }, (_, i) => [a[0] + i, a[1]]);
    // Its ink went with its mesh (on Chromium's GPU canvas it stayed, about 3 runs in 4).
    assert.equal(await inkPixels(ada), 0, "the thin stroke's ink is still on the page after its mesh came");
    const gaps = (await pixelsAt(ada, along, join(ARTIFACTS, "first-6-thin.png"))).filter(isBackground).length;
    assert.equal(gaps, 0, `the thin stroke zoomed out has ${gaps} gaps along ${along.length} px`);
  },

  // 7. The name box selects its text, so typing replaces it; guests' colours stay apart.
  async 7({ base, browser }) {
    const s = await newSession(base);
    const url = sessionUrl(base, s);
    const pages = [];
    for (let i = 0; i < 4; i++) {
      pages.push(await openPage(browser, url, { name: `guest ${i}` }));
      await synced(pages[i]);
    }
    const [ada, bob] = pages;
    const adaId = await ada.evaluate(() => window.penmesh.me);
    await ada.bringToFront();
    await ada.locator("#name").click();
    await ada.keyboard.type("Ada");
    await ada.keyboard.press("Enter");
    await until("Bob to see Ada's name", () => bob.evaluate((id) => window.penmesh.people.get(id), adaId).then((n) => n && !n.startsWith("guest")));
    assert.equal(await bob.evaluate((id) => window.penmesh.people.get(id), adaId), "Ada", "the name Bob sees");
    const colours = [];
    for (const p of pages) colours.push(parseInt((await p.locator("#colour").inputValue()).slice(1), 16));
    const ch = (c, k) => (c >> k) & 0xff;
    const distance = (a, b) => Math.hypot(ch(a, 16) - ch(b, 16), ch(a, 8) - ch(b, 8), ch(a, 0) - ch(b, 0));
    for (let i = 0; i < colours.length; i++) {
      for (let j = 0; j < i; j++) {
        const d = distance(colours[i], colours[j]);
        assert.ok(d >= 80, `guests ${j} and ${i} draw in #${colours[j].toString(16)} and #${colours[i].toString(16)}: ${d.toFixed(0)} apart`);
      }
    }
  },

  // 8. Feedback: undo and redo greyed out when there is nothing; Ctrl+Z with nothing and
  //    erasing another's stroke each say why nothing happened.
  async 8({ base, browser }) {
    const s = await newSession(base);
    const url = sessionUrl(base, s);
    const ada = await openPage(browser, url, { name: "Ada" });
    await synced(ada);
    await ada.locator("#name").fill("Ada");
    await ada.locator("#name").press("Enter");
    const bob = await openPage(browser, url, { name: "Bob" });
    await synced(bob);
    assert.ok(await bob.locator("#undo").isDisabled(), "Undo is not greyed out with nothing to undo");
    assert.ok(await bob.locator("#redo").isDisabled(), "Redo is not greyed out with nothing to redo");
    await bob.keyboard.press("Control+z");
    await until("a notice for Ctrl+Z with nothing to undo", () => bob.getByText(/nothing to undo/i).isVisible());
    await ada.bringToFront();
    await line(ada.cdp, 300, 600, 300);
    await until("Bob to show Ada's stroke", () => bob.evaluate(() => window.penmesh.shown === 1));
    await bob.bringToFront();
    await toolButton(bob, "Eras").click();
    await drawStroke(bob.cdp, { x0: 450, y0: 250, dx: 0, dy: 5, n: 20, wobble: 0 });
    await until("a notice that the stroke is Ada's", () => bob.getByText(/Ada's/).isVisible());
    assert.equal(await bob.evaluate(() => window.penmesh.shown), 1);
    await toolButton(bob, "Draw").click();
    await line(bob.cdp, 300, 600, 450);
    await until("Bob's mesh", () => bob.evaluate(() => window.penmesh.shown === 2 && !window.penmesh.pending));
    assert.ok(await bob.locator("#undo").isEnabled(), "Undo greyed out with a stroke to undo");
    await bob.keyboard.press("Control+z");
    await until("Redo to be offered", () => bob.locator("#redo").isEnabled());
    await bob.keyboard.press("Control+Shift+z");
    await until("Bob's stroke back", () => bob.evaluate(() => window.penmesh.shown === 2));
    await bob.screenshot({ path: join(ARTIFACTS, "first-8-desktop.png") });
  },

  // The eraser (style.md): one drag that erases three strokes is one command; Undo brings all
  //    three back, Redo erases them again.
  async eraser({ base, browser }) {
    const s = await newSession(base);
    const page = await openPage(browser, sessionUrl(base, s));
    await synced(page);
    for (const y of [200, 300, 400]) await line(page.cdp, 300, 500, y);
    await until("three meshes", () => page.evaluate(() => window.penmesh.meshes === 3 && !window.penmesh.pending));
    await toolButton(page, "Eras").click();
    await drawStroke(page.cdp, { x0: 400, y0: 150, dx: 0, dy: 10, n: 30, wobble: 0 });
    await until("the three erased", () => page.evaluate(() => window.penmesh.shown === 0));
    await page.keyboard.press("Control+z");
    await until("one Undo to bring all three back", () => page.evaluate(() => window.penmesh.shown === 3));
    await page.keyboard.press("Control+Shift+z");
    await until("one Redo to erase all three again", () => page.evaluate(() => window.penmesh.shown === 0));
    await page.keyboard.press("Control+z");
    await until("all three back again", () => page.evaluate(() => window.penmesh.shown === 3));
    // The command before the drag is the last stroke drawn: one more Undo takes back one.
    await page.keyboard.press("Control+z");
    await until("the last stroke drawn taken back", () => page.evaluate(() => window.penmesh.shown === 2));
    // An Undo is done on the page when its key is handled; the proxy follows.
    await until("the proxy to show two strokes", async () => (await storedStrokes(base, s)).length === 2);
    await nextFrames(page);
    assert.equal(await page.evaluate(() => window.penmesh.shown), 2, "an Undo took back more than the last stroke drawn");
  },

  // 9. Sharing: "Copy link" copies the session's link; "New session" asks first.
  async 9({ base, browser }) {
    const s = await newSession(base);
    const url = sessionUrl(base, s);
    const page = await openPage(browser, url, { permissions: ["clipboard-read", "clipboard-write"] });
    await synced(page);
    await button(page, "Copy link").click();
    await until("the link in the clipboard", async () => (await page.evaluate(() => navigator.clipboard.readText())) === url);
    let dialogs = 0;
    page.on("dialog", (d) => {
      dialogs++;
      d.dismiss();
    });
    await button(page, "New session").click();
    const asked = async () => dialogs > 0 || (await page.locator("dialog[open]").count()) > 0;
    // Asking is a dialog; leaving without asking is a navigation: whichever comes first.
    await until("New session to ask or to leave", async () => (await asked()) || page.url() !== url);
    assert.equal(page.url(), url, "New session left the session without asking");
    assert.ok(await asked(), "New session did not ask");
    await page.screenshot({ path: join(ARTIFACTS, "first-9-new.png") });
    if (dialogs === 0) await button(page, "Cancel").click();
    assert.equal(page.url(), url);
  },
};

const chosen = process.argv.slice(2).length ? process.argv.slice(2) : Object.keys(checks);
await browserTest(async ({ proxy, browser }) => {
  const failed = [];
  for (const n of chosen) {
    const started = Date.now();
    try {
      await checks[n]({ base: proxy.base, browser });
      log(`item ${n}: PASS (${((Date.now() - started) / 1000).toFixed(1)} s)`);
    } catch (err) {
      failed.push(n);
      log(`item ${n}: FAIL: ${err.message.split("\n")[0]}`);
    }
    for (const c of browser.contexts()) await c.close();
  }
  if (failed.length) throw new Error(`items ${failed.join(", ")} failed`);
});
