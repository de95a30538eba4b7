// The camera the person moves, a turntable that keeps "up" (TinkerCAD's, Onshape's; three.js's
// OrbitControls with a fixed up): it looks at a point of the session (`target`, session
// coordinates: x right, y down the board, z up out of it) at a scale (CSS pixels per unit at
// the target), from a direction given by a turn about the up axis (`yaw`) and a tilt away
// from straight above (`pitch`: 0 looks down on the board, as the page shows it; a quarter
// turn looks at the model from the side, level). The screen's right is always level, so the
// view never rolls: a sideways drag turns about up, a vertical drag tilts, stopped at the top
// and short of straight below. Zoom keeps the point under the pointer where it is, pan moves
// the view with the pointer (both on the plane through the target facing the camera). A
// resize keeps it all; a named view (`look`) or `fit` sets it.
import * as THREE from "three";

const MIN_SCALE = 0.02;
const MAX_SCALE = 64;
// From straight above (0) to short of straight below: never past a pole.
const MAX_PITCH = THREE.MathUtils.degToRad(170);
// Radians of turn per CSS pixel dragged.
export const ORBIT_PER_PX = 0.006;

/// The named views, as {yaw, pitch}: from above (the page's own view of the board), from the
/// front (the bottom edge of the board), from the right side, and a three-quarter view from
/// the front right, above.
export const VIEWS = {
  top: { yaw: 0, pitch: 0 },
  front: { yaw: 0, pitch: Math.PI / 2 },
  side: { yaw: Math.PI / 2, pitch: Math.PI / 2 },
  three: { yaw: THREE.MathUtils.degToRad(30), pitch: THREE.MathUtils.degToRad(60) },
};

/// Session coordinates (y down the board) to three.js's world (the scene flips y).
export const toWorld = (x, y, z) => new THREE.Vector3(x, -y, z);

export class CameraRig {
  constructor(camera, width, height) {
    this.camera = camera;
    this.width = width;
    this.height = height;
    // At first, one unit of the board is one CSS pixel and session (x, y) is page (x, y).
    this.target = new THREE.Vector3(width / 2, height / 2, 0);
    this.scale = 1;
    this.yaw = 0;
    this.pitch = 0;
    this.ray = new THREE.Raycaster();
    this.plane = new THREE.Plane(new THREE.Vector3(0, 0, 1), 0);
    this.apply();
  }

  /// Looking straight down on the board, unturned: the page's own view.
  get top() {
    return this.yaw === 0 && this.pitch === 0;
  }

  /// The page changed size: the camera keeps its target, scale and turn.
  resize(width, height) {
    this.width = width;
    this.height = height;
    this.apply();
  }

  /// The camera's distance at which one unit at the target is one CSS pixel.
  oneToOne() {
    return this.height / 2 / Math.tan(THREE.MathUtils.degToRad(this.camera.fov / 2));
  }

  /// The unit vector from the target toward the camera and the screen's right (both level
  /// when seen from the side), in three.js's world.
  axes() {
    const [sy, cy, sp, cp] = [Math.sin(this.yaw), Math.cos(this.yaw), Math.sin(this.pitch), Math.cos(this.pitch)];
    return { back: new THREE.Vector3(sy * sp, -cy * sp, cp), right: new THREE.Vector3(cy, sy, 0) };
  }

  /// Puts the three.js camera where target, scale and turn say; its up is the screen's up,
  /// square to the level right, so it never rolls (and needs no special case straight above).
  apply() {
    const c = this.camera;
    c.aspect = this.width / this.height;
    const distance = this.oneToOne() / this.scale;
    const t = toWorld(this.target.x, this.target.y, this.target.z);
    const { back, right } = this.axes();
    c.position.copy(t).addScaledVector(back, distance);
    c.near = distance / 100;
    c.far = distance * 100;
    c.up.copy(back.clone().cross(right));
    c.lookAt(t);
    c.updateProjectionMatrix();
    c.updateMatrixWorld();
  }

  rayAt(x, y) {
    this.ray.setFromCamera(new THREE.Vector2((x / this.width) * 2 - 1, -(y / this.height) * 2 + 1), this.camera);
    return this.ray.ray;
  }

  /// The point of the board (session coordinates, z = 0) under page point (`x`, `y`), or null.
  toPlane(x, y) {
    const hit = new THREE.Vector3();
    if (!this.rayAt(x, y).intersectPlane(this.plane, hit)) return null;
    return new THREE.Vector2(hit.x, -hit.y);
  }

  /// The point under page point (`x`, `y`) of the plane through the target facing the camera
  /// (session coordinates), or null.
  toViewPlane(x, y) {
    const { back } = this.axes();
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(back, toWorld(this.target.x, this.target.y, this.target.z));
    const hit = new THREE.Vector3();
    if (!this.rayAt(x, y).intersectPlane(plane, hit)) return null;
    return new THREE.Vector3(hit.x, -hit.y, hit.z);
  }

  /// Where point (`x`, `y`, `z`) of the session is on the page, in CSS pixels.
  toPage(x, y, z = 0) {
    const v = toWorld(x, y, z).project(this.camera);
    return [((v.x + 1) / 2) * this.width, ((1 - v.y) / 2) * this.height];
  }

  /// Zooms by `factor` about page point (`x`, `y`): the point under it stays there.
  zoomAt(x, y, factor) {
    const before = this.toViewPlane(x, y);
    this.scale = THREE.MathUtils.clamp(this.scale * factor, MIN_SCALE, MAX_SCALE);
    this.apply();
    const after = this.toViewPlane(x, y);
    if (before && after) {
      this.target.add(before.sub(after));
      this.apply();
    }
  }

  /// Moves the view with a pointer that went from page point `from` to `to` ([x, y]).
  panBy(from, to) {
    const a = this.toViewPlane(...from);
    const b = this.toViewPlane(...to);
    if (!a || !b) return;
    this.target.add(a.sub(b));
    this.apply();
  }

  /// Turns the camera about its target by a drag of (`dx`, `dy`) CSS pixels: sideways about
  /// the up axis, up and down in tilt (a drag down shows more of the top).
  orbitBy(dx, dy) {
    this.yaw = wrapAngle(this.yaw - dx * ORBIT_PER_PX);
    this.pitch = THREE.MathUtils.clamp(this.pitch - dy * ORBIT_PER_PX, 0, MAX_PITCH);
    this.apply();
  }

  /// Named view `name` (VIEWS) of `box` (a THREE.Box3 of session coordinates): looking at its
  /// centre, all of it in sight with a margin, never closer than one to one; an empty box
  /// keeps the target and scale.
  look(name, box) {
    Object.assign(this, VIEWS[name]);
    if (!box.isEmpty()) {
      box.getCenter(this.target);
      // The box's extent across the screen and up it, from its corners.
      this.apply();
      const { back, right } = this.axes();
      const up = back.clone().cross(right);
      let [w, h] = [0, 0];
      const centre = toWorld(this.target.x, this.target.y, this.target.z);
      for (let i = 0; i < 8; i++) {
        const c = toWorld(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z).sub(centre);
        [w, h] = [Math.max(w, Math.abs(c.dot(right))), Math.max(h, Math.abs(c.dot(up)))];
      }
      const margin = 0.1 * Math.max(w, h) + 10;
      this.scale = Math.min(1, this.height / (2 * (h + margin)), this.width / (2 * (w + margin)));
    }
    this.apply();
  }

  /// The view from above of `box` (the whole drawing): the one reset of the camera.
  fit(box) {
    this.look("top", box);
  }
}

/// An angle in (-π, π].
function wrapAngle(a) {
  const turns = Math.round(a / (2 * Math.PI));
  return a - turns * 2 * Math.PI;
}
