// The penmesh page: a session in 3D (history, live strokes, meshes) and a pen that draws into it.
// It speaks the JSON encoding of the protocol (docs/protocol.md) and asks the proxy to build the
// mesh of its own strokes (POST /v1/strokes/{id}/mesh/build). See docs/web.md.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { GLTFExporter } from "three/examples/jsm/exporters/GLTFExporter.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

// Mouse and touch report no real pressure: they draw with this one (docs/web.md).
const CONSTANT_PRESSURE = 0.5;
// Stage 1's repeat rule, as the native client's (penmesh::DEFAULT_REPEAT_PRESSURE_TOLERANCE).
const REPEAT_PRESSURE = 0.2;
// Samples are sent at most this often while the pen moves (ms); pen-up flushes at once.
const FLUSH_MS = 16;
const PROTOCOL = Number(document.querySelector('meta[name="penmesh-protocol"]').content);
// The protocol's quantisation grid (position px, time ms, pressure), filled in by the proxy.
// Samples are snapped to it before they are sent, as the native client does, so what the proxy
// stores (it puts every sample on this grid on arrival) is exactly what was sent.
const [POSITION_STEP, TIME_STEP, PRESSURE_STEP] = document
  .querySelector('meta[name="penmesh-grid"]')
  .content.split(" ")
  .map(Number);
const snap = (value, step) => Math.round(value / step) * step;

const $ = (id) => document.getElementById(id);
const state = {
  session: null,
  token: null,
  ws: null,
  me: null,
  people: new Map(), // participant -> name
  strokes: new Map(), // stroke -> {participant, points: [[x,y]], line, mesh}
  meshes: 0,
  synced: false,
  errors: [],
  pending: null, // own stroke in progress or not yet done: {stroke, samples, ended, acked}
  timings: [], // own strokes: ms from pen-up to the mesh on screen
  wsBytes: 0, // received on the WebSocket (docs/performance.md)
};
window.penmesh = state; // for the browser tests and the curious

function fail(message) {
  state.errors.push(message);
  $("error").textContent = message;
}

// --- where: /s/{session}#token=… (the token never leaves in a URL the server sees) ---------
const match = location.pathname.match(/^\/s\/([0-9a-fA-F-]{36})$/);
state.token = new URLSearchParams(location.hash.slice(1)).get("token");
$("new").onclick = newSession;
if (!match || !state.token) {
  $("status").textContent = match
    ? "this link has no #token=…: ask for the full link, or start a new session"
    : "no session open: start a new one";
} else {
  state.session = match[1].toLowerCase();
}

async function newSession() {
  const res = await fetch("/v1/sessions", { method: "POST" });
  if (!res.ok) return fail(`cannot create a session: HTTP ${res.status}`);
  const { session, token } = await res.json();
  location.assign(`/s/${session}#token=${token}`);
}

// --- the 3D view -----------------------------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ canvas: $("gl"), antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f3ef);
scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(300, 500, 1000);
scene.add(sun);
// Stroke coordinates are screen-like (y down): flip y so the drawing is not upside down.
const world = new THREE.Group();
world.scale.set(1, -1, 1);
scene.add(world);
const camera = new THREE.PerspectiveCamera(40, 1, 1, 100000);
const controls = new OrbitControls(camera, $("gl"));
controls.enabled = false;
const ink = $("ink");
const ctx = ink.getContext("2d");

// Start with the page's pixels one to one on the z = 0 plane, so a stroke drawn at (x, y)
// CSS pixels lands at stroke coordinates (x, y).
function fitCamera() {
  const w = innerWidth;
  const h = innerHeight;
  renderer.setSize(w, h, false);
  ink.width = w * devicePixelRatio;
  ink.height = h * devicePixelRatio;
  camera.aspect = w / h;
  const distance = h / 2 / Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
  camera.position.set(w / 2, -h / 2, distance);
  controls.target.set(w / 2, -h / 2, 0);
  camera.updateProjectionMatrix();
  controls.update();
  redrawInk();
}
addEventListener("resize", fitCamera);
fitCamera();
renderer.setAnimationLoop(() => {
  controls.update();
  renderer.render(scene, camera);
});

function colour(participant) {
  let h = 0;
  for (const c of participant) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return new THREE.Color().setHSL((h % 360) / 360, 0.65, 0.45);
}

function strokeOf(id, participant) {
  let s = state.strokes.get(id);
  if (!s) {
    s = { participant, points: [], line: null, mesh: null };
    state.strokes.set(id, s);
  }
  return s;
}

// A live stroke: a polyline of its retained points, replaced by the mesh when it comes.
function addRetained(id, participant, points) {
  const s = strokeOf(id, participant);
  if (s.mesh) return;
  for (const [x, y] of points) s.points.push(new THREE.Vector3(x, y, 0));
  if (s.line) {
    world.remove(s.line);
    s.line.geometry.dispose();
  }
  s.line = new THREE.Line(
    new THREE.BufferGeometry().setFromPoints(s.points),
    new THREE.LineBasicMaterial({ color: colour(participant) }),
  );
  world.add(s.line);
}

// One material per person: Lambert shading, cheap enough for software WebGL with 1,000 strokes.
const materials = new Map();
function materialOf(participant) {
  let m = materials.get(participant);
  if (!m) {
    m = new THREE.MeshLambertMaterial({
      color: colour(participant),
      side: THREE.DoubleSide, // the group's y flip turns the winding around
    });
    materials.set(participant, m);
  }
  return m;
}

const loader = new GLTFLoader();
async function loadMesh(id, participant) {
  const s = strokeOf(id, participant);
  if (s.mesh || s.loading) return;
  s.loading = true;
  try {
    const res = await api(`/v1/strokes/${id}/mesh`);
    const gltf = await loader.parseAsync(await res.arrayBuffer(), "");
    const material = materialOf(participant);
    gltf.scene.traverse((o) => {
      if (o.isMesh) o.material = material;
    });
    s.mesh = gltf.scene;
    world.add(s.mesh);
    if (s.line) {
      world.remove(s.line);
      s.line.geometry.dispose();
      s.line = null;
    }
    state.meshes += 1;
    if (state.synced) $("status").textContent = `${state.strokes.size} strokes, ${state.meshes} meshes`;
    if (s.ink) {
      s.ink = null;
      redrawInk();
    }
  } catch (err) {
    fail(`cannot show the mesh of stroke ${id}: ${err.message}`);
  } finally {
    s.loading = false;
  }
}

async function api(path, init = {}) {
  const res = await fetch(path, {
    ...init,
    headers: { ...(init.headers || {}), authorization: `Bearer ${state.token}` },
  });
  if (!res.ok) {
    let detail = "";
    try {
      detail = (await res.json()).message;
    } catch {}
    throw new Error(`${init.method || "GET"} ${path}: HTTP ${res.status} ${detail}`);
  }
  return res;
}

function showPeople() {
  const list = $("people");
  list.replaceChildren();
  for (const [id, name] of state.people) {
    const li = document.createElement("li");
    li.textContent = id === state.me ? `${name} (you)` : name;
    li.style.setProperty("--c", `#${colour(id).getHexString()}`);
    list.append(li);
  }
}

// --- the connection --------------------------------------------------------------------------
const storageKey = () => `penmesh:${state.session}:pending`;

// This tab's participant key (hello.key, and the x-penmesh-key header of the mesh build): 128
// random bits, kept in sessionStorage beside the pending stroke, so a reconnect or a reload is
// the same participant and may resume that stroke; another tab is another participant.
function participantKey() {
  const name = `penmesh:${state.session}:key`;
  let key = sessionStorage.getItem(name);
  if (!key) {
    const bytes = crypto.getRandomValues(new Uint8Array(16));
    key = Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
    sessionStorage.setItem(name, key);
  }
  return key;
}
function savePending() {
  if (state.pending) sessionStorage.setItem(storageKey(), JSON.stringify(state.pending));
  else sessionStorage.removeItem(storageKey());
}

let retry = 500;
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  // The token travels as a subprotocol: never in the URL, so never in an access log.
  const ws = new WebSocket(`${scheme}://${location.host}/v1/sessions/${state.session}/ws`, [
    "penmesh",
    `penmesh.token.${state.token}`,
  ]);
  state.ws = ws;
  ws.onopen = () => {
    retry = 500;
    const pending = JSON.parse(sessionStorage.getItem(storageKey()) || "null");
    state.pending = pending;
    send({
      hello: {
        protocol: PROTOCOL,
        client: "penmesh-web",
        name: localStorage.getItem("penmesh:name") || "browser",
        resume: pending ? [pending.stroke] : [],
        key: participantKey(),
      },
    });
  };
  ws.onmessage = (e) => {
    state.wsBytes += e.data.length;
    onMessage(JSON.parse(e.data));
  };
  ws.onclose = (e) => {
    $("status").textContent = `disconnected (${e.code}${e.reason ? ": " + e.reason : ""}); reconnecting…`;
    state.ws = null;
    setTimeout(connect, retry);
    retry = Math.min(retry * 2, 10000);
  };
}

function send(msg) {
  if (state.ws && state.ws.readyState === WebSocket.OPEN) state.ws.send(JSON.stringify(msg));
}

function onMessage(msg) {
  const [kind, m] = Object.entries(msg)[0];
  switch (kind) {
    case "welcome": {
      state.me = m.participant;
      state.people.set(m.participant, localStorage.getItem("penmesh:name") || "browser");
      showPeople();
      $("status").textContent = "loading the session…";
      const p = state.pending;
      if (p) {
        const r = m.resume.find((r) => r.stroke === p.stroke);
        resumeOwn(p, r);
      }
      break;
    }
    case "synced":
      state.synced = true;
      $("status").textContent = `${state.strokes.size} strokes`;
      break;
    case "ack":
      if (state.pending && state.pending.stroke === m.stroke) state.pending.acked = m.upto_seq;
      break;
    case "retained":
      if (state.pending && state.pending.stroke === m.stroke) addRetained(m.stroke, state.me, m.points);
      break;
    case "stroke_done":
      ownStrokeDone(m.stroke);
      break;
    case "peer_joined":
      state.people.set(m.participant, m.name);
      showPeople();
      break;
    case "peer_left":
      state.people.delete(m.participant);
      showPeople();
      break;
    case "peer_stroke_begin":
      strokeOf(m.stroke, m.participant);
      break;
    case "peer_retained":
      addRetained(m.stroke, m.participant, m.points);
      break;
    case "peer_stroke_done":
      break;
    case "peer_mesh":
      loadMesh(m.stroke, m.participant);
      break;
    case "error":
      fail(`proxy: ${m.code}: ${m.message}`);
      if (m.code === "lagged") state.synced = false;
      break;
    default:
      break;
  }
  if (state.synced) $("status").textContent = `${state.strokes.size} strokes, ${state.meshes} meshes`;
}

// After a reconnect (or a reload) the proxy says how far it has our stroke: send the rest from
// there, then end it if the pen had lifted (or the page went away: the pen cannot come back).
function resumeOwn(p, r) {
  if (!r || r.status === "unknown") {
    // Never reached the proxy: begin it again with everything.
    send({ stroke_begin: { stroke: p.stroke, brush: p.brush, device: p.device } });
    r = { next_seq: 0, status: "open" };
  }
  if (r.status === "done") return ownStrokeDone(p.stroke);
  const rest = p.samples.slice(r.next_seq);
  if (rest.length) send({ points: { stroke: p.stroke, seq: r.next_seq, points: rest } });
  p.sent = p.samples.length;
  if (!drawing) {
    p.ended = true;
    savePending();
    send({ stroke_end: { stroke: p.stroke, n_points: p.samples.length } });
  }
}

async function ownStrokeDone(id) {
  const p = state.pending;
  const s = strokeOf(id, state.me);
  if (p && p.stroke === id) {
    state.pending = null;
    savePending();
  }
  try {
    await api(`/v1/strokes/${id}/mesh/build`, { method: "POST", headers: { "x-penmesh-key": participantKey() } });
    await loadMesh(id, state.me);
    // On screen: the frame after the mesh joined the scene has been drawn.
    if (s.penUp !== undefined) {
      await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
      state.timings.push(performance.now() - s.penUp);
    }
  } catch (err) {
    fail(`cannot build the mesh of stroke ${id}: ${err.message}`);
  }
}

// --- the pen ---------------------------------------------------------------------------------
let drawing = null; // {pointerId, pointerType, t0, inkPath}
let lastFlush = 0;
const ray = new THREE.Raycaster();
const plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
const hit = new THREE.Vector3();

// Where on the drawing plane (stroke coordinates) a pointer is, whatever the view.
function toStroke(e) {
  const r = ink.getBoundingClientRect();
  const ndc = new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  ray.setFromCamera(ndc, camera);
  if (!ray.ray.intersectPlane(plane, hit)) return null;
  return [hit.x, -hit.y];
}

function pressureOf(e) {
  return e.pointerType === "pen" ? Math.min(1, Math.max(0, e.pressure)) : CONSTANT_PRESSURE;
}

function addSample(e) {
  const p = state.pending;
  const at = toStroke(e);
  if (!at) return;
  const prev = p.samples[p.samples.length - 1];
  // Coalesced events can share a timestamp; time must never go backwards.
  const t = Math.max(prev ? prev[2] : 0, snap(e.timeStamp - drawing.t0, TIME_STEP));
  // Stage 1 (docs/web.md): drop a repeat of the last kept position whose pressure is within REPEAT_PRESSURE of it.
  if (prev && snap(at[0], POSITION_STEP) === prev[0] && snap(at[1], POSITION_STEP) === prev[1] && Math.abs(snap(pressureOf(e), PRESSURE_STEP) - prev[3]) <= REPEAT_PRESSURE) return;
  p.samples.push([
    snap(at[0], POSITION_STEP),
    snap(at[1], POSITION_STEP),
    t,
    snap(pressureOf(e), PRESSURE_STEP),
  ]);
  drawing.inkPath.push([e.clientX, e.clientY, pressureOf(e)]);
}

function flush(force) {
  const p = state.pending;
  const now = performance.now();
  if (!p) return;
  savePending(); // every sample survives a reload, sent or not
  if (!force && now - lastFlush < FLUSH_MS) return;
  lastFlush = now;
  if (p.sent < p.samples.length) {
    send({ points: { stroke: p.stroke, seq: p.sent, points: p.samples.slice(p.sent) } });
    p.sent = p.samples.length;
  }
}

ink.addEventListener("pointerdown", (e) => {
  if (!state.me || drawing || (state.pending && !state.pending.ended)) return;
  if (e.pointerType === "touch" && penDown) return; // palm rejection
  if (e.pointerType === "mouse" && e.button !== 0) return;
  ink.setPointerCapture(e.pointerId);
  const stroke = crypto.randomUUID();
  const brush = { size: 8, pressure_response: 0.5, min_radius: 0.25 };
  const device = `web:${e.pointerType}`;
  state.pending = { stroke, brush, device, samples: [], sent: 0, acked: 0, ended: false };
  const s = strokeOf(stroke, state.me);
  drawing = { pointerId: e.pointerId, pointerType: e.pointerType, t0: e.timeStamp, inkPath: [] };
  s.ink = drawing.inkPath;
  send({ stroke_begin: { stroke, brush, device } });
  addSample(e);
  flush(true);
  redrawInk();
});

let penDown = false;
addEventListener("pointerdown", (e) => {
  if (e.pointerType === "pen") penDown = true;
}, true);
addEventListener("pointerup", (e) => {
  if (e.pointerType === "pen") penDown = false;
}, true);

ink.addEventListener("pointermove", (e) => {
  if (!drawing || e.pointerId !== drawing.pointerId) return;
  // A 200-240 Hz pen delivers several samples per frame: take every one of them.
  const events = e.getCoalescedEvents ? e.getCoalescedEvents() : [];
  for (const c of events.length ? events : [e]) addSample(c);
  flush(false);
  redrawInk();
});

function penUp(e) {
  if (!drawing || e.pointerId !== drawing.pointerId) return;
  const p = state.pending;
  drawing = null;
  p.ended = true;
  flush(true);
  strokeOf(p.stroke, state.me).penUp = performance.now();
  send({ stroke_end: { stroke: p.stroke, n_points: p.samples.length } });
}
ink.addEventListener("pointerup", penUp);
ink.addEventListener("pointercancel", penUp);

// The ink: drawn at once under the pen, in page pixels, until the stroke's mesh replaces it.
function redrawInk() {
  ctx.setTransform(devicePixelRatio, 0, 0, devicePixelRatio, 0, 0);
  ctx.clearRect(0, 0, ink.width, ink.height);
  ctx.lineCap = "round";
  ctx.strokeStyle = state.me ? `#${colour(state.me).getHexString()}` : "#333";
  for (const s of state.strokes.values()) {
    const path = s.ink;
    if (!path || path.length === 0) continue;
    for (let i = 0; i < path.length; i++) {
      const [x, y, p] = path[i];
      const [px, py] = path[Math.max(0, i - 1)];
      ctx.lineWidth = Math.max(0.5, 2 * 8 * 0.5 * p);
      ctx.beginPath();
      ctx.moveTo(px, py);
      ctx.lineTo(x, y);
      ctx.stroke();
    }
  }
}

// --- buttons ---------------------------------------------------------------------------------
function setMode(orbit) {
  document.body.classList.toggle("orbit", orbit);
  controls.enabled = orbit;
  $("orbit").setAttribute("aria-pressed", String(orbit));
  $("draw").setAttribute("aria-pressed", String(!orbit));
  if (!orbit) fitCamera(); // the pen draws on the plane as seen from the front
}
$("draw").onclick = () => setMode(false);
$("orbit").onclick = () => setMode(true);
$("download").onclick = () => {
  new GLTFExporter().parse(
    world,
    (glb) => {
      const a = document.createElement("a");
      a.href = URL.createObjectURL(new Blob([glb], { type: "model/gltf-binary" }));
      a.download = `penmesh-${state.session}.glb`;
      a.click();
      setTimeout(() => URL.revokeObjectURL(a.href), 10000);
    },
    (err) => fail(`cannot export: ${err.message}`),
    { binary: true },
  );
};

if (state.session) connect();
