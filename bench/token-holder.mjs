// What one token holder can cost everyone (issue 35), measured against a release proxy on a
// fresh SQLite file, through the real protocol (JSON WebSocket frames, HTTP):
//
//   late-watchers: 1,000 strokes, one taken back, then 10 watchers join; 30 uploads of a small
//     GLB for the stroke taken back, then the same 30 for a stroke not taken back. For each:
//     the session resyncs (full-history reads, the proxy's `penmesh_fanout_syncs_total`), the
//     messages the watchers got, and the proxy's CPU (utime + stime from /proc).
//   bundle: 52 strokes with a 1 MB mesh each (a 52 MB bundle); 8 requests for the bundle at
//     once (gzip accepted, as browsers do), the proxy's RSS sampled every 10 ms (VmRSS); then
//     200 revalidations (If-None-Match, 304) one after another, their median and the proxy's
//     CPU per revalidation.
//
// Usage (from the repository root, after `cargo build --release -p penmesh-proxy`):
//   node --experimental-websocket bench/token-holder.mjs [late-watchers|bundle|both]
//        [--bin target/release/penmesh-proxy]
// Prints one JSON object per part.
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve, dirname } from "node:path";
import { fileURLToPath } from "node:url";
import { randomUUID, randomBytes } from "node:crypto";
import { plainGlb as glb } from "./plain-glb.mjs";

const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  return i < 0 ? fallback : args[i + 1];
};
const part = args[0] && !args[0].startsWith("--") ? args[0] : "both";
const root = resolve(dirname(fileURLToPath(import.meta.url)), "..");
const BIN = resolve(option("--bin", join(root, "target/release/penmesh-proxy")));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function startProxy() {
  const work = mkdtempSync(join(tmpdir(), "penmesh-token-holder-"));
  const port = 20000 + Math.floor(Math.random() * 20000);
  const proc = spawn(BIN, ["--host", "127.0.0.1", "--port", String(port), "--database-url", `sqlite://${work}/db.sqlite`], {
    stdio: ["ignore", "ignore", "pipe"],
    env: { ...process.env, RUST_LOG: "warn" },
  });
  let log = "";
  proc.stderr.on("data", (d) => (log += d));
  const base = `http://127.0.0.1:${port}`;
  for (let i = 0; i < 100; i++) {
    try {
      if ((await fetch(`${base}/readyz`)).ok) break;
    } catch {}
    await sleep(100);
  }
  const stop = () => {
    proc.kill("SIGKILL");
    rmSync(work, { recursive: true, force: true });
  };
  return { base, port, pid: proc.pid, stop, log: () => log };
}

/// utime + stime of `pid`, in seconds.
function cpuSeconds(pid) {
  const stat = readFileSync(`/proc/${pid}/stat`, "utf8");
  const fields = stat.slice(stat.lastIndexOf(")") + 2).split(" ");
  return (Number(fields[11]) + Number(fields[12])) / 100;
}

function rssMb(pid) {
  const status = readFileSync(`/proc/${pid}/status`, "utf8");
  return Number(/VmRSS:\s+(\d+)/.exec(status)[1]) / 1024;
}

async function metric(base, name) {
  const text = await (await fetch(`${base}/metrics`)).text();
  const line = text.split("\n").find((l) => l.startsWith(name + " ") || l.startsWith(name + "{"));
  return line ? Number(line.split(" ").pop()) : 0;
}

/// A JSON WebSocket participant: says hello and counts what it receives.
async function joinSession(proxy, session, token, name, key = randomBytes(16).toString("hex")) {
  const ws = new WebSocket(`ws://127.0.0.1:${proxy.port}/v1/sessions/${session}/ws`, ["penmesh", `penmesh.token.${token}`]);
  const p = { ws, key, received: 0, synced: 0, done: new Set(), waiters: [] };
  ws.onmessage = (e) => {
    const msg = JSON.parse(e.data);
    p.received++;
    if (msg.synced) p.synced++;
    if (msg.stroke_done) p.done.add(msg.stroke_done.stroke);
    if (msg.error && msg.error.code !== "lagged") console.error(name, JSON.stringify(msg.error));
    p.waiters = p.waiters.filter((w) => !w());
  };
  await new Promise((r, j) => ((ws.onopen = r), (ws.onerror = j)));
  ws.send(JSON.stringify({ hello: { protocol: 4, client: "token-holder", name, resume: [], key } }));
  await until(p, () => p.synced >= 1);
  return p;
}

const until = (p, cond) => (cond() ? Promise.resolve() : new Promise((r) => p.waiters.push(() => cond() && (r(), true))));

/// Draws `n` strokes of 12 samples each, 16 in flight at a time.
async function drawStrokes(p, n) {
  const ids = [];
  for (let k = 0; k < n; k++) {
    const stroke = randomUUID();
    ids.push(stroke);
    const points = Array.from({ length: 12 }, (_, i) => [50 + (k % 40) * 20 + i * 1.5, 50 + Math.floor(k / 40) * 20 + (i % 3), i * 8, 0.5]);
    p.ws.send(JSON.stringify({ stroke_begin: { stroke } }));
    p.ws.send(JSON.stringify({ points: { stroke, seq: 0, points } }));
    p.ws.send(JSON.stringify({ stroke_end: { stroke, n_points: points.length } }));
    if (k >= 16) await until(p, () => p.done.size >= k - 15);
  }
  await until(p, () => p.done.size >= n);
  return ids;
}

async function newSession(proxy) {
  return (await fetch(`${proxy.base}/v1/sessions`, { method: "POST" })).json();
}

const asDrawer = (token, key, extra = {}) => ({ authorization: `Bearer ${token}`, "x-penmesh-key": key, ...extra });

async function putMesh(proxy, token, key, stroke, body) {
  const res = await fetch(`${proxy.base}/v1/strokes/${stroke}/mesh`, {
    method: "PUT",
    headers: asDrawer(token, key, { "content-type": "model/gltf-binary" }),
    body,
  });
  if (!res.ok) throw new Error(`PUT mesh: ${res.status} ${await res.text()}`);
}

async function lateWatchers() {
  const proxy = await startProxy();
  try {
    const { session, token } = await newSession(proxy);
    const drawer = await joinSession(proxy, session, token, "drawer");
    const strokes = await drawStrokes(drawer, 1000);
    const [taken, kept] = strokes;
    const res = await fetch(`${proxy.base}/v1/strokes/${taken}`, { method: "DELETE", headers: asDrawer(token, drawer.key) });
    if (res.status !== 204) throw new Error(`DELETE: ${res.status}`);
    const watchers = [];
    for (let i = 0; i < 10; i++) watchers.push(await joinSession(proxy, session, token, `watcher ${i}`));
    const small = glb(3);
    const measure = async (stroke) => {
      await sleep(500);
      const [syncs, cpu, received] = [await metric(proxy.base, "penmesh_fanout_syncs_total"), cpuSeconds(proxy.pid), watchers.reduce((s, w) => s + w.received, 0)];
      const start = performance.now();
      for (let i = 0; i < 30; i++) await putMesh(proxy, token, drawer.key, stroke, small);
      await sleep(1000); // the watchers' resyncs, if any, run after the uploads are answered
      return {
        resyncs: (await metric(proxy.base, "penmesh_fanout_syncs_total")) - syncs,
        proxy_cpu_s: +(cpuSeconds(proxy.pid) - cpu).toFixed(2),
        uploads_s: +((performance.now() - start) / 1000).toFixed(2),
        messages_to_watchers: watchers.reduce((s, w) => s + w.received, 0) - received,
      };
    };
    const removed = await measure(taken);
    const notRemoved = await measure(kept);
    const before = watchers.reduce((s, w) => s + w.received, 0);
    const restore = await fetch(`${proxy.base}/v1/strokes/${taken}/restore`, { method: "POST", headers: asDrawer(token, drawer.key) });
    if (restore.status !== 204) throw new Error(`restore: ${restore.status}`);
    await sleep(500);
    console.log(JSON.stringify({
      part: "late-watchers", strokes: 1000, watchers: 10, uploads: 30, glb_bytes: small.length,
      for_a_stroke_taken_back: removed, for_a_stroke_not_taken_back: notRemoved,
      restore: { messages_to_watchers: watchers.reduce((s, w) => s + w.received, 0) - before, synced_per_watcher: watchers.map((w) => w.synced) },
      warnings_logged: (proxy.log().match(/WARN/g) || []).length,
    }));
    for (const w of [drawer, ...watchers]) w.ws.close();
  } finally {
    proxy.stop();
  }
}

async function bundle() {
  const proxy = await startProxy();
  try {
    const { session, token } = await newSession(proxy);
    const drawer = await joinSession(proxy, session, token, "drawer");
    const strokes = await drawStrokes(drawer, 52);
    const mesh = glb(87381 - (87381 % 3)); // 1 MB
    for (const stroke of strokes) await putMesh(proxy, token, drawer.key, stroke, mesh);
    const url = `${proxy.base}/v1/sessions/${session}/meshes`;
    const get = async (extra = {}) => {
      const start = performance.now();
      const res = await fetch(url, { headers: { authorization: `Bearer ${token}`, ...extra } });
      const bytes = (await res.arrayBuffer()).byteLength;
      return { status: res.status, etag: res.headers.get("etag"), bytes, ms: performance.now() - start };
    };
    const first = await get({ "accept-encoding": "identity" });
    await sleep(500);
    const rssBefore = rssMb(proxy.pid);
    let peak = rssBefore;
    const sampler = setInterval(() => (peak = Math.max(peak, rssMb(proxy.pid))), 10);
    const start = performance.now();
    const answers = await Promise.all(Array.from({ length: 8 }, () => get({ "accept-encoding": "gzip" })));
    const wall = performance.now() - start;
    clearInterval(sampler);
    await sleep(5000); // the checkpoint of the uploads' log and the like, before the 304s are timed
    const cpu = cpuSeconds(proxy.pid);
    const times = [];
    for (let i = 0; i < 200; i++) {
      const r = await get({ "if-none-match": first.etag, "accept-encoding": "identity" });
      if (r.status !== 304) throw new Error(`revalidation: ${r.status}`);
      times.push(r.ms);
    }
    const cpu304 = cpuSeconds(proxy.pid) - cpu;
    // The same for a session without meshes: what a request costs whatever the bundle.
    const empty = await newSession(proxy);
    const emptyUrl = `${proxy.base}/v1/sessions/${empty.session}/meshes`;
    const emptyTag = (await fetch(emptyUrl, { headers: { authorization: `Bearer ${empty.token}` } })).headers.get("etag");
    const cpuEmpty = cpuSeconds(proxy.pid);
    for (let i = 0; i < 200; i++) {
      const r = await fetch(emptyUrl, { headers: { authorization: `Bearer ${empty.token}`, "if-none-match": emptyTag } });
      await r.arrayBuffer();
    }
    const cpuEmpty304 = cpuSeconds(proxy.pid) - cpuEmpty;
    times.sort((a, b) => a - b);
    console.log(JSON.stringify({
      part: "bundle", meshes: strokes.length, bundle_bytes: first.bytes,
      concurrent: { requests: 8, statuses: answers.map((a) => a.status), wall_s: +(wall / 1000).toFixed(2), rss_before_mb: Math.round(rssBefore), rss_peak_mb: Math.round(peak) },
      revalidation_304: { n: 200, median_ms: +times[100].toFixed(2), p95_ms: +times[190].toFixed(2), proxy_cpu_ms_each: +((cpu304 * 1000) / 200).toFixed(2), empty_session_proxy_cpu_ms_each: +((cpuEmpty304 * 1000) / 200).toFixed(2) },
    }));
    drawer.ws.close();
  } finally {
    proxy.stop();
  }
}

if (part === "late-watchers" || part === "both") await lateWatchers();
if (part === "bundle" || part === "both") await bundle();
process.exit(0);
