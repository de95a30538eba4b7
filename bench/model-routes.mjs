// What one token holder or a stranger can cost everyone through the model routes (issue 49),
// measured against a release proxy on a fresh SQLite file, with a canary: another session's
// participant drawing 12-sample strokes one after another, its acks timed (p50/p99/max ms).
//
//   wrong-token: 96 connections each send PUT /v1/strokes/{id}/placement with a wrong token and
//     a 15 MiB body; their statuses and the proxy's RSS before, at most, and after.
//   prints: a 20,000-sample zigzag and 160 duplicates side by side; 8 print requests, each
//     dropped by its client after 3 s; the answers (503 busy or dropped), the proxy's CPU
//     seconds while they ran and in the 5 s after the last client left, RSS at most.
//   duplicates: a 1,000,000-sample stroke; 64 duplicates of it asked at once; their statuses,
//     RSS at most, the canary meanwhile.
//   scenes: a 20,000-sample zigzag (every sample retained) with 250 duplicates (the review's
//     session), then with 49 (1,000,000 samples, the bound); 2 scene exports at once of each;
//     statuses, RSS at most.
//   race: 30 pairs of duplicates of two strokes naming the same new id at once; the statuses,
//     and whether the stored stroke's raw samples are exactly one source's.
//   retry: a long random walk (--walk samples, 400,000 by default) and 9 duplicates beside it;
//     a client asks for the print and, answered 408, asks again at once (503 busy: after a
//     second), until the file or 240 s; each answer's status and time, the proxy's CPU seconds
//     until the file, the prints it made (/metrics), then the same request again.
//   history: 20,000 moves of one stroke, then 16 readers following its placement history page
//     by page for 10 s; their statuses, RSS at most, the canary meanwhile.
//   bundle: a stroke with a 1 MiB mesh (PUT …/mesh) and 100 duplicates of it; for each layout
//     the proxy serves of PMB2 (what pages asked before) and PMB3 (what they ask now), on a proxy
//     of its own: one request's body size and time, then 4 requests at once (gzip accepted, as
//     browsers do: the bytes sent), RSS before and at most. The mesh's positions are scattered,
//     so gzip shrinks it about as little as a real mesh.
//   watchers: a 20,000-sample zigzag (every sample retained) and 8 JSON watchers reading, then
//     200 duplicates of it asked by one client as fast as it can (4 at a time; a 429 or 503
//     tries again after its Retry-After); the time to make them, the refusals, and per watcher
//     its `lagged` errors, whether it was dropped, and the lag of each duplicate (from its 201
//     to the watcher holding it done).
//
// Usage (from the repository root, after `cargo build --release -p penmesh-proxy`):
//   node --experimental-websocket bench/model-routes.mjs [part ...] [--bin target/release/penmesh-proxy]
//     [--timeout-secs 30] (the proxy's --request-timeout-secs) [--walk 400000] (the retry part's)
// Prints one JSON object per part.
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve, dirname } from "node:path";
import { fileURLToPath } from "node:url";
import { randomUUID, randomBytes } from "node:crypto";
import net from "node:net";
import http from "node:http";
import { plainGlb } from "./plain-glb.mjs";

const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  return i < 0 ? fallback : args[i + 1];
};
const parts = args.filter((a, i) => !a.startsWith("--") && !(i > 0 && args[i - 1].startsWith("--")));
const root = resolve(dirname(fileURLToPath(import.meta.url)), "..");
const BIN = resolve(option("--bin", join(root, "target/release/penmesh-proxy")));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/// The proxy on a fresh SQLite file, with `extra` flags.
async function startProxy(extra = []) {
  const work = mkdtempSync(join(tmpdir(), "penmesh-model-routes-"));
  const port = 20000 + Math.floor(Math.random() * 20000);
  const timeout = option("--timeout-secs", "30");
  const settings = ["--port", String(port), "--database-url", `sqlite://${work}/db.sqlite`, "--request-timeout-secs", timeout, ...extra];
  const proc = spawn(BIN, ["--host", "127.0.0.1", ...settings], {
    stdio: ["ignore", "ignore", "pipe"],
    env: { ...process.env, RUST_LOG: "warn" },
  });
  proc.stderr.on("data", () => {});
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
  return { base, port, pid: proc.pid, stop };
}

function cpuSeconds(pid) {
  const stat = readFileSync(`/proc/${pid}/stat`, "utf8");
  const fields = stat.slice(stat.lastIndexOf(")") + 2).split(" ");
  return (Number(fields[11]) + Number(fields[12])) / 100;
}

function rssMb(pid) {
  const status = readFileSync(`/proc/${pid}/status`, "utf8");
  return Number(/VmRSS:\s+(\d+)/.exec(status)[1]) / 1024;
}

/// Samples the proxy's RSS every 10 ms until stopped; the largest seen.
function rssPeak(pid) {
  let peak = rssMb(pid);
  const timer = setInterval(() => (peak = Math.max(peak, rssMb(pid))), 10);
  return () => (clearInterval(timer), Math.round(Math.max(peak, rssMb(pid))));
}

const until = (p, cond) => (cond() ? Promise.resolve() : new Promise((r) => p.waiters.push(() => cond() && (r(), true))));

/// A JSON WebSocket participant that has said hello.
async function join_(proxy, session, token, key = randomBytes(16).toString("hex")) {
  const ws = new WebSocket(`ws://127.0.0.1:${proxy.port}/v1/sessions/${session}/ws`, ["penmesh", `penmesh.token.${token}`]);
  const p = { ws, key, token, synced: 0, acks: new Map(), done: new Set(), waiters: [] };
  ws.onmessage = (e) => {
    const msg = JSON.parse(e.data);
    if (msg.synced) p.synced++;
    if (msg.ack) p.acks.set(msg.ack.stroke, msg.ack.upto_seq);
    if (msg.stroke_done) p.done.add(msg.stroke_done.stroke);
    if (msg.error && msg.error.code !== "lagged") console.error(JSON.stringify(msg.error));
    p.waiters = p.waiters.filter((w) => !w());
  };
  await new Promise((r, j) => ((ws.onopen = r), (ws.onerror = j)));
  ws.send(JSON.stringify({ hello: { protocol: 5, client: "model-routes", resume: [], key } }));
  await until(p, () => p.synced >= 1);
  return p;
}

async function newSession(proxy) {
  return (await fetch(`${proxy.base}/v1/sessions`, { method: "POST" })).json();
}

/// Draws one stroke of `n` samples along a wide, slow curve (few retained), 4,096 a batch;
/// with `wiggle`, zigzagging that many px across it (about every sample retained).
async function drawLong(p, n, dx = 0, wiggle = 0) {
  const stroke = randomUUID();
  p.ws.send(JSON.stringify({ stroke_begin: { stroke } }));
  for (let seq = 0; seq < n; seq += 4096) {
    const points = [];
    for (let i = seq; i < Math.min(n, seq + 4096); i++) {
      const a = (i / n) * Math.PI;
      const y = 400 * Math.sin(a) + (i % 2 ? wiggle : -wiggle);
      points.push([Math.round((dx + 400 * Math.cos(a)) * 16) / 16, Math.round(y * 16) / 16, i, 0.5]);
    }
    p.ws.send(JSON.stringify({ points: { stroke, seq, points } }));
    if (seq >= 64 * 4096) await until(p, () => (p.acks.get(stroke) ?? 0) >= seq - 32 * 4096);
  }
  await until(p, () => (p.acks.get(stroke) ?? 0) >= n);
  p.ws.send(JSON.stringify({ stroke_end: { stroke, n_points: n } }));
  await until(p, () => p.done.has(stroke));
  return stroke;
}

/// A participant of a session of its own drawing 12-sample strokes one after another, each
/// stroke's points timed to their ack, until stopped: then p50, p99, max (ms).
async function canary(proxy) {
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const times = [];
  let running = true;
  const loop = (async () => {
    for (let k = 0; running; k++) {
      const stroke = randomUUID();
      const points = Array.from({ length: 12 }, (_, i) => [50 + (k % 40) * 2 + i, 50 + (i % 3), i * 8, 0.5]);
      p.ws.send(JSON.stringify({ stroke_begin: { stroke } }));
      const sent = performance.now();
      p.ws.send(JSON.stringify({ points: { stroke, seq: 0, points } }));
      await until(p, () => (p.acks.get(stroke) ?? 0) >= 12);
      times.push(performance.now() - sent);
      p.ws.send(JSON.stringify({ stroke_end: { stroke, n_points: 12 } }));
      await sleep(20);
    }
  })();
  return async () => {
    running = false;
    await loop;
    p.ws.close();
    times.sort((a, b) => a - b);
    const q = (f) => Math.round(times[Math.min(times.length - 1, Math.floor(f * times.length))] * 10) / 10;
    return { acks: times.length, p50: q(0.5), p99: q(0.99), max: Math.round(times[times.length - 1] ?? 0) };
  };
}

const drawer = (p, extra = {}) => ({ authorization: `Bearer ${p.token}`, "x-penmesh-key": p.key, ...extra });

async function duplicate(proxy, p, source, body) {
  const res = await fetch(`${proxy.base}/v1/strokes/${source}/duplicate`, {
    method: "POST",
    headers: drawer(p, { "content-type": "application/json" }),
    body: JSON.stringify(body),
  });
  return [res.status, await res.json().catch(() => null)];
}

const at = (x, y) => ({ matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, x, y, 0, 1] });

async function wrongToken() {
  const proxy = await startProxy();
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const stroke = await drawLong(p, 200);
  const before = Math.round(rssMb(proxy.pid));
  const peak = rssPeak(proxy.pid);
  const body = Buffer.alloc(15 << 20, 0x20);
  const one = () =>
    new Promise((resolve) => {
      const socket = net.connect(proxy.port, "127.0.0.1", () => {
        socket.write(
          `PUT /v1/strokes/${stroke}/placement HTTP/1.1\r\nhost: x\r\nauthorization: Bearer ${"f".repeat(64)}\r\n` +
            `content-type: application/json\r\ncontent-length: ${body.length}\r\n\r\n`,
        );
        socket.write(body);
      });
      let answer = "";
      socket.on("data", (d) => {
        answer += d;
        if (answer.includes("\r\n")) (socket.destroy(), resolve(answer.split(" ")[1]));
      });
      socket.on("error", () => resolve(answer.split(" ")[1] ?? "error"));
      socket.on("close", () => resolve(answer.split(" ")[1] ?? "closed"));
    });
  const statuses = await Promise.all(Array.from({ length: 96 }, one));
  const most = peak();
  await sleep(1000);
  const after = Math.round(rssMb(proxy.pid));
  const counts = {};
  for (const s of statuses) counts[s] = (counts[s] ?? 0) + 1;
  proxy.stop();
  // "error": the proxy answered and closed while the client still sent its body.
  return { part: "wrong-token", statuses: counts, rss_mb: { before, most, after } };
}

// The parts below measure what a session of many duplicates or moves costs, not how fast they
// may be made: the rates of duplicates and moves are off (`--… 0`).
const UNLIMITED = ["--duplicate-samples-per-second", "0", "--move-rate-per-second", "0"];

async function prints() {
  const proxy = await startProxy(UNLIMITED);
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawLong(p, 20000, 0, 3);
  for (let i = 0; i < 160; i++) {
    const [status] = await duplicate(proxy, p, source, { placement: at((i % 16) * 60, Math.floor(i / 16) * 60) });
    if (status !== 201) throw new Error(`duplicate ${status}`);
  }
  const done = await canary(proxy);
  const peak = rssPeak(proxy.pid);
  const cpu0 = cpuSeconds(proxy.pid);
  const answers = await Promise.all(
    Array.from({ length: 8 }, async () => {
      const controller = new AbortController();
      setTimeout(() => controller.abort(), 3000);
      try {
        const res = await fetch(`${proxy.base}/v1/sessions/${session}/export?format=stl`, {
          headers: { authorization: `Bearer ${token}` },
          signal: controller.signal,
        });
        await res.arrayBuffer();
        return String(res.status);
      } catch {
        return "dropped";
      }
    }),
  );
  const left = cpuSeconds(proxy.pid);
  await sleep(5000);
  const after = cpuSeconds(proxy.pid);
  const counts = {};
  for (const s of answers) counts[s] = (counts[s] ?? 0) + 1;
  const result = {
    part: "prints",
    answers: counts,
    cpu_s_while_asked: Math.round((left - cpu0) * 10) / 10,
    cpu_s_in_5_s_after_the_last_left: Math.round((after - left) * 10) / 10,
    rss_mb_most: peak(),
    canary_ms: await done(),
  };
  proxy.stop();
  return result;
}

/// Draws one stroke of `n` samples as a seeded random walk (1.5 px a step, its heading turning
/// a little each step, kept within a 900 px square; the pressure a slow wave), 4,096 a batch.
async function drawWalk(p, n, seed = 7) {
  let state = seed;
  const random = () => ((state = (state * 1103515245 + 12345) % 2147483648) / 2147483648);
  const stroke = randomUUID();
  p.ws.send(JSON.stringify({ stroke_begin: { stroke } }));
  let [x, y, heading] = [450, 450, 0];
  for (let seq = 0; seq < n; seq += 4096) {
    const points = [];
    for (let i = seq; i < Math.min(n, seq + 4096); i++) {
      heading += (random() - 0.5) * 0.08;
      x += 1.5 * Math.cos(heading);
      y += 1.5 * Math.sin(heading);
      if (x < 0 || x > 900) heading = Math.PI - heading;
      if (y < 0 || y > 900) heading = -heading;
      x = Math.min(900, Math.max(0, x));
      y = Math.min(900, Math.max(0, y));
      points.push([Math.round(x * 16) / 16, Math.round(y * 16) / 16, i, 0.5 + 0.2 * Math.sin(i / 500)]);
    }
    p.ws.send(JSON.stringify({ points: { stroke, seq, points } }));
    if (seq >= 64 * 4096) await until(p, () => (p.acks.get(stroke) ?? 0) >= seq - 32 * 4096);
  }
  await until(p, () => (p.acks.get(stroke) ?? 0) >= n);
  p.ws.send(JSON.stringify({ stroke_end: { stroke, n_points: n } }));
  await until(p, () => p.done.has(stroke));
  return stroke;
}

/// The proxy's `penmesh_prints_total{answer="made"}` (null from a proxy without it).
async function printsMade(proxy) {
  const text = await (await fetch(`${proxy.base}/metrics`)).text();
  const line = text.split("\n").find((l) => l.startsWith('penmesh_prints_total{answer="made"}'));
  return line ? Number(line.split(" ").pop()) : null;
}

async function retry() {
  const proxy = await startProxy();
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawWalk(p, Number(option("--walk", 400000)));
  for (let i = 1; i <= 9; i++) {
    const [status] = await duplicate(proxy, p, source, { placement: at(i * 300, (i % 3) * 300) });
    if (status !== 201) throw new Error(`duplicate ${status}`);
  }
  console.error(`walk drawn and duplicated`);
  const url = `${proxy.base}/v1/sessions/${session}/export?format=stl`;
  const ask = async () => {
    const started = performance.now();
    const res = await fetch(url, { headers: { authorization: `Bearer ${token}` } });
    const body = Buffer.from(await res.arrayBuffer());
    return { status: res.status, s: Math.round((performance.now() - started) / 100) / 10, body };
  };
  const cpu0 = cpuSeconds(proxy.pid);
  const t0 = performance.now();
  const answers = [];
  let file = null;
  while (!file && performance.now() - t0 < 240000) {
    const { status, s, body } = await ask();
    answers.push(`${status} after ${s} s`);
    if (status === 200) file = body;
    else if (status === 503) await sleep(1000);
    else if (status !== 408) throw new Error(`${status}: ${body}`);
  }
  const delivered_s = file ? Math.round((performance.now() - t0) / 100) / 10 : null;
  const cpu_s = Math.round((cpuSeconds(proxy.pid) - cpu0) * 10) / 10;
  const again = file ? await ask() : null;
  const result = {
    part: "retry",
    answers,
    delivered_s,
    stl_bytes: file?.length ?? null,
    cpu_s,
    prints_made: await printsMade(proxy),
    asked_again: again && { status: again.status, s: again.s, same_bytes: again.body.equals(file) },
  };
  proxy.stop();
  return result;
}

async function duplicates() {
  const proxy = await startProxy(UNLIMITED);
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawLong(p, 1_000_000);
  const before = Math.round(rssMb(proxy.pid));
  const done = await canary(proxy);
  await sleep(1000);
  const peak = rssPeak(proxy.pid);
  const started = performance.now();
  const answers = await Promise.all(Array.from({ length: 64 }, (_, i) => duplicate(proxy, p, source, { placement: at(i, 0) })));
  const seconds = Math.round((performance.now() - started) / 100) / 10;
  await sleep(1000);
  const counts = {};
  for (const [s] of answers) counts[s] = (counts[s] ?? 0) + 1;
  const result = { part: "duplicates", answers: counts, seconds, rss_mb: { before, most: peak() }, canary_ms: await done() };
  proxy.stop();
  return result;
}

/// Two scene exports at once of a session of one 20,000-sample zigzag (every sample retained)
/// and `copies` duplicates of it.
async function scenesOf(copies) {
  const proxy = await startProxy(UNLIMITED);
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawLong(p, 20000, 0, 3);
  for (let i = 0; i < copies; i++) {
    const [status] = await duplicate(proxy, p, source, { placement: at(i, i) });
    if (status !== 201) throw new Error(`duplicate ${status}`);
  }
  const info = await (await fetch(`${proxy.base}/v1/sessions/${session}/strokes`, { headers: { authorization: `Bearer ${token}` } })).json();
  const retained = info.strokes.reduce((n, s) => n + s.n_retained, 0);
  const before = Math.round(rssMb(proxy.pid));
  const peak = rssPeak(proxy.pid);
  const answers = await Promise.all(
    [0, 1].map(async () => {
      const res = await fetch(`${proxy.base}/v1/sessions/${session}/export?format=glb`, { headers: { authorization: `Bearer ${token}` } });
      const body = await res.arrayBuffer();
      return [res.status, body.byteLength];
    }),
  );
  const most = peak();
  await sleep(1000);
  const result = { part: `scenes of ${copies + 1} strokes`, retained, answers, rss_mb: { before, most, after: Math.round(rssMb(proxy.pid)) } };
  proxy.stop();
  return result;
}

/// The review's session (250 duplicates), then one at the bound (1,000,000 samples).
async function scenes() {
  const review = await scenesOf(250);
  console.log(JSON.stringify(review));
  return scenesOf(49);
}

async function race() {
  const proxy = await startProxy();
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const q = { ...p, key: randomBytes(16).toString("hex") };
  const a = await drawLong(p, 3000);
  const b = await drawLong(p, 6000, 900);
  const raw = async (id) => (await (await fetch(`${proxy.base}/v1/strokes/${id}/raw`, { headers: drawer(p) })).json()).samples;
  const [rawA, rawB] = [JSON.stringify(await raw(a)), JSON.stringify(await raw(b))];
  const tally = { "201+409": 0, other: 0, whole: 0, mixed: 0 };
  for (let i = 0; i < 30; i++) {
    const id = randomUUID();
    const [x, y] = await Promise.all([
      duplicate(proxy, p, a, { stroke: id, placement: at(i, 0) }),
      duplicate(proxy, q, b, { stroke: id, placement: at(i, 0) }),
    ]);
    const statuses = [x[0], y[0]].sort().join("+");
    tally[statuses === "201+409" ? "201+409" : "other"]++;
    const stored = JSON.stringify(await raw(id));
    tally[stored === (x[0] === 201 ? rawA : rawB) ? "whole" : "mixed"]++;
  }
  proxy.stop();
  return { part: "race", pairs: tally };
}

/// 20,000 moves of one stroke (16 clients moving it at once), then 16 readers each following
/// its whole placement history, page by page, over and over for 10 s, while the canary draws.
async function history() {
  const proxy = await startProxy(UNLIMITED);
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const stroke = await drawLong(p, 200);
  const started = performance.now();
  let next = 0;
  await Promise.all(
    Array.from({ length: 16 }, async () => {
      while (next < 20000) {
        const k = next++;
        const res = await fetch(`${proxy.base}/v1/strokes/${stroke}/placement`, {
          method: "PUT",
          headers: drawer(p, { "content-type": "application/json" }),
          body: JSON.stringify(at(k, 0)),
        });
        if (res.status !== 204) throw new Error(`move ${res.status}`);
      }
    }),
  );
  const moving_s = Math.round((performance.now() - started) / 100) / 10;
  const done = await canary(proxy);
  await sleep(1000);
  const peak = rssPeak(proxy.pid);
  const until_ = performance.now() + 10000;
  const statuses = {};
  let pages = 0;
  await Promise.all(
    Array.from({ length: 16 }, async () => {
      while (performance.now() < until_) {
        let from = 0;
        while (from !== undefined) {
          const res = await fetch(`${proxy.base}/v1/strokes/${stroke}/placements?from=${from}`, { headers: drawer(p) });
          statuses[res.status] = (statuses[res.status] ?? 0) + 1;
          const body = await res.json();
          pages++;
          from = res.status === 200 ? body.next : undefined;
        }
      }
    }),
  );
  const result = { part: "history", moves: 20000, moving_s, pages_read: pages, statuses, rss_mb_most: peak(), canary_ms: await done() };
  proxy.stop();
  return result;
}

/// The mesh bundle of a stroke with a 1 MiB mesh and 100 duplicates, in `query`'s layout.
async function bundleOf(query) {
  const proxy = await startProxy();
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawLong(p, 200);
  const mesh = plainGlb(87381 - (87381 % 3), true); // 1 MiB, which gzip shrinks little
  const put = await fetch(`${proxy.base}/v1/strokes/${source}/mesh`, { method: "PUT", headers: drawer(p, { "content-type": "model/gltf-binary" }), body: mesh });
  if (!put.ok) throw new Error(`PUT mesh: ${put.status} ${await put.text()}`);
  for (let k = 1; k <= 100; k++) {
    const [status] = await duplicate(proxy, p, source, { placement: at(50 * k, 0) });
    if (status !== 201) throw new Error(`duplicate ${k}: ${status}`);
  }
  const url = `${proxy.base}/v1/sessions/${session}/meshes${query}`;
  // The body as sent (gzipped or not: node:http leaves it as it came).
  const get = (gzip) =>
    new Promise((ok, fail) => {
      const headers = { authorization: `Bearer ${token}`, "accept-encoding": gzip ? "gzip" : "identity" };
      http.get(url, { headers }, (res) => {
        let bytes = 0;
        let first = Buffer.alloc(0);
        res.on("data", (d) => ((bytes += d.length), first.length < 4 && (first = Buffer.concat([first, d]))));
        res.on("end", () => ok({ status: res.statusCode, bytes, layout: gzip ? "gzip" : first.subarray(0, 4).toString() }));
      }).on("error", fail);
    });
  const rssBefore = Math.round(rssMb(proxy.pid));
  let peak = rssPeak(proxy.pid);
  const t = performance.now();
  const one = await get(false);
  const oneMs = Math.round(performance.now() - t);
  const oneRss = peak();
  peak = rssPeak(proxy.pid);
  const t4 = performance.now();
  const four = await Promise.all([0, 1, 2, 3].map(() => get(true)));
  const fourMs = Math.round(performance.now() - t4);
  const result = {
    query,
    mesh_bytes: mesh.length,
    duplicates: 100,
    layout: one.layout,
    body_bytes: one.bytes,
    one_ms: oneMs,
    rss_mb_before: rssBefore,
    rss_mb_most_one: oneRss,
    four_at_once_gzip: { statuses: four.map((r) => r.status), gzip_bytes: four[0].bytes, ms: fourMs, rss_mb_most: peak() },
    rss_mb_after: Math.round(rssMb(proxy.pid)),
  };
  p.ws.close();
  proxy.stop();
  return result;
}

async function bundle() {
  return { part: "bundle", pmb2: await bundleOf("?placements=true"), pmb3: await bundleOf("?layout=PMB3") };
}

/// A JSON watcher of the session: when it held each stroke done, its `lagged` errors, and
/// whether the proxy dropped it.
async function watcher(proxy, session, token) {
  const ws = new WebSocket(`ws://127.0.0.1:${proxy.port}/v1/sessions/${session}/ws`, ["penmesh", `penmesh.token.${token}`]);
  const w = { ws, done: new Map(), lagged: 0, dropped: false, synced: 0 };
  const hold = (stroke) => w.done.has(stroke) || w.done.set(stroke, performance.now());
  ws.onmessage = (e) => {
    const msg = JSON.parse(e.data);
    if (msg.synced) w.synced++;
    if (msg.peer_stroke_done) hold(msg.peer_stroke_done.stroke);
    if (msg.peer_strokes) for (const s of msg.peer_strokes.strokes) if (s.done) hold(s.stroke);
    if (msg.error?.code === "lagged") w.lagged++;
  };
  ws.onclose = () => (w.dropped = true);
  await new Promise((r, j) => ((ws.onopen = r), (ws.onerror = j)));
  ws.send(JSON.stringify({ hello: { protocol: 5, client: "model-routes-watcher", resume: [] } }));
  while (!w.synced) await sleep(10);
  return w;
}

/// Item 11 of the review: 200 duplicates of a 20,000-sample stroke asked as fast as one client
/// can, 8 watchers reading.
async function watchers() {
  const proxy = await startProxy();
  const { session, token } = await newSession(proxy);
  const p = await join_(proxy, session, token);
  const source = await drawLong(p, 20000, 0, 3);
  const ws = await Promise.all(Array.from({ length: 8 }, () => watcher(proxy, session, token)));
  const made = new Map(); // duplicate -> when its 201 came
  const refused = {};
  let next = 0;
  const started = performance.now();
  await Promise.all(
    Array.from({ length: 4 }, async () => {
      while (next < 200) {
        const k = next++;
        const id = randomUUID();
        for (;;) {
          const res = await fetch(`${proxy.base}/v1/strokes/${source}/duplicate`, {
            method: "POST",
            headers: drawer(p, { "content-type": "application/json" }),
            body: JSON.stringify({ stroke: id, placement: at((k % 20) * 40, Math.floor(k / 20) * 40) }),
          });
          await res.arrayBuffer();
          if (res.status === 201) break;
          if (res.status !== 429 && res.status !== 503) throw new Error(`duplicate ${res.status}`);
          refused[res.status] = (refused[res.status] ?? 0) + 1;
          await sleep(1000 * Number(res.headers.get("retry-after") ?? 1));
        }
        made.set(id, performance.now());
      }
    }),
  );
  const making_s = Math.round((performance.now() - started) / 100) / 10;
  // Every watcher holds every duplicate, or is dropped, or 60 s pass.
  const all = () => ws.every((w) => w.dropped || [...made.keys()].every((id) => w.done.has(id)));
  for (const until_ = performance.now() + 60000; !all() && performance.now() < until_; ) await sleep(50);
  const lags = [];
  for (const w of ws) for (const [id, at_] of made) if (w.done.has(id)) lags.push(Math.max(0, w.done.get(id) - at_));
  lags.sort((a, b) => a - b);
  const q = (f) => Math.round(lags[Math.min(lags.length - 1, Math.floor(f * lags.length))] ?? 0);
  const result = {
    part: "watchers",
    duplicates: made.size,
    making_s,
    refused,
    watchers: ws.map((w) => ({ lagged: w.lagged, dropped: w.dropped, held: [...made.keys()].filter((id) => w.done.has(id)).length })),
    lag_ms: { p50: q(0.5), p99: q(0.99), max: q(1) },
  };
  for (const w of ws) w.ws.close();
  proxy.stop();
  return result;
}

const all = { "wrong-token": wrongToken, prints, retry, duplicates, scenes, race, history, bundle, watchers };
for (const part of parts.length ? parts : Object.keys(all)) {
  console.log(JSON.stringify(await all[part]()));
}
process.exit(0);
