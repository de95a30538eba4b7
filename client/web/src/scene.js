// The 3D view: the three.js renderer, camera and orbit controls, and the session's strokes in
// it: a live stroke as a polyline of its retained points, a finished one as its mesh, each in
// its person's colour. Stroke coordinates are screen-like (y down); the scene flips y.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { GLTFExporter } from "three/examples/jsm/exporters/GLTFExporter.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

/// A participant's colour, the same on every page.
export function colourOf(participant) {
  let h = 0;
  for (const c of participant) h = (h * 31 + c.charCodeAt(0)) >>> 0;
  return new THREE.Color().setHSL((h % 360) / 360, 0.65, 0.45);
}

export class SceneView {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xf4f3ef);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(300, 500, 1000);
    this.scene.add(sun);
    // Stroke coordinates are screen-like (y down): flip y so the drawing is not upside down.
    this.world = new THREE.Group();
    this.world.scale.set(1, -1, 1);
    this.scene.add(this.world);
    this.camera = new THREE.PerspectiveCamera(40, 1, 1, 100000);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enabled = false;
    this.strokes = new Map(); // stroke -> {participant, points: [Vector3], line, mesh}
    this.meshCount = 0;
    this.materials = new Map(); // participant -> material
    this.loader = new GLTFLoader();
    this.ray = new THREE.Raycaster();
    this.plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
    this.frontView();
    this.renderer.setAnimationLoop(() => {
      this.controls.update();
      this.renderer.render(this.scene, this.camera);
    });
  }

  /// The front view: the page's pixels one to one on the z = 0 plane, so a stroke drawn at
  /// (x, y) CSS pixels lands at stroke coordinates (x, y). Also fits the renderer to the page.
  frontView() {
    const w = innerWidth;
    const h = innerHeight;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    const distance = h / 2 / Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
    this.camera.position.set(w / 2, -h / 2, distance);
    this.controls.target.set(w / 2, -h / 2, 0);
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  /// Orbit mode: the controls move the camera. Leaving it faces the drawing plane again (the
  /// pen draws on the plane as seen from the front).
  setOrbit(orbit) {
    this.controls.enabled = orbit;
    if (!orbit) this.frontView();
  }

  stroke(id, participant) {
    let s = this.strokes.get(id);
    if (!s) {
      s = { participant, points: [], line: null, mesh: null };
      this.strokes.set(id, s);
    }
    return s;
  }

  hasMesh(id) {
    const s = this.strokes.get(id);
    return Boolean(s && s.mesh);
  }

  /// A live stroke: a polyline of its retained points, replaced by the mesh when it comes.
  addRetained(id, participant, points) {
    const s = this.stroke(id, participant);
    if (s.mesh) return;
    for (const [x, y] of points) s.points.push(new THREE.Vector3(x, y, 0));
    this.removeLine(s);
    s.line = new THREE.Line(
      new THREE.BufferGeometry().setFromPoints(s.points),
      new THREE.LineBasicMaterial({ color: colourOf(participant) }),
    );
    this.world.add(s.line);
  }

  removeLine(s) {
    if (!s.line) return;
    this.world.remove(s.line);
    s.line.geometry.dispose();
    s.line = null;
  }

  // One material per person: Lambert shading, cheap enough for software WebGL with 1,000 strokes.
  materialOf(participant) {
    let m = this.materials.get(participant);
    if (!m) {
      m = new THREE.MeshLambertMaterial({
        color: colourOf(participant),
        side: THREE.DoubleSide, // the group's y flip turns the winding around
      });
      this.materials.set(participant, m);
    }
    return m;
  }

  /// Shows a stroke's mesh (a GLB) in its person's colour, in place of its polyline.
  async addGlb(id, participant, glb) {
    const gltf = await this.loader.parseAsync(glb, "");
    const s = this.stroke(id, participant);
    if (s.mesh) return;
    const material = this.materialOf(participant);
    gltf.scene.traverse((o) => {
      if (o.isMesh) o.material = material;
    });
    s.mesh = gltf.scene;
    this.world.add(s.mesh);
    this.removeLine(s);
    this.meshCount += 1;
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
    return new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  }

  /// Every mesh on screen in one GLB, each stroke a node.
  exportGlb() {
    return new Promise((ok, err) => new GLTFExporter().parse(this.world, ok, err, { binary: true }));
  }
}
