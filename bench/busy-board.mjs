// A busy board (issue 26): ten people's 1,000 real strokes drawn into one session through the
// real protocol, then the session's page opened in headless Chromium (SwiftShader WebGL), and
// the five numbers of docs/performance.md ("The busy board"):
//   1. time until the view is complete (every mesh in the scene and drawn), from navigation start;
//   2. bytes transferred to open it (HTTP as received, headers included, and WebSocket frames);
//   3. HTTP requests (the WebSocket is one connection more);
//   4. frames per second while orbiting (a mouse drag through CDP, frames the page rendered);
//   5. the browser's CPU while nothing changes (all of Chromium's processes, from /proc).
// Also the page's main-thread tasks over 50 ms (the Long Tasks API: `long_tasks`, [start, ms]
// from navigation start, and their sum from the bundle's arrival until the view was complete),
// and with --profile the first open's CPU profile until then (DevTools' .cpuprofile; the page
// is minified: an esbuild build of the same sources with `sourcemap: true` maps it back).
//
// Usage (from the repository root, after `cargo build --release --bin penmesh --bin penmesh-proxy` and
// `npm ci --prefix client/web`):
//   node bench/busy-board.mjs [--bin target/release/penmesh] [--people 10] [--strokes 1000]
//                             [--size 140] [--planes 1] [--json OUT.json] [--profile OUT.cpuprofile]
//                             [--orbit-profile OUT.cpuprofile] [--frame-costs] [--page DIR]
//                             [--save-bundle OUT.bin]
//                             [--exports N [--export-formats glb,stl] [--no-page]]
//
// What bounds an orbit frame: `--orbit-profile` writes the first open's CPU profile during the
// orbit; `--frame-costs` times frames drawn back to back in the page (each waited for with a
// one-pixel readPixels), the view turned a little between them, as the page is and with one
// thing changed at a time (docs/performance-log.md "What bounds an orbit frame").
// `--page DIR` serves the page's script from DIR/app.js (`node client/web/build.mjs DIR` in a
// checkout of another commit) instead of the proxy's, so two pages can be paired with one
// build of the Rust; both arms of a pair should then use it (it is sent unzipped).
// `--save-bundle` keeps the board's mesh bundle as the page reads it (`GET
// .../meshes?layout=PMB3`) for bench/page-merge.mjs.
//
// `--planes 3` puts person k's strokes on plane k mod 3 (`penmesh draw --placement`, protocol
// 5): the board, the front plane standing on it through y = 350, the side plane through x = 500
// (issue 37: the board's goals with strokes on three planes).
//
// The strokes are SVC2004 and SigComp2011 signatures from ../shared/data (read in place, split
// at pen lifts by the rules of shared/src/formats.rs), each scaled to --size px across and put
// at a seeded random place on a 1000x700 board, reused in turn until there are --strokes; person
// k draws every tenth with `penmesh draw --input` against a `penmesh-proxy` on a fresh
// SQLite file. Needs Debian's Chromium (/usr/bin/chromium, or PENMESH_CHROMIUM).
import { mkdtempSync, readdirSync, readFileSync, statSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";
import { gzipSync } from "node:zlib";
import { dirname } from "node:path";
import { fileURLToPath } from "node:url";

const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  return i < 0 ? fallback : args[i + 1];
};
const root = resolve(dirname(fileURLToPath(import.meta.url)), "..");
const BIN = resolve(option("--bin", join(root, "target/release/penmesh")));
process.env.PENMESH_BIN = BIN; // before the harness reads it: its proxy and its `penmesh draw`
const { launch, log, newSession, runPenmesh, startProxy } = await import("../client/web/test/harness.mjs");
const PEOPLE = Number(option("--people", "10"));
const STROKES = Number(option("--strokes", "1000"));
const SIZE = Number(option("--size", "140"));
const JSON_OUT = option("--json", null);
const PROFILE = option("--profile", null); // the first open's CPU profile (.cpuprofile, DevTools)
const PLANES = Number(option("--planes", "1"));
const ORBIT_PROFILE = option("--orbit-profile", null);
const FRAME_COSTS = args.includes("--frame-costs");
const PAGE_DIR = option("--page", null);
const SAVE_BUNDLE = option("--save-bundle", null);
// The planes of --planes, as `penmesh draw --placement` takes them (column-major): the board,
// the front plane through y = 350, the side plane through x = 500.
const PLACEMENTS = [null, "1,0,0,0,0,0,1,0,0,-1,0,0,0,350,0,1", "0,1,0,0,0,0,1,0,1,0,0,0,500,0,0,1"];
if (!(PLANES >= 1 && PLANES <= 3)) throw new Error(`--planes takes 1, 2 or 3, not ${option("--planes")}`);
// Issue 39: time this many exports of the board through `penmesh export` (GLB, and STL with
// --export-formats glb,stl), and with --no-page stop there.
const EXPORTS = Number(option("--exports", "0"));
const EXPORT_FORMATS = option("--export-formats", "glb").split(",");
const NO_PAGE = args.includes("--no-page");
let profiled = false;
let orbitProfiled = false;
const DATA = resolve(root, "../shared/data");
const BOARD = { width: 1000, height: 700 };
const ORBIT_SECONDS = 5;
const IDLE_SECONDS = 5;

// --- the strokes: shared/src/formats.rs's rules, for the two data sets -----------------------
const SVC2004_GAP_MS = 20; // a larger gap between two samples is a pen lift
const HWR_PERIOD_MS = 5; // SigComp2011 has no timestamps: 200 Hz
const LEVELS = 1023; // pressure levels of the tablets

function readSvc2004(text) {
  const strokes = [];
  let current = [];
  let start = 0;
  let previous = null;
  for (const line of text.split(/\r?\n/).slice(1)) {
    if (!line.trim()) continue;
    const [x, y, time, button, , , pressure] = line.trim().split(/\s+/).map(Number);
    if (previous === null || (time >= previous && (button === 0 || time - previous > SVC2004_GAP_MS))) {
      if (current.length) strokes.push(current);
      current = [];
      start = time;
    }
    previous = time;
    current.push([x, y, time - start, pressure / LEVELS]);
  }
  if (current.length) strokes.push(current);
  return strokes;
}

function readHwr(text) {
  const strokes = [];
  let current = [];
  let index = 0;
  let start = 0;
  for (const line of text.split(/\r?\n/)) {
    if (!line.trim()) continue;
    const [x, y, pressure] = line.trim().split(/\s+/).map(Number);
    if (pressure === 0) {
      if (current.length) strokes.push(current);
      current = [];
    } else {
      if (!current.length) start = index;
      current.push([x, y, (index - start) * HWR_PERIOD_MS, pressure / LEVELS]);
    }
    index += 1;
  }
  if (current.length) strokes.push(current);
  return strokes;
}

function realStrokes() {
  const strokes = [];
  for (const [dir, read] of [["svc2004", readSvc2004], ["sigcomp2011_dutch", readHwr]]) {
    for (const file of readdirSync(join(DATA, dir)).filter((f) => /\.(txt|hwr)$/i.test(f)).sort()) {
      strokes.push(...read(readFileSync(join(DATA, dir, file), "utf8")));
    }
  }
  return strokes;
}

// A seeded generator (mulberry32): the same board every run.
function random(seed) {
  return () => {
    seed = (seed + 0x6d2b79f5) | 0;
    let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/// `n` strokes, each scaled to `size` px across (its larger side) and centred at a random place
/// of the board, y down as drawn.
function board(source, n, size) {
  const next = random(26);
  const out = [];
  for (let k = 0; k < n; k++) {
    const s = source[k % source.length];
    const xs = s.map((p) => p[0]);
    const ys = s.map((p) => p[1]);
    const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
    const scale = size / Math.max(x1 - x0, y1 - y0, 1);
    const cx = size / 2 + next() * (BOARD.width - size);
    const cy = size / 2 + next() * (BOARD.height - size);
    const round = (v) => Math.round(v * 100) / 100;
    out.push(s.map(([x, y, t, p]) => [round(cx + (x - (x0 + x1) / 2) * scale), round(cy + (y - (y0 + y1) / 2) * scale), t, p]));
  }
  return out;
}

// --- the browser side ---------------------------------------------------------------------
function procStat(pid) {
  try {
    const stat = readFileSync(`/proc/${pid}/stat`, "utf8");
    const fields = stat.slice(stat.lastIndexOf(")") + 2).split(" ");
    return { ppid: Number(fields[1]), ticks: Number(fields[11]) + Number(fields[12]) };
  } catch {
    return null;
  }
}

/// CPU ticks (user + system) of Chromium's processes under `pid` (this script), by process
/// type (the browser, the renderer, the GPU process, ...).
function chromiumTicks(pid) {
  const all = readdirSync("/proc").filter((d) => /^\d+$/.test(d)).map(Number);
  const parent = new Map(all.map((p) => [p, procStat(p)?.ppid]));
  const inTree = (p) => {
    for (let q = p; q; q = parent.get(q)) if (q === pid) return true;
    return false;
  };
  const byType = {};
  for (const p of all.filter(inTree)) {
    const stat = procStat(p);
    if (!stat) continue;
    let cmdline = "";
    try {
      cmdline = readFileSync(`/proc/${p}/cmdline`, "utf8");
    } catch {}
    if (!cmdline.includes("chrom")) continue;
    const type = /--type=([\w-]+)/.exec(cmdline)?.[1] ?? "browser";
    byType[type] = (byType[type] || 0) + stat.ticks;
  }
  return byType;
}
const TICKS_PER_SECOND = 100; // USER_HZ on Linux
/// Ticks of every process type in `after` less those in `before`.
const sumTicks = (after, before) => Object.keys(after).reduce((a, k) => a + after[k] - (before[k] || 0), 0);

/// Opens the session's page and measures it; `expected` meshes make the view complete.
async function measurePage(context, url, expected) {
  const page = await context.newPage();
  const cdp = await context.newCDPSession(page);
  await cdp.send("Network.enable");
  const traffic = { requests: 0, httpBytes: 0, wsBytes: 0, statuses: {} };
  cdp.on("Network.requestWillBeSent", () => (traffic.requests += 1));
  cdp.on("Network.responseReceived", (e) => (traffic.statuses[e.response.status] = (traffic.statuses[e.response.status] || 0) + 1));
  cdp.on("Network.loadingFinished", (e) => (traffic.httpBytes += e.encodedDataLength));
  // A binary frame's payload comes base64 (the page speaks binary frames, codec.js).
  const payloadBytes = ({ opcode, payloadData }) => (opcode === 2 ? Buffer.from(payloadData, "base64").length : Buffer.byteLength(payloadData));
  cdp.on("Network.webSocketFrameReceived", (e) => (traffic.wsBytes += payloadBytes(e.response)));
  cdp.on("Network.webSocketFrameSent", (e) => (traffic.wsBytes += payloadBytes(e.response)));
  page.on("pageerror", (e) => console.error("page error:", e.message));
  // The page's main-thread tasks over 50 ms (the Long Tasks API), from before its script runs.
  await page.addInitScript(() => {
    window.__longTasks = [];
    try {
      new PerformanceObserver((list) => {
        for (const e of list.getEntries()) window.__longTasks.push([Math.round(e.startTime), Math.round(e.duration)]);
      }).observe({ type: "longtask", buffered: true });
    } catch {}
  });
  if (PROFILE && !profiled) {
    await cdp.send("Profiler.enable");
    await cdp.send("Profiler.setSamplingInterval", { interval: 250 });
    await cdp.send("Profiler.start");
  }

  // Chromium's CPU time (all its processes, /proc) from here until the view is complete, and
  // per frame of the orbit: measures that a busy machine disturbs less than wall time.
  const ticksBeforeOpen = chromiumTicks(process.pid);
  await page.goto(url);
  const completeMs = await page.evaluate(
    (n) =>
      new Promise((done) => {
        const check = () =>
          window.penmesh && window.penmesh.meshes >= n
            ? requestAnimationFrame(() => requestAnimationFrame(() => done(performance.now())))
            : setTimeout(check, 10);
        check();
      }),
    expected,
  );
  const openCpuS = sumTicks(chromiumTicks(process.pid), ticksBeforeOpen) / TICKS_PER_SECOND;
  // When the script and the meshes had arrived (ms from navigation start).
  const arrived = await page.evaluate(() =>
    Object.fromEntries(
      performance
        .getEntriesByType("resource")
        .filter((e) => /\/web\/app\.js$|\/meshes(\?placements=true|\?layout=PMB3)?$/.test(e.name))
        .map((e) => [e.name.endsWith("app.js") ? "script_ms" : "bundle_ms", Math.round(e.responseEnd)]),
    ),
  );
  // The main thread's long tasks from the bundle's arrival until the view was complete: the
  // longest is the one that reads the bundle's GLBs and merges them (docs/performance-log.md,
  // "A GLB reader of our own layout").
  const longTasks = await page.evaluate(() => window.__longTasks);
  const afterBundle = longTasks.filter(([start, duration]) => start + duration >= (arrived.bundle_ms ?? 0) && start <= completeMs);
  const mainThread = {
    long_tasks_after_bundle_ms: afterBundle.reduce((a, [, d]) => a + d, 0),
    longest_task_after_bundle_ms: afterBundle.reduce((a, [, d]) => Math.max(a, d), 0),
    long_tasks: longTasks,
  };
  if (PROFILE && !profiled) {
    profiled = true;
    const { profile } = await cdp.send("Profiler.stop");
    writeFileSync(PROFILE, JSON.stringify(profile));
    log(`CPU profile of the first open (until the view was complete): ${PROFILE}`);
  }
  await page.waitForTimeout(1000); // let stragglers (late frames, acks) be counted
  await page.screenshot({ path: join(work, "busy-board-open.png") });
  const errors = await page.evaluate(() => window.penmesh.errors);

  // Orbit: a circular drag; frames are those the page rendered (or, for a page that renders
  // every animation frame, its animation frames).
  await page.click("#tool-orbit");
  await page.evaluate(() => {
    window.__rafTicks = 0;
    const tick = () => {
      window.__rafTicks += 1;
      if (!window.__stopTicks) requestAnimationFrame(tick);
    };
    if (window.penmesh.frames === undefined) requestAnimationFrame(tick);
  });
  const frames = () => page.evaluate(() => window.penmesh.frames ?? window.__rafTicks);
  const mouse = (type, x, y) => cdp.send("Input.dispatchMouseEvent", { type, x, y, button: "left", buttons: type === "mouseReleased" ? 0 : 1, clickCount: 1 });
  const orbitProfiling = ORBIT_PROFILE && !orbitProfiled;
  if (orbitProfiling) {
    orbitProfiled = true;
    await cdp.send("Profiler.enable");
    await cdp.send("Profiler.setSamplingInterval", { interval: 250 });
    await cdp.send("Profiler.start");
  }
  await mouse("mousePressed", 500, 350);
  const ticksBeforeOrbit = chromiumTicks(process.pid);
  const f0 = await frames();
  const t0 = Date.now();
  let step = 0;
  while (Date.now() - t0 < ORBIT_SECONDS * 1000) {
    step += 1;
    await mouse("mouseMoved", 500 + 200 * Math.sin(step / 20), 350 + 120 * Math.sin(step / 31));
  }
  const orbitFrames = (await frames()) - f0;
  const orbitFps = orbitFrames / ((Date.now() - t0) / 1000);
  const orbitCpuMsPerFrame = (sumTicks(chromiumTicks(process.pid), ticksBeforeOrbit) * 1000) / TICKS_PER_SECOND / Math.max(orbitFrames, 1);
  if (orbitProfiling) {
    const { profile } = await cdp.send("Profiler.stop");
    writeFileSync(ORBIT_PROFILE, JSON.stringify(profile));
    log(`CPU profile of the first orbit: ${ORBIT_PROFILE}`);
  }
  const triangles = await page.evaluate(() => window.penmesh.triangles ?? null);
  await mouse("mouseReleased", 500, 350);
  await page.evaluate(() => (window.__stopTicks = true));

  // Idle: nothing changes for IDLE_SECONDS, after the frames of the orbit are done.
  await page.waitForTimeout(3000);
  const before = chromiumTicks(process.pid);
  const idleFrames0 = await page.evaluate(() => window.penmesh.frames ?? null);
  const i0 = Date.now();
  await page.waitForTimeout(IDLE_SECONDS * 1000);
  const seconds = (Date.now() - i0) / 1000;
  const after = chromiumTicks(process.pid);
  const idleFrames1 = await page.evaluate(() => window.penmesh.frames ?? null);
  const idle = {};
  for (const type of Object.keys(after)) idle[type] = (after[type] - (before[type] || 0)) / TICKS_PER_SECOND / seconds;
  const idleCores = Object.values(idle).reduce((a, b) => a + b, 0);
  await page.screenshot({ path: join(work, "busy-board-orbited.png") });
  const frameCosts = FRAME_COSTS ? await measureFrameCosts(page) : undefined;
  await page.close();
  return {
    complete_ms: Math.round(completeMs),
    ...arrived,
    ...mainThread,
    http_bytes: traffic.httpBytes,
    ws_bytes: traffic.wsBytes,
    bytes: traffic.httpBytes + traffic.wsBytes,
    http_requests: traffic.requests,
    statuses: traffic.statuses,
    orbit_fps: Number(orbitFps.toFixed(1)),
    open_cpu_s: Number(openCpuS.toFixed(2)),
    orbit_cpu_ms_per_frame: Number(orbitCpuMsPerFrame.toFixed(1)),
    triangles, // drawn in the orbit's last frame
    idle_cores: Number(idleCores.toFixed(3)),
    idle_cores_by_process: Object.fromEntries(Object.entries(idle).map(([k, v]) => [k, Number(v.toFixed(3))])),
    idle_frames: idleFrames0 === null ? null : idleFrames1 - idleFrames0,
    frame_costs: frameCosts,
    errors,
  };
}

/// Milliseconds a frame, drawn back to back (each waited for with a one-pixel readPixels: the
/// GPU process, SwiftShader here, has drawn it), the view turned a little between frames, for
/// the page as it is and with one thing changed at a time; each variant timed in turn, ROUNDS
/// times. Both the wall time and the CPU time of Chromium's processes (all of them, from
/// /proc: a measure that a busy machine disturbs less) per frame.
async function measureFrameCosts(page) {
  const ROUNDS = 3;
  const FRAMES = 10;
  const names = await page.evaluate(() => {
    const view = window.penmesh.view;
    const gl = view.renderer.getContext();
    const pixel = new Uint8Array(4);
    const groups = view.groups.objects;
    const grid = view.world.children.find((o) => o.isLineSegments);
    const ShaderMaterial = view.material.constructor;
    const plain = new ShaderMaterial({
      vertexShader: "void main() { gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }",
      fragmentShader: "void main() { gl_FragColor = vec4(0.3, 0.3, 0.3, 1.0); }",
    });
    // One shader of the page's pair made plain at a time.
    const own = { vertexShader: view.material.vertexShader, fragmentShader: view.material.fragmentShader, uniforms: view.material.uniforms };
    const plainVertex = new ShaderMaterial({ ...own, vertexShader: "attribute vec3 colour; varying vec3 vColour; void main() { vColour = colour; gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }" });
    const plainFragment = new ShaderMaterial({ ...own, fragmentShader: "varying vec3 vColour; void main() { gl_FragColor = vec4(vColour, 1.0); }" });
    const material = (m) => [() => groups.forEach((g) => (g.material = m)), () => groups.forEach((g) => (g.material = view.material))];
    let turn = 1;
    const frame = () => {
      turn = -turn;
      view.rig.orbitBy(4 * turn, 2 * turn);
      view.renderer.render(view.scene, view.camera);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    };
    const variants = {
      as_is: [() => {}, () => {}],
      grid_hidden: [() => grid && (grid.visible = false), () => grid && (grid.visible = true)],
      canvas_100x70: [() => view.renderer.setSize(100, 70, false), () => view.resize()],
      plain_material: material(plain),
      plain_vertex_shader: material(plainVertex),
      plain_fragment_shader: material(plainFragment),
      half_the_groups: [() => groups.forEach((g, i) => (g.visible = i % 2 === 0)), () => groups.forEach((g) => (g.visible = true))],
      meshes_hidden: [() => groups.forEach((g) => (g.visible = false)), () => groups.forEach((g) => (g.visible = true))],
    };
    view.rig.orbitBy(120, -60); // a turned view: the grid shows, the strokes seen at a slant
    window.__frameCosts = { variants, frame };
    return Object.keys(variants);
  });
  const out = {};
  for (let round = 0; round < ROUNDS; round++) {
    for (const name of names) {
      const triangles = await page.evaluate((name) => {
        const { variants, frame } = window.__frameCosts;
        variants[name][0]();
        frame(); // warm: a new program is compiled here
        frame();
        return window.penmesh.view.renderer.info.render.triangles;
      }, name);
      const before = chromiumTicks(process.pid);
      const ms = await page.evaluate(
        ([name, n]) => {
          const t = performance.now();
          for (let i = 0; i < n; i++) window.__frameCosts.frame();
          const ms = (performance.now() - t) / n;
          window.__frameCosts.variants[name][1]();
          return ms;
        },
        [name, FRAMES],
      );
      const after = chromiumTicks(process.pid);
      const cpu = sumTicks(after, before);
      const entry = (out[name] ??= { triangles, wall_ms: [], cpu_ms: [] });
      entry.wall_ms.push(Number(ms.toFixed(1)));
      entry.cpu_ms.push(Number(((cpu * 1000) / TICKS_PER_SECOND / FRAMES).toFixed(1)));
    }
  }
  await page.evaluate(() => {
    window.penmesh.view.rig.orbitBy(-120, 60);
    window.penmesh.view.requestRender();
  });
  return out;
}

// --- the run ------------------------------------------------------------------------------
const work = mkdtempSync(join(tmpdir(), "penmesh-busy-board-"));
const children = [];
let browser;
try {
  const source = realStrokes();
  const strokes = board(source, STROKES, SIZE);
  log(`${source.length} real strokes, reused into ${strokes.length}, ${strokes.reduce((a, s) => a + s.length, 0)} samples`);
  const proxy = await startProxy(children);
  const session = await newSession(proxy.base);
  const drawStart = Date.now();
  // One person after the other: ten `penmesh draw` at full speed at once lose their
  // connections (each is sent the others' events faster than it reads them).
  for (let k = 0; k < PEOPLE; k++) {
    const file = join(work, `person-${k}.json`);
    writeFileSync(file, JSON.stringify(strokes.filter((_, i) => i % PEOPLE === k)));
    try {
      const placement = PLACEMENTS[k % PLANES];
      await runPenmesh(["draw", "--server", proxy.base, "--session", session.session, "--token", session.token, "--input", file, "--name", `person-${k}`, "--json", ...(placement ? ["--placement", placement] : [])], children);
    } catch (err) {
      console.error(proxy.log.split("\n").slice(-20).join("\n"));
      throw err;
    }
  }
  const auth = { authorization: `Bearer ${session.token}` };
  const list = await (await fetch(`${proxy.base}/v1/sessions/${session.session}/strokes`, { headers: auth })).json();
  const withMesh = list.strokes.filter((s) => s.has_mesh).length;
  log(`drawn by ${PEOPLE} people in ${((Date.now() - drawStart) / 1000).toFixed(1)} s: ${list.strokes.length} strokes, ${withMesh} with a mesh`);

  // The meshes as the bundle holds them (absent on a proxy without GET .../meshes).
  let meshes = null;
  const bundle = await fetch(`${proxy.base}/v1/sessions/${session.session}/meshes`, { headers: auth });
  if (bundle.ok) {
    const body = Buffer.from(await bundle.arrayBuffer());
    const { decodeMeshBundle } = await import("../client/web/src/api.js");
    const t = performance.now();
    const decoded = decodeMeshBundle(body.buffer.slice(body.byteOffset, body.byteOffset + body.length));
    const binaryDecodeMs = performance.now() - t;
    const sizes = decoded.map((m) => m.glb.byteLength).sort((a, b) => a - b);
    // The other form weighed for the bundle: JSON with base64 GLBs.
    const json = JSON.stringify({ meshes: decoded.map((m) => ({ stroke: m.stroke, participant: m.participant, glb: Buffer.from(m.glb).toString("base64") })) });
    const t2 = performance.now();
    JSON.parse(json).meshes.forEach((m) => Buffer.from(m.glb, "base64"));
    const jsonDecodeMs = performance.now() - t2;
    meshes = {
      count: decoded.length,
      glb_median: sizes[Math.floor(sizes.length / 2)],
      glb_max: sizes[sizes.length - 1],
      bundle_bytes: body.length,
      bundle_gzip_bytes: gzipSync(body).length,
      json_base64_bytes: Buffer.byteLength(json),
      json_base64_gzip_bytes: gzipSync(json).length,
      bundle_decode_ms: Number(binaryDecodeMs.toFixed(1)),
      json_base64_decode_ms: Number(jsonDecodeMs.toFixed(1)),
    };
    log("meshes:", JSON.stringify(meshes));
  }

  if (SAVE_BUNDLE) {
    const placed = await fetch(`${proxy.base}/v1/sessions/${session.session}/meshes?layout=PMB3`, { headers: auth });
    writeFileSync(SAVE_BUNDLE, Buffer.from(await placed.arrayBuffer()));
    log(`mesh bundle (PMB3): ${SAVE_BUNDLE}`);
  }

  // The board taken out through the CLI, as a user does: wall time of each `penmesh export`.
  const exportTimes = {};
  for (const format of EXPORTS > 0 ? EXPORT_FORMATS : []) {
    const out = join(work, `board.${format}`);
    const times = [];
    for (let i = 0; i < EXPORTS; i++) {
      const t = performance.now();
      await runPenmesh(["export", "--server", proxy.base, "--session", session.session, "--token", session.token, "--format", format, "--out", out], children);
      times.push(Math.round(performance.now() - t));
    }
    exportTimes[format] = { ms: times, bytes: statSync(out).size, file: out };
    log(`export ${format}: ${times.join(", ")} ms, ${statSync(out).size} bytes (${out})`);
  }
  if (NO_PAGE) {
    if (JSON_OUT) writeFileSync(JSON_OUT, JSON.stringify({ bin: BIN, people: PEOPLE, strokes: STROKES, size: SIZE, meshes, exports: exportTimes }, null, 2));
    for (const c of children) if (c.exitCode === null) c.kill("SIGTERM");
    process.exit(0);
  }

  browser = await launch();
  const context = await browser.newContext({ viewport: { width: BOARD.width, height: BOARD.height }, deviceScaleFactor: 1 });
  if (PAGE_DIR) {
    const script = readFileSync(join(PAGE_DIR, "app.js"));
    await context.route("**/web/app.js", (route) => route.fulfill({ status: 200, contentType: "text/javascript", body: script }));
  }
  const url = `${proxy.base}/s/${session.session}#token=${session.token}`;
  const first = await measurePage(context, url, withMesh);
  log("opened:", JSON.stringify(first));
  // Again in the same browser: what its HTTP cache saves.
  const again = await measurePage(context, url, withMesh);
  log("reopened:", JSON.stringify(again));

  const goals = [
    ["view complete", `${first.complete_ms} ms`, first.complete_ms <= 1500, "<= 1500 ms"],
    ["transferred", `${(first.bytes / 1e6).toFixed(2)} MB (${(first.http_bytes / 1e6).toFixed(2)} HTTP, ${(first.ws_bytes / 1e6).toFixed(2)} WebSocket)`, first.bytes <= 2.5e6, "<= 2.5 MB"],
    ["requests", `${first.http_requests} HTTP + 1 WebSocket`, first.http_requests <= 10, "<= 10"],
    ["orbit", `${first.orbit_fps} fps`, first.orbit_fps >= 10, ">= 10 fps"],
    ["idle CPU", `${first.idle_cores} cores`, first.idle_cores <= 0.05, "<= 0.05 core"],
  ];
  console.log("\n| what | measured | goal | met |\n|---|---|---|---|");
  for (const [what, value, met, goal] of goals) console.log(`| ${what} | ${value} | ${goal} | ${met ? "yes" : "no"} |`);
  if (JSON_OUT) writeFileSync(JSON_OUT, JSON.stringify({ bin: BIN, people: PEOPLE, strokes: STROKES, size: SIZE, meshes, exports: exportTimes, first, again }, null, 2));
  log(`screenshots: ${work}/busy-board-{open,orbited}.png`);
} finally {
  for (const c of children) if (c.exitCode === null) c.kill("SIGTERM");
  if (browser) await browser.close();
}
