// What the browser test and the measurements share: a real proxy (`penmesh-proxy` on a
// fresh SQLite file), Debian's Chromium through playwright-core, and a pen through CDP.
import { chromium } from "playwright-core";
import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { existsSync, mkdirSync, mkdtempSync } from "node:fs";
import { createServer } from "node:net";
import { tmpdir } from "node:os";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";

export const root = resolve(dirname(fileURLToPath(import.meta.url)), "../../..");
export const CHROMIUM = process.env.PENMESH_CHROMIUM || "/usr/bin/chromium";
export const BIN = process.env.PENMESH_BIN || join(root, "target/debug/penmesh");
// The proxy's own binary: $PENMESH_PROXY_BIN, or the one built beside `penmesh`.
export const PROXY_BIN = process.env.PENMESH_PROXY_BIN || join(dirname(BIN), "penmesh-proxy");

// Where the browser tests write their screenshots.
export const ARTIFACTS = process.env.PENMESH_WEB_ARTIFACTS || join(root, "target/web-test");

const started = Date.now();
export const log = (...a) => console.log(`[${((Date.now() - started) / 1000).toFixed(1)}s]`, ...a);

/// Fails (exit 1) with what to do when Chromium or the penmesh binary is missing: never a skip.
export function requireTools() {
  if (!existsSync(CHROMIUM)) {
    console.error(`FAIL: no Chromium at ${CHROMIUM}; install Debian's (apt-get install -y chromium) or set PENMESH_CHROMIUM`);
    process.exit(1);
  }
  if (!existsSync(BIN)) {
    console.error(`FAIL: no penmesh binary at ${BIN}; build it (cargo build --bin penmesh) or set PENMESH_BIN`);
    process.exit(1);
  }
  if (!existsSync(PROXY_BIN)) {
    console.error(`FAIL: no penmesh-proxy binary at ${PROXY_BIN}; build it (cargo build --bin penmesh-proxy) or set PENMESH_PROXY_BIN`);
    process.exit(1);
  }
}

function freePort() {
  return new Promise((ok, err) => {
    const s = createServer();
    s.listen(0, "127.0.0.1", () => {
      const { port } = s.address();
      s.close(() => ok(port));
    });
    s.on("error", err);
  });
}

/// Waits until `fn` returns something truthy, polling every 100 ms; fails naming `what` (and
/// the last answer) after `timeoutMs`. The tests wait on conditions with this, never on time:
/// the timeout is only how long a condition may take on a busy machine before it counts as
/// never (60 s by default: the suites must pass with both cores kept busy, docs/web.md).
export async function until(what, fn, timeoutMs = 60000) {
  const end = Date.now() + timeoutMs;
  let last;
  while (Date.now() < end) {
    try {
      last = await fn();
      if (last) return last;
    } catch (e) {
      last = e;
    }
    await new Promise((r) => setTimeout(r, 100));
  }
  throw new Error(`timed out waiting for ${what} (last: ${last instanceof Error ? last.message : JSON.stringify(last)})`);
}

/// Resolves once `page` has rendered two more animation frames: what it drew for the last
/// change is on the screen (three.js renders on change, in a frame callback).
export function nextFrames(page) {
  return page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
}

/// Resizes `page` and waits until the page has laid itself out at the new size: the window, the
/// camera (session.js's resize handler) and the ink canvas all at `{ width, height }`. Chromium
/// fires `resize` at its next frame, later still on a busy machine (issue 48).
export async function resizeTo(page, { width, height }) {
  await page.setViewportSize({ width, height });
  await until(`the page laid out at ${width}x${height}`, () =>
    page.evaluate(([w, h]) => {
      const rig = window.penmesh && window.penmesh.view.rig;
      const ink = document.getElementById("ink");
      return innerWidth === w && innerHeight === h && rig && rig.width === w && rig.height === h && ink.width === w * devicePixelRatio;
    }, [width, height]),
  );
  await nextFrames(page);
}

/// Starts the proxy; `children` collects every process to stop at the end.
export async function startProxy(children) {
  const dir = mkdtempSync(join(tmpdir(), "penmesh-web-test-"));
  const port = await freePort();
  const base = `http://127.0.0.1:${port}`;
  const proxy = spawn(PROXY_BIN, ["--host", "127.0.0.1", "--port", String(port), "--database-url", `sqlite://${dir}/t.db`], {
    stdio: ["ignore", "ignore", "pipe"],
  });
  const out = { base, log: "" };
  proxy.stderr.on("data", (d) => (out.log += d));
  children.push(proxy);
  await until("the proxy", async () => (await fetch(`${base}/healthz`)).ok);
  return out;
}

export async function newSession(base) {
  const res = await fetch(`${base}/v1/sessions`, { method: "POST" });
  if (!res.ok) throw new Error(`POST /v1/sessions: HTTP ${res.status}`);
  return res.json();
}

/// The page's link to session `s` (what "Copy link" gives: the token in the fragment).
export const sessionUrl = (base, { session, token }) => `${base}/s/${session}#token=${token}`;

/// The window the desktop tests open (one unit of the board per CSS pixel at the first view).
export const VIEW = { width: 1000, height: 700 };

/// Waits until `page` is in its session (Welcome) and has its history (Synced).
export const synced = (page) => page.waitForFunction(() => window.penmesh && window.penmesh.me && window.penmesh.synced);

/// Opens `url` in a browser context of its own (another person, another participant) at
/// `viewport` (touch: a phone's), its page errors printed under `name`, `brush` kept for it
/// before it loads; `prepare(page)` runs before it loads (to route or record its WebSocket).
/// Returns the page with its CDP session as `page.cdp`, once synced (unless `wait` is false).
export async function openPage(browser, url, { name = "page", viewport = VIEW, touch = false, brush = null, permissions = [], prepare = null, wait = true } = {}) {
  const context = await browser.newContext({ viewport, deviceScaleFactor: 1, hasTouch: touch, isMobile: touch, permissions, acceptDownloads: true });
  if (brush) await context.addInitScript((b) => sessionStorage.setItem("penmesh:brush", JSON.stringify(b)), brush);
  const page = await context.newPage();
  page.on("pageerror", (e) => console.error(`[${name}] page error:`, e.message));
  page.cdp = await context.newCDPSession(page);
  if (prepare) await prepare(page);
  await page.goto(url);
  if (wait) await synced(page);
  return page;
}

/// A new session with two people in it, each on a page of their own (synced), Ada's in front:
/// `{ s, url, ada, bob }`.
export async function adaAndBob(browser, base) {
  const s = await newSession(base);
  const url = sessionUrl(base, s);
  const ada = await openPage(browser, url, { name: "ada" });
  const bob = await openPage(browser, url, { name: "bob" });
  await ada.bringToFront();
  return { s, url, ada, bob };
}

/// A pen stroke through the page points `corners` ([x, y]) at an even pressure, a sample every
/// 6 px or so; the pen stays down when `lift` is false.
export async function polyline(cdp, corners, lift = true) {
  const ev = (type, [x, y]) =>
    cdp.send("Input.dispatchMouseEvent", { type, x, y, force: type === "mouseReleased" ? 0 : 0.5, button: "left", buttons: type === "mouseReleased" ? 0 : 1, clickCount: 1, pointerType: "pen" });
  await ev("mousePressed", corners[0]);
  for (let i = 1; i < corners.length; i++) {
    const [[x0, y0], [x1, y1]] = [corners[i - 1], corners[i]];
    const n = Math.max(1, Math.round(Math.hypot(x1 - x0, y1 - y0) / 6));
    for (let k = 1; k <= n; k++) await ev("mouseMoved", [x0 + ((x1 - x0) * k) / n, y0 + ((y1 - y0) * k) / n]);
  }
  if (lift) await ev("mouseReleased", corners[corners.length - 1]);
}

/// The strokes stored in a session (GET /v1/sessions/{id}/strokes): what a test checks storage by.
export async function storedStrokes(base, { session, token }) {
  const res = await fetch(`${base}/v1/sessions/${session}/strokes`, { headers: { authorization: `Bearer ${token}` } });
  if (!res.ok) throw new Error(`GET /v1/sessions/${session}/strokes: HTTP ${res.status}`);
  return (await res.json()).strokes;
}

export function launch() {
  return chromium.launch({
    executablePath: CHROMIUM,
    args: [
      "--no-sandbox",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--no-first-run",
    ],
  });
}

/// Runs `penmesh ARGS…` to the end; rejects with its output when it fails.
export function runPenmesh(args, children) {
  const child = spawn(BIN, args, { stdio: ["ignore", "pipe", "pipe"] });
  children.push(child);
  let out = "";
  child.stdout.on("data", (d) => (out += d));
  child.stderr.on("data", (d) => (out += d));
  return new Promise((ok, err) => child.on("exit", (code) => (code === 0 ? ok(out) : err(new Error(`penmesh ${args[0]} failed (${code}):\n${out}`)))));
}

/// A pen stroke through CDP: down, `n` moves, up (unless `lift` is false); the pressure rises
/// then falls; x wobbles by up to `wobble` px. Returns the `[x, y, pressure]` of each event sent.
export async function drawStroke(cdp, { x0, y0, dx, dy, n, lift = true, wobble = 20 }) {
  const sent = [];
  const ev = (type, x, y, force) =>
    cdp.send("Input.dispatchMouseEvent", {
      type, x, y, force, button: "left", buttons: type === "mouseReleased" ? 0 : 1,
      clickCount: 1, pointerType: "pen",
    });
  for (let i = 0; i <= n; i++) {
    const x = x0 + dx * i + wobble * Math.sin(i / 6);
    const y = y0 + dy * i;
    const force = Math.round((0.1 + 0.8 * Math.sin((Math.PI * i) / n)) * 1000) / 1000;
    await ev(i === 0 ? "mousePressed" : "mouseMoved", x, y, force);
    sent.push([x, y, force]);
  }
  if (lift) {
    const [x, y] = sent[sent.length - 1];
    await ev("mouseReleased", x, y, 0);
  }
  return sent;
}

/// The page's background colour (index.html, scene.js).
export const BACKGROUND = [0xf4, 0xf3, 0xef];

export const isBackground = ([r, g, b]) => Math.abs(r - BACKGROUND[0]) + Math.abs(g - BACKGROUND[1]) + Math.abs(b - BACKGROUND[2]) < 24;

/// The WebGL canvas of `page` at `points` (CSS pixels), read back from a screenshot saved to
/// `file` (decoded by the browser itself): the darkest pixel of the 5x5 around each point, as
/// the mesh is a few pixels wide.
export async function pixelsAt(page, points, file) {
  const png = await page.locator("#gl").screenshot({ path: file });
  return page.evaluate(
    async ({ data, points }) => {
      const img = new Image();
      img.src = `data:image/png;base64,${data}`;
      await img.decode();
      const c = document.createElement("canvas");
      c.width = img.width;
      c.height = img.height;
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      return points.map(([x, y]) => {
        const d = g.getImageData(Math.round(x) - 2, Math.round(y) - 2, 5, 5).data;
        let best = [255, 255, 255];
        for (let i = 0; i < d.length; i += 4) if (d[i] + d[i + 1] + d[i + 2] < best[0] + best[1] + best[2]) best = [d[i], d[i + 1], d[i + 2]];
        return best;
      });
    },
    { data: png.toString("base64"), points },
  );
}

/// Runs one browser test: `main({ proxy, browser, children })` with a proxy on a fresh database
/// and a launched Chromium (`children` collects the processes it starts). Every process and
/// the browser are stopped at the end; a failure prints the proxy's log and exits 1.
export async function browserTest(main) {
  requireTools();
  mkdirSync(ARTIFACTS, { recursive: true });
  const children = [];
  let proxy;
  let browser;
  const cleanup = async () => {
    for (const c of children) if (c.exitCode === null) c.kill("SIGTERM");
    if (browser) await browser.close().catch(() => {});
  };
  try {
    proxy = await startProxy(children);
    browser = await launch();
    await main({ proxy, browser, children });
    await cleanup();
    log(`PASS (screenshots in ${ARTIFACTS})`);
  } catch (err) {
    console.error("FAIL:", err.stack || err);
    console.error("--- proxy log (tail) ---\n" + (proxy ? proxy.log : "").split("\n").slice(-30).join("\n"));
    await cleanup();
    process.exit(1);
  }
}

/// Where the middle sample of `stroke` is on `page`, in its plane.
export function strokeMiddle(page, stroke) {
  return page.evaluate((id) => {
    const st = window.penmesh.strokes.get(id);
    const p = st.points[Math.floor(st.points.length / 2)];
    return window.penmesh.toPage(p.x, p.y, st.placement);
  }, stroke);
}

/// Clicks the middle sample of `stroke` on `page` (the Select tool on), checks that it alone is
/// selected, and returns where the gizmo's `axis` handle is on the page.
export async function selectForGizmo(page, stroke, axis = "X") {
  await page.mouse.click(...(await strokeMiddle(page, stroke)));
  assert.deepEqual(await page.evaluate(() => window.penmesh.selected), [stroke], "a click selects the stroke under it");
  const handle = await page.evaluate((a) => window.penmesh.gizmoHandle(a), axis);
  assert.ok(handle, "no gizmo on the selected stroke");
  return handle;
}
