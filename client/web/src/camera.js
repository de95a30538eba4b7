// The camera the person moves: a point of the drawing plane it looks at (`target`, stroke
// coordinates), a scale (CSS pixels per unit of the plane there) and a turn (`yaw`, `pitch`;
// both 0 is the front view, facing the plane). Zoom keeps the plane point under the pointer
// where it is, pan moves the plane with the pointer, orbit turns about the target. A resize
// keeps all three (the view stays where the person put it); only `fit` resets them.
import * as THREE from "three";

const MIN_SCALE = 0.02;
const MAX_SCALE = 64;
const MAX_PITCH = THREE.MathUtils.degToRad(85);
// Radians of turn per CSS pixel dragged.
const ORBIT_PER_PX = 0.006;

export class CameraRig {
  constructor(camera, width, height) {
    this.camera = camera;
    this.width = width;
    this.height = height;
    // At first, one unit of the plane is one CSS pixel and stroke (x, y) is page (x, y).
    this.target = new THREE.Vector2(width / 2, height / 2);
    this.scale = 1;
    this.yaw = 0;
    this.pitch = 0;
    this.ray = new THREE.Raycaster();
    this.plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
    this.apply();
  }

  get front() {
    return this.yaw === 0 && this.pitch === 0;
  }

  /// The page changed size: the camera keeps its target, scale and turn.
  resize(width, height) {
    this.width = width;
    this.height = height;
    this.apply();
  }

  /// The camera's distance at which one unit on the plane is one CSS pixel.
  oneToOne() {
    return this.height / 2 / Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
  }

  /// Puts the three.js camera where target, scale and turn say (the scene flips y).
  apply() {
    const c = this.camera;
    c.aspect = this.width / this.height;
    const distance = this.oneToOne() / this.scale;
    const t = new THREE.Vector3(this.target.x, -this.target.y, 0);
    const dir = new THREE.Vector3(Math.sin(this.yaw) * Math.cos(this.pitch), Math.sin(this.pitch), Math.cos(this.yaw) * Math.cos(this.pitch));
    c.position.copy(t).addScaledVector(dir, distance);
    c.near = distance / 100;
    c.far = distance * 100;
    c.up.set(0, 1, 0);
    c.lookAt(t);
    c.updateProjectionMatrix();
    c.updateMatrixWorld();
  }

  /// The point of the plane (stroke coordinates) under page point (`x`, `y`), or null.
  toPlane(x, y) {
    const ndc = new THREE.Vector2((x / this.width) * 2 - 1, -(y / this.height) * 2 + 1);
    this.ray.setFromCamera(ndc, this.camera);
    const hit = new THREE.Vector3();
    if (!this.ray.ray.intersectPlane(this.plane, hit)) return null;
    return new THREE.Vector2(hit.x, -hit.y);
  }

  /// Where point (`x`, `y`, `z`) of the session (stroke-like: y down) is on the page, in CSS
  /// pixels.
  toPage(x, y, z = 0) {
    const v = new THREE.Vector3(x, -y, z).project(this.camera);
    return [((v.x + 1) / 2) * this.width, ((1 - v.y) / 2) * this.height];
  }

  /// Zooms by `factor` about page point (`x`, `y`): the plane point under it stays there.
  zoomAt(x, y, factor) {
    const before = this.toPlane(x, y);
    this.scale = THREE.MathUtils.clamp(this.scale * factor, MIN_SCALE, MAX_SCALE);
    this.apply();
    const after = this.toPlane(x, y);
    if (before && after) {
      this.target.add(before.sub(after));
      this.apply();
    }
  }

  /// Moves the plane with a pointer that went from page point `from` to `to` ([x, y]).
  panBy(from, to) {
    const a = this.toPlane(...from);
    const b = this.toPlane(...to);
    if (!a || !b) return;
    this.target.add(a.sub(b));
    this.apply();
  }

  /// Turns the camera about its target by a drag of (`dx`, `dy`) CSS pixels.
  orbitBy(dx, dy) {
    this.yaw -= dx * ORBIT_PER_PX;
    this.pitch = THREE.MathUtils.clamp(this.pitch + dy * ORBIT_PER_PX, -MAX_PITCH, MAX_PITCH);
    this.apply();
  }

  /// The front view of `box` (a THREE.Box2 of stroke coordinates) with a margin, never closer
  /// than one to one; an empty box keeps the target and scale and only faces the plane.
  fit(box) {
    this.yaw = 0;
    this.pitch = 0;
    if (!box.isEmpty()) {
      const size = box.getSize(new THREE.Vector2());
      const margin = 0.05 * Math.max(size.x, size.y) + 10;
      this.scale = Math.min(1, this.height / (size.y + 2 * margin), this.width / (size.x + 2 * margin));
      box.getCenter(this.target);
    }
    this.apply();
  }
}
