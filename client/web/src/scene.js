// The 3D view: the three.js renderer, the camera (camera.js) and the session's strokes in it:
// a live stroke as a ribbon of its retained points at its brush's width (ribbon.js), finished
// ones as meshes merged per person and placement (one draw call each, batch.js), each in its
// brush's colour or else its person's. No stroke is drawn thinner than MIN_WIDTH_PX on screen. A
// stroke taken back is hidden until it is brought back. It renders only when something
// changed: the camera moved, a stroke grew or a mesh came (no frame while idle). Stroke
// coordinates are screen-like (y down); the scene flips y. Each stroke stands where its
// placement (placement.js) puts it: the node matrix of its ribbon, of its mesh lifted out, or
// of the group its mesh is merged into (batch.js); its mesh never changes. The pen
// draws on the work plane (`workPlacement`, workplane.js): `toStroke` and `toPage` are in its
// coordinates.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";
import { StrokeGroups, flatten } from "./batch.js";
import { matrixOf, samePlacement } from "./placement.js";
import { CameraRig } from "./camera.js";
import { radiusOf, ribbonGeometry } from "./ribbon.js";
import { readGlb } from "./glb.js";

/// Colours far apart from each other (every two at least 84 apart in RGB, over settings.js's
/// MIN_COLOUR_DISTANCE): a person's default is one of them (session.js picks one the others
/// who joined before do not use).
export const PALETTE = [0xd62828, 0x1d6fd6, 0x2a9d3a, 0xe07a00, 0x7b3fc4, 0x12a88a, 0xc2188c, 0x5a3a1a, 0x7a8a00, 0x26307a];

/// A participant's colour before they chose one, the same on every page.
export function colourOf(participant) {
  let h = 0;
  for (const c of participant) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return new THREE.Color(PALETTE[h % PALETTE.length]);
}

/// A stroke's colour: its brush's (`color`, 0xRRGGBB) when it has one, else its drawer's.
export function strokeColour(participant, brush) {
  return brush && Number.isInteger(brush.color) ? new THREE.Color(brush.color) : colourOf(participant);
}

// A stroke narrower than this on screen (device pixels) is drawn this wide: a thinner one
// falls between pixel centres and shows as a dashed line.
const MIN_WIDTH_PX = 1.5;
// Cheap to shade: the light is worked out once per vertex (a light over the viewer's shoulder
// and an ambient part), and a pixel only takes the colour its vertices give it. A stroke's rim
// vertex stands at z = ±thickness·r (shared/src/mesh.rs, thickness 0.5) and its normal points
// out of the outline: where 2r is under MIN_WIDTH_PX on screen, the vertex moves out along it.
// The widening costs little per vertex, with no branch (SwiftShader shades vertices on the CPU;
// the busy board's orbit frame is bound by its work per triangle and per covered pixel, and
// a plain vertex shader saves about a tenth of it: docs/performance-log.md, "What bounds an orbit
// frame"). `minHalfWidth` is half of
// MIN_WIDTH_PX in plane units per unit of depth (set by SceneView.resize), so at a vertex the
// least half-width is minHalfWidth · depth, and the move, made in view space, needs no second
// projection. Each matrix multiplies a vector, never another matrix. Positions and normals are
// the mesh's own, in its plane (its group's object carries the placement, batch.js).
const VERTEX_SHADER = `
attribute vec3 colour;
uniform float minHalfWidth;
varying vec3 vColour;
void main() {
  vec3 n = normalize(normalMatrix * normal);
  float light = max(dot(n, vec3(0.29, 0.48, 0.83)), 0.0);
  vColour = colour * (0.55 + 0.6 * light);
  vec4 mv = modelViewMatrix * vec4(position, 1.0);
  float grow = max(minHalfWidth * -mv.z - 2.0 * abs(position.z), 0.0);
  vec2 push = normal.xy * (grow * inversesqrt(max(dot(normal.xy, normal.xy), 1e-12)));
  mv.xyz += modelViewMatrix[0].xyz * push.x + modelViewMatrix[1].xyz * push.y;
  gl_Position = projectionMatrix * mv;
}`;
const FRAGMENT_SHADER = `
varying vec3 vColour;
void main() {
  gl_FragColor = vec4(vColour, 1.0);
  #include <colorspace_fragment>
}`;

// A hole (a stroke whose solid is a hole, docs/protocol.md "Solids") is shown as TinkerCAD
// shows one: see-through grey, hatched with screen-space stripes, so what it cuts stays visible
// under it. It is drawn over whatever is in front of it and writes no depth, so a hole inside
// a plate (or behind a wall) still shows where it cuts, and the solids around it are drawn whole.
const HOLE_FRAGMENT_SHADER = `
varying vec3 vColour;
void main() {
  float stripe = step(5.0, mod(gl_FragCoord.x + gl_FragCoord.y, 10.0));
  gl_FragColor = vec4(mix(vec3(0.45), vColour, 0.25), mix(0.25, 0.6, stripe));
  #include <colorspace_fragment>
}`;

/// Whether a stroke's solid (`{kind, depth}` or null: the rod) is a hole.
export const isHole = (solid) => Boolean(solid && solid.kind === "hole");
/// Whether two solids (`{kind, depth}`; null: the rod) are the same.
export const sameSolid = (a, b) => (a?.kind ?? "line") === (b?.kind ?? "line") && (a?.depth ?? null) === (b?.depth ?? null);

/// Whether a WebGL context is drawn on the CPU (SwiftShader, llvmpipe).
function softwareWebGL(gl) {
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const renderer = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
  return /swiftshader|llvmpipe|software/i.test(renderer);
}

/// The renderer: multisampled on a GPU, not in software WebGL, where multisampling costs a
/// frame about 2.3 times as much (docs/performance-log.md). The first context, without
/// multisampling, tells which: a software one is kept (another context would cost about 0.4 s
/// there, before anything is shown); on a GPU the canvas is swapped for a fresh one with a
/// multisampled context (a context's attributes are fixed when it is made), cheap there.
function createRenderer(canvas) {
  const plain = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  if (softwareWebGL(plain.getContext())) return plain;
  plain.forceContextLoss();
  plain.dispose();
  const fresh = canvas.cloneNode(false);
  canvas.replaceWith(fresh);
  return new THREE.WebGLRenderer({ canvas: fresh, antialias: true, preserveDrawingBuffer: true });
}

/// The print's default longest side (mm: penmesh_print::DEFAULT_SIZE_MM).
export const DEFAULT_PRINT_MM = 100;

export class SceneView {
  constructor(canvas) {
    this.renderer = createRenderer(canvas);
    this.canvas = this.renderer.domElement;
    this.renderer.setPixelRatio(window.devicePixelRatio);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xf4f3ef);
    // Stroke coordinates are screen-like (y down): flip y so the drawing is not upside down
    // (three.js turns the winding of the flipped meshes around for culling).
    this.world = new THREE.Group();
    this.world.scale.set(1, -1, 1);
    this.scene.add(this.world);
    this.camera = new THREE.PerspectiveCamera(40, 1, 1, 100000);
    this.rig = new CameraRig(this.camera, innerWidth, innerHeight);
    // stroke -> {participant, colour, brush, done, removed, points: [Vector3], pressures,
    // line: its live ribbon, mesh: its range in its group's merged meshes (batch.js),
    // placement: 16 numbers or null (the board), lifted: its own object while selected,
    // solid: {kind, depth} or null (the rod), meshStale: its solid changed, its mesh not yet,
    // box: its mesh's box at its placement, kept until either changes (placedBox)}
    this.strokes = new Map();
    this.meshCount = 0;
    this.removedCount = 0; // strokes taken back
    this.hiddenMeshCount = 0; // meshes of strokes taken back
    this.workPlacement = null; // the plane the pen draws on (null: the board)
    this.printMm = DEFAULT_PRINT_MM; // the print's longest side (the Export menu's, export.js)
    this.material = new THREE.ShaderMaterial({ vertexShader: VERTEX_SHADER, fragmentShader: FRAGMENT_SHADER, uniforms: { minHalfWidth: { value: 0 } } });
    // A live ribbon is one face: seen from either side.
    this.ribbonMaterial = new THREE.ShaderMaterial({ vertexShader: VERTEX_SHADER, fragmentShader: FRAGMENT_SHADER, uniforms: this.material.uniforms, side: THREE.DoubleSide });
    this.holeMaterial = new THREE.ShaderMaterial({ vertexShader: VERTEX_SHADER, fragmentShader: HOLE_FRAGMENT_SHADER, uniforms: this.material.uniforms, transparent: true, depthTest: false, depthWrite: false });
    this.groups = new StrokeGroups(this.material, this.world, this.holeMaterial); // the finished meshes
    this.changedLines = new Set(); // strokes whose polyline is rebuilt at the next frame
    this.frames = 0; // frames rendered (the browser test checks that an idle page renders none)
    this.frameQueued = false;
    // For GLBs the page's own reader leaves alone (parse). The meshes may be meshopt-compressed
    // (EXT_meshopt_compression); plain ones load as well.
    this.loader = new GLTFLoader();
    this.loader.setMeshoptDecoder(MeshoptDecoder);
    this.resize();
  }

  /// Draws one frame at the next animation frame (several requests, one frame).
  requestRender() {
    if (this.frameQueued) return;
    this.frameQueued = true;
    requestAnimationFrame(() => {
      this.frameQueued = false;
      for (const s of this.changedLines) this.rebuildLine(s);
      this.changedLines.clear();
      this.renderer.render(this.scene, this.camera);
      this.frames += 1;
    });
  }

  /// Fits the renderer to the page; the camera stays where it is (camera.js).
  resize() {
    this.renderer.setSize(innerWidth, innerHeight, false);
    this.rig.resize(innerWidth, innerHeight);
    // Half of MIN_WIDTH_PX in plane units, per unit of depth: the screen's height in device
    // pixels spans 2 / projection[1][1] units at depth 1.
    const heightPx = innerHeight * this.renderer.getPixelRatio();
    this.material.uniforms.minHalfWidth.value = MIN_WIDTH_PX / (heightPx * this.camera.projectionMatrix.elements[5]);
    this.requestRender();
  }

  /// CSS pixels per unit of the plane at the camera's target.
  pixelsPerUnit() {
    return this.rig.scale;
  }

  /// The box of what is drawn (the retained points of every stroke shown, placed), in session
  /// coordinates.
  drawingBox() {
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (const s of this.strokes.values()) {
      if (s.removed) continue;
      const m = matrixOf(s.placement);
      for (const p of s.points) box.expandByPoint(v.copy(p).applyMatrix4(m));
    }
    return box;
  }

  /// The box of what the print is made of, in session coordinates: the meshes of the strokes
  /// shown at their placements (a hole only takes away), and the retained points of those
  /// without a mesh yet.
  modelBox() {
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (const s of this.strokes.values()) {
      if (s.removed || isHole(s.solid)) continue;
      if (s.mesh) box.union(this.placedBox(s));
      else for (const p of s.points) box.expandByPoint(v.copy(p).applyMatrix4(matrixOf(s.placement)));
    }
    return box;
  }

  /// Stroke `s`'s mesh's box at its placement (session space), worked out again only after
  /// its mesh or its placement changed.
  placedBox(s) {
    if (!s.box) {
      const m = matrixOf(s.placement);
      const v = new THREE.Vector3();
      const { positions } = s.mesh.flat;
      s.box = new THREE.Box3();
      for (let i = 0; i < positions.length; i += 3) s.box.expandByPoint(v.fromArray(positions, i).applyMatrix4(m));
    }
    return s.box;
  }

  /// The print's millimetres per unit of the session, as the Export menu makes it: the print
  /// is scaled so that its longest side is `printMm` (docs/print.md), and its solids are the
  /// meshes' (within the thickness floor the print gives a stroke thinner than it).
  mmPerUnit() {
    const size = this.modelBox().getSize(new THREE.Vector3());
    const longest = Math.max(size.x, size.y, size.z);
    return longest > 0 ? this.printMm / longest : 0;
  }

  /// Fits the view from above to what is drawn (with a margin), never closer than one to one.
  fitToDrawing() {
    this.rig.fit(this.drawingBox());
    this.requestRender();
  }

  /// Named view `name` (camera.js VIEWS) of what is drawn.
  look(name) {
    this.rig.look(name, this.drawingBox());
    this.requestRender();
  }

  /// The camera moved (camera.js): drawn at the next frame.
  cameraMoved() {
    this.requestRender();
  }

  /// The stroke `id` of `participant`, drawn with `brush` when it is known (its begin): its
  /// colour follows the brush, a mesh already shown included.
  stroke(id, participant, brush) {
    let s = this.strokes.get(id);
    if (!s) {
      s = { participant, colour: strokeColour(participant, brush), brush: brush || null, done: false, removed: false, points: [], pressures: [], line: null, mesh: null, placement: null, lifted: null, solid: null, meshStale: false, box: null };
      this.strokes.set(id, s);
    } else if (brush) {
      s.colour = strokeColour(participant, brush);
      s.brush = brush;
      if (s.mesh) s.mesh.group.setColour(s.mesh, s.colour);
      if (s.line) this.changedLines.add(s);
      this.requestRender();
    }
    return s;
  }

  /// Hides a stroke taken back (`removed`) or shows it again.
  setRemoved(id, removed) {
    const s = this.strokes.get(id);
    if (!s || s.removed === removed) return;
    s.removed = removed;
    const change = removed ? 1 : -1;
    this.removedCount += change;
    if (s.mesh) {
      this.hiddenMeshCount += change;
      s.mesh.group.setHidden(s.mesh, removed);
    }
    if (s.line) s.line.visible = !removed;
    if (s.lifted) s.lifted.visible = !removed;
    this.requestRender();
  }

  /// Places stroke `id` (16 numbers, as the proxy said or as a gesture goes): its ribbon's or
  /// lifted object's matrix; its mesh into the group of its placement (a lifted one when it is
  /// put back: a drag places it at every step).
  setPlacement(id, placement) {
    const s = this.strokes.get(id);
    if (!s) return;
    // The same placement again (the history's `peer_placement` after the bundle said it, our
    // own echoed): nothing to move, no frame to draw.
    const same = samePlacement(s.placement, placement);
    s.placement = placement;
    if (same) return;
    s.box = null;
    const m = matrixOf(placement);
    if (s.line) s.line.matrix.copy(m);
    if (s.lifted) s.lifted.matrix.copy(m);
    else if (s.mesh) s.mesh = this.groups.place(s.mesh, s.participant, s.colour, placement, isHole(s.solid));
    this.requestRender();
  }

  /// Stroke `id`'s solid (`{kind, depth}`, docs/protocol.md "Solids"): a hole's mesh drawn as a
  /// hole at once; the mesh itself is the old solid's until `replaceMesh` brings the new one
  /// (the proxy builds it after the solid is set), so it is marked stale when it changed.
  setSolid(id, participant, solid) {
    const s = this.stroke(id, participant);
    const same = sameSolid(s.solid, solid);
    s.solid = solid.kind === "line" && solid.depth === null ? null : solid;
    if (same) return;
    if (s.mesh) s.meshStale = true;
    if (s.lifted) s.lifted.material = isHole(s.solid) ? this.holeMaterial : this.material;
    else if (s.mesh) s.mesh = this.groups.place(s.mesh, s.participant, s.colour, s.placement, isHole(s.solid));
    this.requestRender();
  }

  /// Each shown stroke's box with a mesh in session space (its mesh at its placement), by id:
  /// `{min: [x, y, z], max: [x, y, z]}` (the browser tests compare pages by them).
  boxes() {
    const boxes = {};
    for (const [id, s] of this.strokes) {
      if (!s.mesh || s.removed) continue;
      const box = this.placedBox(s);
      boxes[id] = { min: box.min.toArray(), max: box.max.toArray() };
    }
    return boxes;
  }

  /// Lifts stroke `id`'s mesh out of its group's merged meshes as its own object, its
  /// placement its matrix (what a gizmo moves); null when it has no mesh.
  liftOut(id) {
    const s = this.strokes.get(id);
    if (!s || !s.mesh) return null;
    if (!s.lifted) {
      s.mesh.group.setLifted(s.mesh, true);
      s.lifted = new THREE.Mesh(s.mesh.group.geometryOf(s.mesh), isHole(s.solid) ? this.holeMaterial : this.material);
      s.lifted.matrixAutoUpdate = false;
      s.lifted.matrix.copy(matrixOf(s.placement));
      s.lifted.visible = !s.removed;
      s.lifted.name = id;
      this.world.add(s.lifted);
      this.requestRender();
    }
    return s.lifted;
  }

  /// Puts a lifted stroke back into the merged meshes of its group (that of its placement now).
  putBack(id) {
    const s = this.strokes.get(id);
    if (!s || !s.lifted) return;
    this.world.remove(s.lifted);
    s.lifted.geometry.dispose();
    s.lifted = null;
    s.mesh = this.groups.place(s.mesh, s.participant, s.colour, s.placement, isHole(s.solid));
    s.mesh.group.setLifted(s.mesh, false);
    this.requestRender();
  }

  /// Strokes shown (not taken back), and those of them shown with a mesh.
  get shownStrokes() {
    return this.strokes.size - this.removedCount;
  }

  get shownMeshes() {
    return this.meshCount - this.hiddenMeshCount;
  }

  /// The shown, finished strokes drawn under page point (`x`, `y`), whatever their plane: their
  /// retained points joined by segments, as the page shows them, within `reachPx` CSS px
  /// beyond their width (the eraser: what is under the cursor is what it rubs).
  strokesUnder(x, y, reachPx) {
    const hits = [];
    const ppu = this.pixelsPerUnit();
    for (const [id, s] of this.strokes) {
      if (s.removed || !s.done || s.points.length === 0) continue;
      const scale = s.placement ? Math.hypot(s.placement[0], s.placement[1], s.placement[2]) : 1;
      const reach = reachPx + radiusOf(s.brush, 1) * scale * ppu;
      let a = this.toPage(s.points[0].x, s.points[0].y, s.placement);
      for (let i = 0; i < s.points.length; i++) {
        const b = i + 1 < s.points.length ? this.toPage(s.points[i + 1].x, s.points[i + 1].y, s.placement) : a;
        if (pageDistance(x, y, a, b) <= reach) {
          hits.push(id);
          break;
        }
        a = b;
      }
    }
    return hits;
  }

  hasMesh(id) {
    const s = this.strokes.get(id);
    return Boolean(s && s.mesh);
  }

  /// A stroke's retained points `[x, y, t, p]` from index `first` on (kept for the fit and
  /// the eraser): until its mesh comes, its ribbon grows at the next frame.
  addRetained(id, participant, first, points) {
    const s = this.stroke(id, participant);
    s.points.length = Math.min(s.points.length, first);
    s.pressures.length = s.points.length;
    for (const [x, y, , p] of points) {
      s.points.push(new THREE.Vector3(x, y, 0));
      s.pressures.push(p);
    }
    if (s.mesh) return;
    this.changedLines.add(s);
    this.requestRender();
  }

  rebuildLine(s) {
    this.removeLine(s);
    if (s.mesh || s.points.length === 0) return;
    s.line = new THREE.Mesh(ribbonGeometry(s.points, s.pressures, s.brush, s.colour), this.ribbonMaterial);
    s.line.visible = !s.removed;
    s.line.matrixAutoUpdate = false;
    s.line.matrix.copy(matrixOf(s.placement));
    this.world.add(s.line);
  }

  removeLine(s) {
    if (!s.line) return;
    this.world.remove(s.line);
    s.line.geometry.dispose();
    s.line = null;
  }

  /// Reads a stroke's mesh (a GLB) for `addMesh`: with the page's own reader (glb.js), or,
  /// for a file it leaves alone (its `plan` says which), with three.js's GLTFLoader.
  async parse(glb) {
    return (await readGlb(glb)) ?? flatten((await this.loader.parseAsync(glb, "")).scene);
  }

  /// Shows a stroke's mesh (from `parse`) in the merged meshes of its person and placement,
  /// in place of its polyline; false when it already had one.
  addMesh(id, participant, flat) {
    const s = this.stroke(id, participant);
    if (s.mesh) return false;
    s.mesh = this.groups.add(flat, participant, s.colour, s.placement, isHole(s.solid));
    s.box = null;
    if (s.removed) {
      s.mesh.group.setHidden(s.mesh, true);
      this.hiddenMeshCount += 1;
    }
    this.removeLine(s);
    this.meshCount += 1;
    this.requestRender();
    return true;
  }

  /// Shows stroke `id`'s new mesh (its solid changed) in place of the one it had: the old range
  /// dropped, the new one in the group of its placement and solid, lifted out again when it was.
  replaceMesh(id, participant, flat) {
    const s = this.stroke(id, participant);
    s.meshStale = false;
    if (!s.mesh) return this.addMesh(id, participant, flat);
    const lifted = Boolean(s.lifted);
    if (lifted) {
      this.world.remove(s.lifted);
      s.lifted.geometry.dispose();
      s.lifted = null;
    }
    const hidden = s.mesh.hidden;
    this.groups.drop(s.mesh);
    s.mesh = this.groups.add(flat, s.participant, s.colour, s.placement, isHole(s.solid));
    s.box = null;
    s.mesh.group.setHidden(s.mesh, hidden);
    if (lifted) this.liftOut(id);
    this.requestRender();
    return true;
  }

  /// Where on the work plane (its own coordinates, those of a stroke drawn on it) a point of
  /// the page is, whatever the view: the pointer's ray onto the plane; null when the plane is
  /// not under it.
  toStroke(clientX, clientY) {
    const rig = this.rig;
    if (!this.workPlacement) {
      const hit = rig.toPlane(clientX, clientY); // the board: the camera's own plane
      return hit ? [hit.x, hit.y] : null;
    }
    const ndc = new THREE.Vector2((clientX / rig.width) * 2 - 1, -(clientY / rig.height) * 2 + 1);
    rig.ray.setFromCamera(ndc, this.camera);
    // The ray in the plane's coordinates (the world's y flip, then the placement, undone).
    const toLocal = new THREE.Matrix4().makeScale(1, -1, 1).multiply(matrixOf(this.workPlacement)).invert();
    const ray = rig.ray.ray.clone().applyMatrix4(toLocal);
    const hit = ray.intersectPlane(new THREE.Plane(new THREE.Vector3(0, 0, 1), 0), new THREE.Vector3());
    return hit ? [hit.x, hit.y] : null;
  }

  /// Where a point (`x`, `y`) of a plane (`placement`: by default the work plane) is on the page
  /// (CSS pixels).
  toPage(x, y, placement = this.workPlacement) {
    // Called for every ink point at every redraw: no matrix made.
    const m = placement;
    if (!m) return this.rig.toPage(x, y);
    return this.rig.toPage(m[0] * x + m[4] * y + m[12], m[1] * x + m[5] * y + m[13], m[2] * x + m[6] * y + m[14]);
  }

  /// Resolves once what the scene holds now has been drawn on screen.
  drawn() {
    this.requestRender();
    return new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  }
}

/// The distance from page point (`px`, `py`) to the segment `a`-`b` ([x, y] each).
function pageDistance(px, py, [ax, ay], [bx, by]) {
  const [dx, dy] = [bx - ax, by - ay];
  const length2 = dx * dx + dy * dy;
  const t = length2 > 0 ? Math.max(0, Math.min(1, ((px - ax) * dx + (py - ay) * dy) / length2)) : 0;
  return Math.hypot(px - (ax + t * dx), py - (ay + t * dy));
}
