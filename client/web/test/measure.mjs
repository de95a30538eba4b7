// The page's numbers of docs/performance.md, once each (not a test):
//   node client/web/test/measure.mjs
// 1. pen-up to the mesh on screen, p50/p99 over 50 pen strokes drawn through CDP;
// 2. bytes the page downloads to open a 100-stroke session (HTTP bodies as transferred, plus
//    the WebSocket's payloads: binary frames since codec.js, text before).
// A 1,000-stroke board (frames per second while orbiting among its numbers) is
// bench/busy-board.mjs.
import { drawStroke, launch, log, newSession, requireTools, runPenmesh, startProxy, until } from "./harness.mjs";

requireTools();
const children = [];
const browser = await launch();
const quantile = (xs, q) => [...xs].sort((a, b) => a - b)[Math.min(xs.length - 1, Math.floor(q * xs.length))];
try {
  const { base } = await startProxy(children);
  const context = await browser.newContext({ viewport: { width: 1000, height: 700 }, deviceScaleFactor: 1 });
  const open = async ({ session, token }) => {
    const page = await context.newPage();
    await page.goto(`${base}/s/${session}#token=${token}`);
    await page.waitForFunction(() => window.penmesh && window.penmesh.synced);
    return page;
  };

  // 1. Pen-up to mesh on screen.
  const s1 = await newSession(base);
  const page = await open(s1);
  const cdp = await context.newCDPSession(page);
  for (let i = 0; i < 50; i++) {
    await drawStroke(cdp, { x0: 60 + (i % 10) * 90, y0: 60 + Math.floor(i / 10) * 120, dx: 1, dy: 1.5, n: 60 });
    await until(`mesh ${i + 1}`, () => page.evaluate((w) => window.penmesh.timings.length >= w, i + 1));
  }
  const timings = await page.evaluate(() => window.penmesh.timings);
  log(`pen-up to mesh on screen over ${timings.length} strokes: p50 ${quantile(timings, 0.5).toFixed(1)} ms, p99 ${quantile(timings, 0.99).toFixed(1)} ms, max ${Math.max(...timings).toFixed(1)} ms`);
  await page.close();

  // 2. Bytes to open a 100-stroke session.
  const drawN = async (session, n) =>
    runPenmesh(["draw", "--server", base, "--session", session.session, "--token", session.token, "--synth", "leaf", "--count", String(n), "--size", "300", "--name", "native"], children);
  const s100 = await newSession(base);
  await drawN(s100, 100);
  const counted = await context.newPage();
  let http = 0;
  counted.on("requestfinished", async (req) => {
    const sizes = await req.sizes();
    http += sizes.responseBodySize + sizes.responseHeadersSize;
  });
  await counted.goto(`${base}/s/${s100.session}#token=${s100.token}`);
  await until("100 meshes", () => counted.evaluate(() => window.penmesh.meshes >= 100), 120000);
  // Every request the meshes brought finished (no request for 500 ms: Playwright's idle).
  await counted.waitForLoadState("networkidle");
  const ws = await counted.evaluate(() => window.penmesh.wsBytes);
  log(`100-stroke session: ${http} bytes over HTTP (page, script, the meshes), ${ws} bytes of WebSocket payloads, ${http + ws} in all`);
  await counted.close();
} finally {
  for (const c of children) if (c.exitCode === null) c.kill("SIGTERM");
  await browser.close();
}
