// The 3D view: the three.js renderer, camera and orbit controls, and the session's strokes in
// it: a live stroke as a polyline of its retained points, finished ones as meshes merged per
// person (one draw call each, batch.js), each in its brush's colour or else its person's. A
// stroke taken back is hidden until it is brought back. It renders only when something
// changed: the camera moved, a stroke grew or a mesh came (no frame while idle). Stroke
// coordinates are screen-like (y down); the scene flips y.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { GLTFExporter } from "three/examples/jsm/exporters/GLTFExporter.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";
import { MergedMeshes, flatten } from "./batch.js";
import { readGlb } from "./glb.js";

/// A participant's colour, the same on every page.
export function colourOf(participant) {
  let h = 0;
  for (const c of participant) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return new THREE.Color().setHSL((h % 360) / 360, 0.65, 0.45);
}

/// A stroke's colour: its brush's (`color`, 0xRRGGBB) when it has one, else its drawer's.
export function strokeColour(participant, brush) {
  return brush && Number.isInteger(brush.color) ? new THREE.Color(brush.color) : colourOf(participant);
}

/// The distance from point `p` to the segment `a`-`b` (each with `x` and `y`).
function segmentDistance(p, a, b) {
  const [dx, dy] = [b.x - a.x, b.y - a.y];
  const length2 = dx * dx + dy * dy;
  const t = length2 > 0 ? Math.max(0, Math.min(1, ((p.x - a.x) * dx + (p.y - a.y) * dy) / length2)) : 0;
  return Math.hypot(p.x - (a.x + t * dx), p.y - (a.y + t * dy));
}

// Cheap to shade: the light is worked out once per vertex (a light over the viewer's shoulder
// and an ambient part), and a pixel only takes the colour its vertices give it.
const VERTEX_SHADER = `
attribute vec3 colour;
varying vec3 vColour;
void main() {
  vec3 n = normalize(normalMatrix * normal);
  float light = max(dot(n, vec3(0.29, 0.48, 0.83)), 0.0);
  vColour = colour * (0.55 + 0.6 * light);
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;
const FRAGMENT_SHADER = `
varying vec3 vColour;
void main() {
  gl_FragColor = vec4(vColour, 1.0);
  #include <colorspace_fragment>
}`;

/// Whether a WebGL context is drawn on the CPU (SwiftShader, llvmpipe).
function softwareWebGL(gl) {
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const renderer = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
  return /swiftshader|llvmpipe|software/i.test(renderer);
}

/// The renderer: multisampled on a GPU, not in software WebGL, where multisampling costs a
/// frame about 2.3 times as much (docs/performance.md). The first context, without
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
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.enabled = false;
    this.controls.addEventListener("change", () => this.requestRender());
    this.strokes = new Map(); // stroke -> {participant, colour, done, removed, points: [Vector3], line, mesh: its range in its person's merged meshes}
    this.meshCount = 0;
    this.removedCount = 0; // strokes taken back
    this.hiddenMeshCount = 0; // meshes of strokes taken back
    this.people = new Map(); // participant -> MergedMeshes
    this.material = new THREE.ShaderMaterial({ vertexShader: VERTEX_SHADER, fragmentShader: FRAGMENT_SHADER });
    this.lineMaterials = new Map(); // colour as hex -> LineBasicMaterial
    this.changedLines = new Set(); // strokes whose polyline is rebuilt at the next frame
    this.front = null; // the front view fitted to the drawing, {x, y, distance}; null: one to one
    this.frames = 0; // frames rendered (the browser test checks that an idle page renders none)
    this.frameQueued = false;
    // For GLBs the page's own reader leaves alone (parse). The meshes may be meshopt-compressed
    // (EXT_meshopt_compression); plain ones load as well.
    this.loader = new GLTFLoader();
    this.loader.setMeshoptDecoder(MeshoptDecoder);
    this.ray = new THREE.Raycaster();
    this.plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
    this.frontView();
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

  /// The front view: the camera faces the drawing plane, at the fitted view, or with the
  /// page's pixels one to one on the z = 0 plane (a stroke drawn at (x, y) CSS pixels lands at
  /// stroke coordinates (x, y)). Also fits the renderer to the page.
  frontView() {
    const w = innerWidth;
    const h = innerHeight;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    const { x, y, distance } = this.front || { x: w / 2, y: h / 2, distance: this.oneToOne() };
    this.camera.position.set(x, -y, distance);
    this.controls.target.set(x, -y, 0);
    this.camera.updateProjectionMatrix();
    this.controls.update();
    this.requestRender();
  }

  /// The camera's distance at which one unit on the plane is one CSS pixel.
  oneToOne() {
    return innerHeight / 2 / Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
  }

  /// CSS pixels per unit of the plane in the front view.
  pixelsPerUnit() {
    return this.front ? this.oneToOne() / this.front.distance : 1;
  }

  /// Fits the front view to what is drawn (the retained points of every stroke, with a
  /// margin), never closer than one to one; the front view stays where it is when nothing is.
  fitToDrawing() {
    const box = new THREE.Box2();
    for (const s of this.strokes.values()) if (!s.removed) for (const p of s.points) box.expandByPoint(p);
    if (box.isEmpty()) return;
    const size = box.getSize(new THREE.Vector2());
    const margin = 0.05 * Math.max(size.x, size.y) + 10;
    const height = Math.max(size.y + 2 * margin, (size.x + 2 * margin) / this.camera.aspect);
    const distance = height / 2 / Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
    const centre = box.getCenter(new THREE.Vector2());
    this.front = { x: centre.x, y: centre.y, distance: Math.max(distance, this.oneToOne()) };
    this.frontView();
  }

  /// Orbit mode: the controls move the camera. Leaving it faces the drawing plane again (the
  /// pen draws on the plane as seen from the front).
  setOrbit(orbit) {
    this.controls.enabled = orbit;
    if (!orbit) this.frontView();
  }

  /// The stroke `id` of `participant`, drawn with `brush` when it is known (its begin): its
  /// colour follows the brush, a mesh already shown included.
  stroke(id, participant, brush) {
    let s = this.strokes.get(id);
    if (!s) {
      s = { participant, colour: strokeColour(participant, brush), done: false, removed: false, points: [], line: null, mesh: null };
      this.strokes.set(id, s);
    } else if (brush) {
      s.colour = strokeColour(participant, brush);
      if (s.mesh) this.person(participant).setColour(s.mesh, s.colour);
      if (s.line) s.line.material = this.lineMaterial(s.colour);
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
      this.person(s.participant).setHidden(s.mesh, removed);
    }
    if (s.line) s.line.visible = !removed;
    this.requestRender();
  }

  /// Strokes shown (not taken back), and those of them shown with a mesh.
  get shownStrokes() {
    return this.strokes.size - this.removedCount;
  }

  get shownMeshes() {
    return this.meshCount - this.hiddenMeshCount;
  }

  /// The shown, finished strokes of `participant` that pass within `radius` of the point
  /// (`x`, `y`) of the drawing plane (their retained points joined by segments), for the eraser.
  strokesAt(x, y, radius, participant) {
    const p = { x, y };
    const hits = [];
    for (const [id, s] of this.strokes) {
      if (s.participant !== participant || s.removed || !s.done) continue;
      const pts = s.points;
      for (let i = 0; i < pts.length; i++) {
        if (segmentDistance(p, pts[i], pts[Math.min(i + 1, pts.length - 1)]) <= radius) {
          hits.push(id);
          break;
        }
      }
    }
    return hits;
  }

  lineMaterial(colour) {
    const hex = colour.getHex();
    if (!this.lineMaterials.has(hex)) this.lineMaterials.set(hex, new THREE.LineBasicMaterial({ color: colour }));
    return this.lineMaterials.get(hex);
  }

  hasMesh(id) {
    const s = this.strokes.get(id);
    return Boolean(s && s.mesh);
  }

  /// A person's merged meshes.
  person(participant) {
    let merged = this.people.get(participant);
    if (!merged) {
      merged = new MergedMeshes(this.material);
      this.world.add(merged.mesh);
      this.people.set(participant, merged);
    }
    return merged;
  }

  /// A stroke's retained points from index `first` on (kept for the fit): until its mesh
  /// comes, its polyline grows at the next frame.
  addRetained(id, participant, first, points) {
    const s = this.stroke(id, participant);
    s.points.length = Math.min(s.points.length, first);
    for (const [x, y] of points) s.points.push(new THREE.Vector3(x, y, 0));
    if (s.mesh) return;
    this.changedLines.add(s);
    this.requestRender();
  }

  rebuildLine(s) {
    this.removeLine(s);
    if (s.mesh || s.points.length === 0) return;
    s.line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(s.points), this.lineMaterial(s.colour));
    s.line.visible = !s.removed;
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

  /// Shows a stroke's mesh (from `parse`) in its person's merged meshes, in place of its
  /// polyline; false when it already had one.
  addMesh(id, participant, flat) {
    const s = this.stroke(id, participant);
    if (s.mesh) return false;
    const merged = this.person(participant);
    s.mesh = merged.add(flat, s.colour);
    if (s.removed) {
      merged.setHidden(s.mesh, true);
      this.hiddenMeshCount += 1;
    }
    this.removeLine(s);
    this.meshCount += 1;
    this.requestRender();
    return true;
  }

  /// Where on the drawing plane (stroke coordinates) a point of the page is, whatever the view;
  /// null when the plane is not under it.
  toStroke(clientX, clientY) {
    const r = this.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
    this.ray.setFromCamera(ndc, this.camera);
    const hit = new THREE.Vector3();
    if (!this.ray.ray.intersectPlane(this.plane, hit)) return null;
    return [hit.x, -hit.y];
  }

  /// Resolves once what the scene holds now has been drawn on screen.
  drawn() {
    this.requestRender();
    return new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  }

  /// Every mesh on screen in one GLB (strokes taken back left out), each stroke a node named by
  /// its id, in its colour.
  async exportGlb() {
    const root = new THREE.Group();
    root.scale.set(1, -1, 1);
    const materials = new Map(); // colour as hex -> material
    for (const [id, s] of this.strokes) {
      if (!s.mesh || s.removed) continue;
      const hex = s.colour.getHex();
      if (!materials.has(hex)) materials.set(hex, new THREE.MeshStandardMaterial({ color: s.colour }));
      const mesh = new THREE.Mesh(this.person(s.participant).geometryOf(s.mesh), materials.get(hex));
      mesh.name = id;
      root.add(mesh);
    }
    try {
      return await new Promise((ok, err) => new GLTFExporter().parse(root, ok, err, { binary: true }));
    } finally {
      root.traverse((o) => o.geometry && o.geometry.dispose());
    }
  }
}
