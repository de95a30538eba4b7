// The work plane: the plane the pen draws on, shown as a grid. The board (the identity, z = 0),
// the two planes standing on it (front, side), the plane of a picked stroke, or the plane
// through three picked points; moved along its normal by `offset`. Its placement is what a
// stroke begun on it carries (`stroke_begin.placement`); the view draws the pen's pointer ray
// onto it (scene.js `toStroke`). The grid, a finite faded patch (grid.js), follows the
// camera's target along the plane; on the board itself the ground's grid shows it (ground.js).
import * as THREE from "three";
import { fadedGrid } from "./grid.js";
import { FRONT, IDENTITY, SIDE, isIdentity, matrixOf } from "./placement.js";

/// A grid cell, in plane units (one CSS pixel at one to one); the gizmo snaps to GRID_SNAP.
export const GRID_CELL = 50;
export const GRID_SNAP = 10;
const GRID_CELLS = 16;

export const PLANES = { board: IDENTITY, front: FRONT, side: SIDE };

export class WorkPlane {
  /// `view`: the 3D view (scene.js), whose `workPlacement` this sets.
  constructor(view) {
    this.view = view;
    this.kind = "board"; // board | front | side | stroke | points
    this.base = IDENTITY;
    this.offset = 0; // along the normal, plane units
    this.onChange = () => {};
    this.grid = fadedGrid(GRID_CELL, GRID_CELLS);
    view.world.add(this.grid);
    this.apply();
  }

  /// The plane's placement (16 numbers; null: the board itself).
  get placement() {
    if (this.offset === 0) return isIdentity(this.base) ? null : [...this.base];
    const m = [...this.base];
    const n = Math.hypot(m[8], m[9], m[10]);
    for (let k = 0; k < 3; k++) m[12 + k] += (m[8 + k] / n) * this.offset;
    return m;
  }

  /// One of PLANES by name, or a placement picked (`kind` "stroke" or "points"). A named
  /// plane goes through `through` (a THREE.Vector3 of session space: the selection's or the
  /// model's centre; its foot on the board, so a standing plane's y is the height).
  set(kind, base = PLANES[kind], through = null) {
    this.kind = kind;
    this.base = [...(base || IDENTITY)];
    if (through && kind !== "board" && kind in PLANES) [this.base[12], this.base[13]] = [through.x, through.y];
    this.offset = 0;
    this.apply();
  }

  /// Moves the plane along its normal by `d` plane units.
  move(d) {
    this.offset += d;
    this.apply();
  }

  /// Puts the plane `offset` plane units along its normal from where it was set.
  setOffset(offset) {
    this.offset = offset;
    this.apply();
  }

  /// Moves the plane by `d` plane units away from the camera (toward it when `d` is negative):
  /// along its normal, the way that faces away from the camera (a plane seen edge-on: its
  /// normal's way).
  moveAway(d) {
    const m = matrixOf(this.placement);
    const normal = new THREE.Vector3().setFromMatrixColumn(m, 2).normalize();
    const camera = this.view.camera.position.clone().applyMatrix4(new THREE.Matrix4().makeScale(1, -1, 1)); // to session space
    const origin = new THREE.Vector3().setFromMatrixPosition(m);
    const side = normal.dot(origin.sub(camera));
    this.move(side < -1e-9 ? -d : d);
  }

  apply() {
    this.view.workPlacement = this.placement;
    this.follow();
    this.onChange(this);
  }

  /// The grid under the camera's target: its centre the cell of the plane nearest to it.
  follow() {
    const rig = this.view.rig;
    const m = matrixOf(this.placement);
    const target = rig.target.clone().applyMatrix4(m.clone().invert());
    const snap = (v) => Math.round(v / GRID_CELL) * GRID_CELL;
    this.grid.matrix.copy(m.multiply(new THREE.Matrix4().makeTranslation(snap(target.x), snap(target.y), 0)));
    // On the board itself, the ground's grid (ground.js) is the plane's.
    this.grid.visible = this.placement !== null;
    this.view.requestRender();
  }
}
