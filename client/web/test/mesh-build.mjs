// The browser test of a mesh build that fails (docs/web.md): the page asks the proxy to build
// each of its strokes' meshes (POST /v1/strokes/{id}/mesh/build), and Playwright's request
// routing answers that call 503 as a busy or failing proxy would:
// 1. once: the page tries again and the mesh is built and shown, with no error;
// 2. every time: the page reports the failure after its last try, the stroke is stored done
//    without a mesh; once the proxy answers again, a reload builds it (the history says the
//    stroke has none).
// Run by scripts/test.sh.
import assert from "node:assert/strict";
import { browserTest, drawStroke, log, newSession, storedStrokes, synced, until } from "./harness.mjs";

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const { session, token } = await newSession(base);
  const stored = () => storedStrokes(base, { session, token });

  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  let failures = 0; // builds still to answer 503
  let asked = 0; // builds the page asked for
  await context.route(/\/mesh\/build$/, (route) => {
    asked += 1;
    if (failures === 0) return route.continue();
    failures -= 1;
    return route.fulfill({ status: 503, contentType: "application/json", body: JSON.stringify({ code: "busy", message: "test: the proxy is busy" }) });
  });

  const page = await context.newPage();
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto(`${base}/s/${session}#token=${token}`);
  await synced(page);
  const cdp = await context.newCDPSession(page);

  // --- 1. one failed build: tried again --------------------------------------------------
  failures = 1;
  await drawStroke(cdp, { x0: 150, y0: 200, dx: 5, dy: 1, n: 50 });
  await until("the mesh built on the second try and shown", () => page.evaluate(() => window.penmesh.meshes >= 1));
  assert.equal(asked, 2, "one failed build and one that succeeded");
  assert.deepEqual(await page.evaluate(() => window.penmesh.errors), [], "a build that succeeded on its second try is no error");
  log("a build that failed once: tried again, the mesh shown");

  // --- 2. every build fails: reported, then built after a reload --------------------------
  failures = Infinity;
  asked = 0;
  await drawStroke(cdp, { x0: 200, y0: 450, dx: 5, dy: -1, n: 50 });
  await until("the page to report the failed build", () => page.evaluate(() => window.penmesh.errors.some((e) => e.includes("cannot build the mesh"))));
  assert.equal(asked, 4, "the first try and three more");
  const meshless = (await stored()).filter((s) => !s.has_mesh);
  assert.equal(meshless.length, 1, "one stroke without a mesh");
  assert.equal(meshless[0].status, "done", "stored done all the same");
  failures = 0;
  await page.reload();
  await page.waitForFunction(() => window.penmesh && window.penmesh.synced);
  await until("the reloaded page to build the missing mesh and show both", () => page.evaluate(() => window.penmesh.meshes >= 2));
  assert.ok((await stored()).every((s) => s.status === "done" && s.has_mesh), "every stroke done with a mesh");
  assert.deepEqual(await page.evaluate(() => window.penmesh.errors), [], "the reloaded page reported errors");
  log("builds that kept failing: reported; the reload built the mesh");
});
