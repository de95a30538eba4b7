// A session's page: the connection (protocol.js) and the HTTP calls (api.js) feed the 3D view
// (scene.js); the editor (editor.js) owns the tools, the camera, the history and the brush,
// fed by the one input surface (input.js); the toolbar and the keys are controls.js's. It asks
// the proxy to build the mesh of its own strokes (POST /v1/strokes/{id}/mesh/build). A token
// the proxy refuses ends the page in words (app.js `blocked`), with no retry. See docs/web.md.
import { Api } from "./api.js";
import { blocked } from "./landing.js";
import { attachControls } from "./controls.js";
import { Editor } from "./editor.js";
import { Ground } from "./ground.js";
import { attachExport } from "./export.js";
import { Ink } from "./ink.js";
import { attachInput } from "./input.js";
import { attachModelBar } from "./modelbar.js";
import { Connection } from "./protocol.js";
import { PALETTE, SceneView, colourOf, sameSolid, strokeColour } from "./scene.js";
import { colourApart, saveBrush, savedBrush, savedName } from "./settings.js";
import { Selection } from "./select.js";
import { SelectionPanel } from "./selpanel.js";
import { addSolidRow } from "./solidrow.js";
import { attachDrawSolid } from "./drawsolid.js";
import { TakeBack } from "./takeback.js";
import { attachViews } from "./views.js";
import { WorkPlane } from "./workplane.js";

// A mesh build that fails for a reason that may pass (no answer, the proxy busy or failing:
// 429, 5xx) is tried again after each of these waits (ms); any other refusal is reported.
const MESH_BUILD_WAITS_MS = [1000, 2000, 4000];
const REFUSED_TEXT =
  "This link does not open a session: the session does not exist, or the link's token is not its own (a link cut short?). Ask whoever shared it for the whole link, or start a new session.";

const meta = (name) => document.querySelector(`meta[name="${name}"]`).content;
const $ = (id) => document.getElementById(id);

export function startSession(session, token) {
  const brush = savedBrush(); // this tab's choice of colour and size
  const people = new Map(); // participant -> name
  const errors = [];
  const timings = []; // own strokes: ms from pen-up to the mesh on screen
  const loading = new Set(); // strokes whose mesh is being fetched on its own
  const fetchAgain = new Set(); // strokes whose mesh changed while it was being fetched
  const meshKnown = new Set(); // strokes the proxy has said have a mesh (the history, PeerMesh)
  const building = new Set(); // our strokes whose mesh build was asked for by this page
  // Meshes announced (PeerMesh) before the session's mesh bundle came: stroke -> participant.
  // Those the bundle did not hold are fetched on their own then.
  let announced = new Map();
  const solidSaid = new Set(); // strokes whose solid the connection has said (newer than the bundle's)
  let fitted = false; // the view is fitted to the drawing once, when the history is in
  let refused = false;

  const fail = (message) => {
    errors.push(message);
    $("error").textContent = message;
  };
  const refuse = () => {
    if (refused) return;
    refused = true;
    conn.refused = true;
    blocked(REFUSED_TEXT);
  };

  const api = new Api(token);
  // The session's meshes and its history are asked for before the 3D view is set up: creating a
  // WebGL context is slow in software WebGL (about 0.4 s here), and the proxy builds both
  // meanwhile (docs/performance-log.md, "The busy board again, 2026-11-25").
  const bundleRequest = api.meshBundle(session);
  bundleRequest.catch(() => {}); // its failure is reported where it is awaited (loadBundle)
  // Asked once (the name field is offered first), then kept; a guest name until then.
  const askName = savedName() === null;
  const name = savedName() || `guest ${Math.floor(Math.random() * 0x10000).toString(16).padStart(4, "0")}`;
  const conn = new Connection({
    session,
    token,
    protocol: Number(meta("penmesh-protocol")),
    // The protocol's quantisation grid (position px, time ms, pressure), filled in by the proxy.
    grid: meta("penmesh-grid").split(" ").map(Number),
    // The proxy's ACUTS defaults (tolerance px, angle degrees, pressure tolerance).
    params: meta("penmesh-params").split(" ").map(Number),
    name,
    on: onMessage,
  });
  conn.connect(); // its messages are handled once this function has run
  const view = new SceneView($("gl"));
  const ink = new Ink($("ink"), brush, view);
  const takeBack = new TakeBack((stroke, remove) => conn.setRemoved(stroke, remove));
  const editor = new Editor({ conn, view, ink, takeBack, brush, people });
  // The model: the plane the pen draws on, and the strokes selected to move (select.js).
  const workPlane = new WorkPlane(view);
  editor.workPlane = workPlane;
  editor.selection = new Selection(editor, { api, workPlane });
  const ground = new Ground(view);
  editor.on("camera", () => {
    workPlane.follow();
    ground.follow();
  });
  attachInput($("ink"), editor);
  const controls = attachControls(editor, { session, name, askName, fail });
  attachModelBar(editor, { workPlane, selection: editor.selection });
  attachViews(editor);
  editor.selectionPanel = new SelectionPanel(editor, editor.selection);
  editor.selectionPanel.addRow(addSolidRow(editor.selectionPanel, { api, key: () => conn.participantKey() }));
  attachDrawSolid(editor, $("draw-solid"));
  attachExport({
    button: $("download"),
    session,
    token,
    key: () => conn.participantKey(),
    name: () => controls.name,
    notice: (t) => editor.notice(t),
    fail,
    imported: (ids) => takeBack.push(takeBack.strokesCommand(ids, false)),
    // The print's size scales every mm the page shows (the selection's panel, the gizmo's).
    printSize: (mm) => {
      view.printMm = mm;
      editor.selection.changed();
    },
  });

  // For the browser tests and the curious.
  window.penmesh = {
    get me() { return conn.me; },
    get synced() { return conn.synced; },
    get pending() { return conn.pending; },
    get unfinished() { return conn.unfinished.length; }, // our strokes not yet done
    get wsBytes() { return conn.wsBytes; },
    // How the page sends ("binary" or "json"), and a Ping to say it: the proxy answers in the
    // form of the page's latest frame (the tests check the page reads both at every moment).
    get encoding() { return conn.encoding; },
    set encoding(e) { conn.encoding = e; },
    ping: () => conn.send({ ping: { nonce: 0 } }),
    get strokes() { return view.strokes; },
    get meshes() { return view.meshCount; },
    get frames() { return view.frames; },
    get drawCalls() { return view.renderer.info.render.calls; }, // of the last frame
    get triangles() { return view.renderer.info.render.triangles; }, // of the last frame
    get shown() { return view.shownMeshes; },
    get removed() { return [...view.strokes].filter(([, s]) => s.removed).map(([id]) => id); },
    get brush() { return brush; },
    get tool() { return editor.tool.id; },
    get inked() { return ink.count; }, // strokes on the ink
    get view() { return view; }, // the 3D view (bench/busy-board.mjs --frame-costs)
    get camera() { const r = view.rig; return { x: r.target.x, y: r.target.y, z: r.target.z, scale: r.scale, yaw: r.yaw, pitch: r.pitch }; },
    toStroke: (x, y) => view.toStroke(x, y),
    toPage: (x, y, placement) => view.toPage(x, y, placement),
    // The model (protocol 5): each stroke's placement (null: the board), the work plane's, the
    // selection, and each shown stroke's box in session space (its mesh at its placement).
    get placements() { return Object.fromEntries([...view.strokes].map(([id, s]) => [id, s.placement])); },
    get workPlane() { return { kind: workPlane.kind, offset: workPlane.offset, placement: workPlane.placement }; },
    get selected() { return editor.selection.list; },
    boxes: () => view.boxes(),
    gizmoHandle: (axis) => editor.selection.handleAt(axis),
    // The box of the selected strokes' points, placed (what the selection's panel shows).
    selectionBounds: () => { const b = editor.selection.bounds(); return { min: b.min.toArray(), max: b.max.toArray() }; },
    // Places any stroke here and asks the proxy to (the tests check that it refuses another's
    // and that the page puts the stroke back).
    place: (stroke, placement) => editor.selection.place(new Map([[stroke, placement]])),
    // Asks the proxy to take back (`remove`) or bring back any stroke, ours or not (the tests
    // check that the proxy refuses another's).
    setRemoved: (stroke, remove) => conn.setRemoved(stroke, remove),
    undo: () => editor.undo(),
    redo: () => editor.redo(),
    people,
    errors,
    timings,
  };

  function resize() {
    view.resize();
    ink.resize(innerWidth, innerHeight);
    editor.cameraMoved();
  }
  addEventListener("resize", resize);
  resize();

  function showStatus() {
    if (conn.synced) $("status").textContent = `${view.shownStrokes} strokes, ${view.shownMeshes} meshes`;
  }

  // Each person's colour in the list: their brush's, as their latest stroke drew it (ours as
  // chosen); a person who has not drawn shows their default.
  const brushColours = new Map(); // participant -> "#rrggbb"
  // Each person's default colour, fixed when they are first seen, in the order they joined: the
  // one their participant id gives, unless someone who joined before has one near it, then the
  // palette's farthest from theirs. Every page works it out alike (the history lists people in
  // the order they joined), so a guest's page picks what the others expect of it.
  const defaults = new Map(); // participant -> 0xRRGGBB
  const assignDefault = (id) => {
    if (!defaults.has(id)) defaults.set(id, colourApart(colourOf(id).getHex(), [...defaults.values()], PALETTE));
  };
  const hexOfPerson = (id) => brushColours.get(id) ?? `#${(defaults.get(id) ?? colourOf(id).getHex()).toString(16).padStart(6, "0")}`;

  function showPeople() {
    const list = $("people");
    list.replaceChildren();
    for (const [id, who] of people) {
      const li = document.createElement("li");
      li.textContent = id === conn.me ? `${who} (you)` : who;
      li.style.setProperty("--c", hexOfPerson(id));
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
  controls.onBrush = () => conn.me && brush.color !== null && brushUsed(conn.me, brush);
  controls.onRename = (newName) => {
    conn.rename(newName);
    if (conn.me) people.set(conn.me, newName);
    showPeople();
  };

  /// A person who chose no colour draws in their default (`defaults`), said in their strokes'
  /// brush, so every page shows it whatever it worked out.
  function colourApartFromOthers() {
    assignDefault(conn.me);
    if (brush.color !== null) return;
    brush.color = defaults.get(conn.me);
    saveBrush(brush);
    controls.showBrush();
  }

  function meshShown(id) {
    showStatus();
    ink.remove(id);
  }

  // Every mesh stored so far in one request (GET /v1/sessions/{id}/meshes, PMB3), started with
  // the page; the connection's PeerMesh events bring the ones stored later. A mesh several
  // strokes show (a duplicate's is its source's) comes once and is read once.
  async function loadBundle() {
    try {
      const strokes = await bundleRequest;
      const parsed = new Map(); // a mesh's bytes -> its parse
      await Promise.all(
        strokes.map(async (m) => {
          if (!parsed.has(m.glb)) parsed.set(m.glb, view.parse(m.glb));
          const flat = await parsed.get(m.glb);
          const s = view.stroke(m.stroke, m.participant);
          // The bundle's placement and solid, unless the connection said newer ones already;
          // the solid before the mesh shows, so that a hole is drawn as one from the start.
          if (m.placement && !s.placement) view.setPlacement(m.stroke, m.placement);
          // (No solid: a bundle of an older layout, from a replica not yet upgraded.)
          if (m.solid && !solidSaid.has(m.stroke)) view.setSolid(m.stroke, m.participant, m.solid);
          if (!view.addMesh(m.stroke, m.participant, flat)) return;
          meshShown(m.stroke);
          // Built as another solid than the one the connection said: its new mesh is fetched
          // when announced.
          if (m.solid && !sameSolid(s.solid, m.solid)) s.meshStale = true;
        }),
      );
    } catch (err) {
      if (err.status === 401) return refuse();
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

  /// Fetches and shows stroke `id`'s mesh, unless it has one; a stroke whose solid changed
  /// since its mesh came (view.setSolid), or `replace`, has its mesh fetched again and replaced.
  /// A new mesh announced while one is being fetched is fetched after it (an undo right after
  /// a change: the first fetch may bring the mesh before it).
  async function loadMesh(id, participant, replace = false) {
    const stale = replace || Boolean(view.strokes.get(id)?.meshStale);
    if (loading.has(id)) {
      if (stale) fetchAgain.add(id);
      return;
    }
    if (view.hasMesh(id) && !stale) return;
    loading.add(id);
    try {
      const flat = await view.parse(await api.strokeMesh(id));
      if (view.hasMesh(id)) {
        view.replaceMesh(id, participant, flat);
        if (editor.selection.ids.has(id)) editor.selection.refresh();
      } else if (view.addMesh(id, participant, flat)) meshShown(id);
    } catch (err) {
      fail(`cannot show the mesh of stroke ${id}: ${err.message}`);
    } finally {
      loading.delete(id);
      if (fetchAgain.delete(id)) loadMesh(id, participant, true);
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
      if (editor.penUpAt.has(id)) {
        await view.drawn();
        timings.push(performance.now() - editor.penUpAt.get(id));
      }
    } catch (err) {
      building.delete(id); // asked again when the history next comes (a reconnect, a reload)
      fail(`cannot build the mesh of stroke ${id}: ${err.message}`);
    }
  }

  function onMessage(kind, m) {
    switch (kind) {
      case "welcome":
        people.set(m.participant, controls.name);
        showPeople();
        controls.showBrush();
        $("status").textContent = "loading the session…";
        break;
      case "synced":
        $("status").textContent = `${view.shownStrokes} strokes`;
        if (!fitted) {
          fitted = true;
          editor.fit();
          colourApartFromOthers();
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
        if (kind === "peer_joined" && m.participant !== conn.me) assignDefault(m.participant);
        people.set(m.participant, m.name);
        showPeople();
        break;
      case "stroke_removed":
      case "stroke_restored":
        view.setRemoved(m.stroke, kind === "stroke_removed");
        if (kind === "stroke_removed") ink.remove(m.stroke);
        editor.selection.refresh();
        break;
      case "peer_left":
        people.delete(m.participant);
        showPeople();
        break;
      case "peer_stroke_begin":
        view.stroke(m.stroke, m.participant, m.brush);
        // Our own colour is our brush's (controls.onBrush), not that of a copy we made of
        // another's stroke (a duplicate keeps its source's brush).
        if (m.participant !== conn.me) brushUsed(m.participant, m.brush);
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
      case "peer_placement":
        view.setPlacement(m.stroke, m.placement.matrix);
        // Only a selected stroke's box and gizmo follow it (a history's hundreds of placements
        // ask for no frame).
        if (editor.selection.ids.has(m.stroke)) editor.selection.refresh();
        break;
      case "peer_solid":
        // The mesh the proxy builds for it follows (peer_mesh), and replaces the one shown.
        solidSaid.add(m.stroke);
        view.setSolid(m.stroke, m.participant, m.solid);
        if (editor.selection.ids.has(m.stroke)) editor.selection.refresh();
        break;
      case "error":
        if (m.code === "not_owner") editor.notice("that stroke is someone else's: you can take back only your own");
        // A placement refused (not ours, still open, gone): the stroke back where the proxy has it.
        if (["not_owner", "stroke_open", "unknown_stroke"].includes(m.code) && m.stroke && view.strokes.get(m.stroke)?.done) {
          api.placement(m.stroke).then((p) => {
            view.setPlacement(m.stroke, p);
            editor.selection.refresh();
          }, () => {});
        }
        fail(`proxy: ${m.code}: ${m.message}`);
        break;
      case "refused":
        refuse();
        return;
      case "closed":
        $("status").textContent = `disconnected (${m.code}${m.reason ? ": " + m.reason : ""}); reconnecting…`;
        return;
      default:
        break;
    }
    showStatus();
  }

  loadBundle();
}
