// The penmesh page: a session in 3D (history, live strokes, meshes) and a pen that draws into it.
// This module wires the others: the connection (protocol.js) and the HTTP calls (api.js) feed
// the 3D view (scene.js); the pen (pen.js) feeds the connection and the ink (ink.js), or the
// eraser; undo and redo go through takeback.js; the brush and the name are settings.js's. It
// asks the proxy to build the mesh of its own strokes (POST /v1/strokes/{id}/mesh/build). See
// docs/web.md.
import { Api, createSession } from "./api.js";
import { Ink } from "./ink.js";
import { attachPen } from "./pen.js";
import { Connection } from "./protocol.js";
import { SceneView, colourOf, strokeColour } from "./scene.js";
import { cleanName, hexOf, colourOf as colourNumber, saveBrush, saveName, savedBrush, savedName } from "./settings.js";
import { TakeBack } from "./takeback.js";

// The brush of our strokes (this tab's choice of colour and size).
const brush = savedBrush();
// Half the eraser's width, in CSS pixels.
const ERASER_RADIUS_PX = 8;
const meta = (name) => document.querySelector(`meta[name="${name}"]`).content;
const $ = (id) => document.getElementById(id);

const people = new Map(); // participant -> name
const errors = [];
const timings = []; // own strokes: ms from pen-up to the mesh on screen
const penUpAt = new Map(); // own stroke -> performance.now() at pen-up
const loading = new Set(); // strokes whose mesh is being fetched on its own
const meshKnown = new Set(); // strokes the proxy has said have a mesh (the history, PeerMesh)
const building = new Set(); // our strokes whose mesh build was asked for by this page
// A mesh build that fails for a reason that may pass (no answer, the proxy busy or failing:
// 429, 5xx) is tried again after each of these waits (ms); any other refusal is reported.
const MESH_BUILD_WAITS_MS = [1000, 2000, 4000];
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
// Asked once (the name field is offered first), then kept; a guest name until then.
const askName = savedName() === null;
let myName = savedName() || `guest ${Math.floor(Math.random() * 0x10000).toString(16).padStart(4, "0")}`;
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
const ink = new Ink($("ink"), brush);
const takeBack = new TakeBack((stroke, remove) => conn.setRemoved(stroke, remove));
let eraser = false; // the eraser tool (for a mouse or a finger; a pen's eraser end always erases)

// For the browser tests and the curious.
window.penmesh = {
  get me() { return conn.me; },
  get synced() { return conn.synced; },
  get pending() { return conn.pending; },
  get unfinished() { return conn.unfinished.length; }, // our strokes not yet done
  get wsBytes() { return conn.wsBytes; },
  get strokes() { return view.strokes; },
  get meshes() { return view.meshCount; },
  get frames() { return view.frames; },
  get drawCalls() { return view.renderer.info.render.calls; }, // of the last frame
  get triangles() { return view.renderer.info.render.triangles; }, // of the last frame
  get shown() { return view.shownMeshes; },
  get removed() { return [...view.strokes].filter(([, s]) => s.removed).map(([id]) => id); },
  get brush() { return brush; },
  // Asks the proxy to take back (`remove`) or bring back any stroke, ours or not (the tests
  // check that the proxy refuses another's).
  setRemoved: (stroke, remove) => conn.setRemoved(stroke, remove),
  undo: () => takeBack.undo(),
  redo: () => takeBack.redo(),
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
  if (conn.synced) $("status").textContent = `${view.shownStrokes} strokes, ${view.shownMeshes} meshes`;
}

// Each person's colour in the list: their brush's, as their latest stroke drew it (ours as
// chosen); a person who has not drawn shows the participant's own colour.
const brushColours = new Map(); // participant -> "#rrggbb"

function showPeople() {
  const list = $("people");
  list.replaceChildren();
  for (const [id, name] of people) {
    const li = document.createElement("li");
    li.textContent = id === conn.me ? `${name} (you)` : name;
    li.style.setProperty("--c", brushColours.get(id) ?? `#${colourOf(id).getHexString()}`);
    list.append(li);
  }
}

/// Notes `participant`'s brush colour, and redraws the list when it changed.
function brushUsed(participant, brushOfStroke) {
  const colour = `#${strokeColour(participant, brushOfStroke).getHexString()}`;
  if (brushColours.get(participant) === colour) return;
  brushColours.set(participant, colour);
  showPeople();
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
  meshKnown.add(id);
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

/// Asks the proxy to build our stroke's mesh, trying again while the failure may pass.
async function buildOwnMesh(id) {
  for (let attempt = 0; ; attempt++) {
    try {
      return await api.buildMesh(id, conn.participantKey());
    } catch (err) {
      const mayPass = err.status === undefined || err.status === 429 || err.status >= 500;
      if (!mayPass || attempt >= MESH_BUILD_WAITS_MS.length) throw err;
      await new Promise((r) => setTimeout(r, MESH_BUILD_WAITS_MS[attempt]));
    }
  }
}

async function ownStrokeDone(id) {
  view.stroke(id, conn.me).done = true;
  takeBack.drawn(id);
  await ownMesh(id);
}

/// Builds and shows the mesh of our done stroke `id` (once per page).
async function ownMesh(id) {
  if (building.has(id)) return;
  building.add(id);
  try {
    await buildOwnMesh(id);
    await loadMesh(id, conn.me); // our own: not announced to us
    // On screen: the frame after the mesh joined the scene has been drawn.
    if (penUpAt.has(id)) {
      await view.drawn();
      timings.push(performance.now() - penUpAt.get(id));
    }
  } catch (err) {
    building.delete(id); // asked again when the history next comes (a reconnect, a reload)
    fail(`cannot build the mesh of stroke ${id}: ${err.message}`);
  }
}

function onMessage(kind, m) {
  switch (kind) {
    case "welcome":
      people.set(m.participant, myName);
      showPeople();
      showBrush();
      $("status").textContent = "loading the session…";
      break;
    case "synced":
      $("status").textContent = `${view.shownStrokes} strokes`;
      if (!fitted) {
        fitted = true;
        view.fitToDrawing();
        ink.setScale(view.pixelsPerUnit());
        // After a reload, undo takes back our strokes of the history, the last first.
        if (takeBack.undone.length === 0) {
          for (const [id, s] of view.strokes) if (s.participant === conn.me && s.done && !s.removed) takeBack.drawn(id);
        }
      }
      // Our done strokes the history has without a mesh (a build that failed, or a page that
      // went away before it asked): built now.
      for (const [id, s] of view.strokes) if (s.participant === conn.me && s.done && !meshKnown.has(id)) ownMesh(id);
      break;
    case "retained": // our own stroke
      view.addRetained(m.stroke, conn.me, m.first, m.points);
      break;
    case "stroke_done": // our own stroke
      ownStrokeDone(m.stroke);
      break;
    case "peer_joined":
    case "peer_renamed":
      people.set(m.participant, m.name);
      showPeople();
      break;
    case "stroke_removed":
    case "stroke_restored":
      view.setRemoved(m.stroke, kind === "stroke_removed");
      break;
    case "peer_left":
      people.delete(m.participant);
      showPeople();
      break;
    case "peer_stroke_begin":
      view.stroke(m.stroke, m.participant, m.brush);
      brushUsed(m.participant, m.brush);
      break;
    case "peer_retained":
      view.addRetained(m.stroke, m.participant, m.first, m.points);
      break;
    case "peer_stroke_done":
      view.stroke(m.stroke, m.participant).done = true;
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
// Our strokes the eraser touches at a point of the page: each taken back (and undo brings it
// back).
function erase(clientX, clientY) {
  const at = view.toStroke(clientX, clientY);
  if (!at || !conn.me) return;
  const radius = ERASER_RADIUS_PX / view.pixelsPerUnit() + brush.size * brush.pressure_response;
  for (const stroke of view.strokesAt(at[0], at[1], radius, conn.me)) {
    if (!takeBack.erase(stroke)) fail("cannot erase: not connected to the proxy; try again");
  }
}
attachPen($("ink"), {
  canStart: () => conn.canBegin(),
  eraserTool: () => eraser,
  erase,
  down: (device, sample) => {
    const stroke = conn.begin({ ...brush }, device);
    view.stroke(stroke, conn.me, brush);
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

// --- undo, redo, the eraser, the brush and the name --------------------------------------------
function undoOrRedo(redo) {
  const done = redo ? takeBack.redo() : takeBack.undo();
  if (!done && conn.ws === null) fail("cannot undo or redo: not connected to the proxy; try again");
}
$("undo").onclick = () => undoOrRedo(false);
$("redo").onclick = () => undoOrRedo(true);
addEventListener("keydown", (e) => {
  if (!(e.ctrlKey || e.metaKey) || e.target instanceof HTMLInputElement) return;
  const key = e.key.toLowerCase();
  if (key === "z" || key === "y") {
    e.preventDefault();
    undoOrRedo(key === "y" || e.shiftKey);
  }
});
$("eraser").onclick = () => {
  eraser = !eraser;
  $("eraser").setAttribute("aria-pressed", String(eraser));
};

function showBrush() {
  const colour = brush.color === null ? colourOf(conn.me || "") : strokeColour(conn.me, brush);
  $("colour").value = `#${colour.getHexString()}`;
  $("size").value = String(brush.size);
  ink.setColour(`#${colour.getHexString()}`);
  if (conn.me && brush.color !== null) brushUsed(conn.me, brush);
}
$("colour").oninput = (e) => {
  brush.color = colourNumber(e.target.value);
  saveBrush(brush);
  ink.setColour(hexOf(brush.color));
  if (conn.me) brushUsed(conn.me, brush);
};
$("size").oninput = (e) => {
  brush.size = Number(e.target.value);
  saveBrush(brush);
};
$("name").value = myName;
if (askName) {
  $("name").classList.add("ask");
  $("name").placeholder = "your name";
}
$("name").onchange = (e) => {
  const name = cleanName(e.target.value);
  if (!name) {
    e.target.value = myName;
    return;
  }
  myName = name;
  saveName(name);
  $("name").classList.remove("ask");
  conn.rename(name);
  if (conn.me) people.set(conn.me, name);
  showPeople();
};
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
