// The penmesh page: a session in 3D (history, live strokes, meshes) and a pen that draws into it.
// This module wires the others: the connection (protocol.js) and the HTTP calls (api.js) feed
// the 3D view (scene.js); the pen (pen.js) feeds the connection and the ink (ink.js). It asks the
// proxy to build the mesh of its own strokes (POST /v1/strokes/{id}/mesh/build). See docs/web.md.
import { Api, createSession } from "./api.js";
import { Ink } from "./ink.js";
import { attachPen } from "./pen.js";
import { Connection } from "./protocol.js";
import { SceneView, colourOf } from "./scene.js";

// The brush of our strokes (the proxy's default brush).
const BRUSH = { size: 8, pressure_response: 0.5, min_radius: 0.25 };
const meta = (name) => document.querySelector(`meta[name="${name}"]`).content;
const $ = (id) => document.getElementById(id);

const people = new Map(); // participant -> name
const errors = [];
const timings = []; // own strokes: ms from pen-up to the mesh on screen
const penUpAt = new Map(); // own stroke -> performance.now() at pen-up
const loading = new Set(); // strokes whose mesh is being fetched on its own
// Meshes announced (PeerMesh) before the session's mesh bundle came: stroke -> participant.
// Those the bundle did not hold are fetched on their own then.
let announced = new Map();
let fitted = false; // the view is fitted to the drawing once, when the history is in

function fail(message) {
  errors.push(message);
  $("error").textContent = message;
}

// --- where: /s/{session}#token=… (the token never leaves in a URL the server sees) ---------
const match = location.pathname.match(/^\/s\/([0-9a-fA-F-]{36})$/);
const token = new URLSearchParams(location.hash.slice(1)).get("token");
const session = match && token ? match[1].toLowerCase() : null;
$("new").onclick = async () => {
  try {
    const created = await createSession();
    location.assign(`/s/${created.session}#token=${created.token}`);
  } catch (err) {
    fail(err.message);
  }
};
if (!session) {
  $("status").textContent = match
    ? "this link has no #token=…: ask for the full link, or start a new session"
    : "no session open: start a new one";
}

const api = new Api(token);
// The session's meshes and its history are asked for before the 3D view is set up: creating a
// WebGL context is slow in software WebGL (about 0.4 s here), and the proxy builds both
// meanwhile (docs/performance.md, "A busy board").
const bundleRequest = session ? api.meshBundle(session) : null;
bundleRequest?.catch(() => {}); // its failure is reported where it is awaited (loadBundle)
// The proxy refuses a name over 200 characters or with a NUL byte (hello.name).
const myName = (localStorage.getItem("penmesh:name") || "browser").replace(/\0/g, "").slice(0, 200);
const conn = new Connection({
  session,
  token,
  protocol: Number(meta("penmesh-protocol")),
  // The protocol's quantisation grid (position px, time ms, pressure), filled in by the proxy.
  grid: meta("penmesh-grid").split(" ").map(Number),
  name: myName,
  on: onMessage,
});
if (session) conn.connect(); // its messages are handled once this module has run
const view = new SceneView($("gl"));
const ink = new Ink($("ink"), BRUSH);

// For the browser tests and the curious.
window.penmesh = {
  get me() { return conn.me; },
  get synced() { return conn.synced; },
  get pending() { return conn.pending; },
  get wsBytes() { return conn.wsBytes; },
  get strokes() { return view.strokes; },
  get meshes() { return view.meshCount; },
  get frames() { return view.frames; },
  get drawCalls() { return view.renderer.info.render.calls; }, // of the last frame
  people,
  errors,
  timings,
};

function resize() {
  view.frontView();
  ink.resize(innerWidth, innerHeight);
  ink.setScale(view.pixelsPerUnit());
}
addEventListener("resize", resize);
resize();

function showStatus() {
  if (conn.synced) $("status").textContent = `${view.strokes.size} strokes, ${view.meshCount} meshes`;
}

function showPeople() {
  const list = $("people");
  list.replaceChildren();
  for (const [id, name] of people) {
    const li = document.createElement("li");
    li.textContent = id === conn.me ? `${name} (you)` : name;
    li.style.setProperty("--c", `#${colourOf(id).getHexString()}`);
    list.append(li);
  }
}

function meshShown(id) {
  showStatus();
  ink.remove(id);
}

// Every mesh stored so far in one request (GET /v1/sessions/{id}/meshes), started with the
// page; the connection's PeerMesh events bring the ones stored later.
async function loadBundle() {
  try {
    const meshes = await bundleRequest;
    await Promise.all(
      meshes.map(async (m) => {
        if (view.addMesh(m.stroke, m.participant, await view.parse(m.glb))) meshShown(m.stroke);
      }),
    );
  } catch (err) {
    fail(`cannot show the session's meshes: ${err.message}`);
  }
  const rest = announced;
  announced = null;
  for (const [id, participant] of rest) loadMesh(id, participant);
}

function meshAnnounced(id, participant) {
  if (announced) announced.set(id, participant);
  else loadMesh(id, participant);
}

async function loadMesh(id, participant) {
  if (view.hasMesh(id) || loading.has(id)) return;
  loading.add(id);
  try {
    const flat = await view.parse(await api.strokeMesh(id));
    if (view.addMesh(id, participant, flat)) meshShown(id);
  } catch (err) {
    fail(`cannot show the mesh of stroke ${id}: ${err.message}`);
  } finally {
    loading.delete(id);
  }
}

async function ownStrokeDone(id) {
  view.stroke(id, conn.me);
  try {
    await api.buildMesh(id, conn.participantKey());
    await loadMesh(id, conn.me); // our own: not announced to us
    // On screen: the frame after the mesh joined the scene has been drawn.
    if (penUpAt.has(id)) {
      await view.drawn();
      timings.push(performance.now() - penUpAt.get(id));
    }
  } catch (err) {
    fail(`cannot build the mesh of stroke ${id}: ${err.message}`);
  }
}

function onMessage(kind, m) {
  switch (kind) {
    case "welcome":
      people.set(m.participant, myName);
      showPeople();
      ink.setColour(`#${colourOf(m.participant).getHexString()}`);
      $("status").textContent = "loading the session…";
      break;
    case "synced":
      $("status").textContent = `${view.strokes.size} strokes`;
      if (!fitted) {
        fitted = true;
        view.fitToDrawing();
        ink.setScale(view.pixelsPerUnit());
      }
      break;
    case "retained": // our own stroke
      view.addRetained(m.stroke, conn.me, m.first, m.points);
      break;
    case "stroke_done": // our own stroke
      ownStrokeDone(m.stroke);
      break;
    case "peer_joined":
      people.set(m.participant, m.name);
      showPeople();
      break;
    case "peer_left":
      people.delete(m.participant);
      showPeople();
      break;
    case "peer_stroke_begin":
      view.stroke(m.stroke, m.participant);
      break;
    case "peer_retained":
      view.addRetained(m.stroke, m.participant, m.first, m.points);
      break;
    case "peer_mesh":
      meshAnnounced(m.stroke, m.participant);
      break;
    case "error":
      fail(`proxy: ${m.code}: ${m.message}`);
      break;
    case "closed":
      $("status").textContent = `disconnected (${m.code}${m.reason ? ": " + m.reason : ""}); reconnecting…`;
      return;
    default:
      break;
  }
  showStatus();
}

// --- the pen: samples to the connection, ink under the pen ---------------------------------
function addSamples(stroke, samples) {
  for (const s of samples) {
    const at = view.toStroke(s.clientX, s.clientY);
    if (!at) continue;
    conn.add(at[0], at[1], s.t, s.p);
    ink.add(stroke, s.clientX, s.clientY, s.p);
  }
}
attachPen($("ink"), {
  canStart: () => conn.canBegin(),
  down: (device, sample) => {
    const stroke = conn.begin(BRUSH, device);
    view.stroke(stroke, conn.me);
    ink.begin(stroke);
    addSamples(stroke, [sample]);
    conn.flush(true);
    ink.redraw();
  },
  move: (samples) => {
    addSamples(conn.pending.stroke, samples);
    conn.flush(false);
    ink.redraw();
  },
  up: () => {
    const stroke = conn.pending.stroke;
    conn.end();
    penUpAt.set(stroke, performance.now());
  },
});

// --- buttons ---------------------------------------------------------------------------------
function setMode(orbit) {
  document.body.classList.toggle("orbit", orbit);
  view.setOrbit(orbit);
  $("orbit").setAttribute("aria-pressed", String(orbit));
  $("draw").setAttribute("aria-pressed", String(!orbit));
  if (!orbit) ink.redraw();
}
$("draw").onclick = () => setMode(false);
$("orbit").onclick = () => setMode(true);
$("download").onclick = async () => {
  try {
    const glb = await view.exportGlb();
    const a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([glb], { type: "model/gltf-binary" }));
    a.download = `penmesh-${session}.glb`;
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  } catch (err) {
    fail(`cannot export: ${err.message}`);
  }
};

if (session) loadBundle();
