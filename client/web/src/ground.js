// The ground: the board (z = 0) shown as a faded grid patch under what the camera looks at,
// on every session, with the session's axes marked at its origin (x red, y green, z blue:
// three.js's and Blender's colours); two draw calls. Seen straight from above the page itself is the board,
// so the grid there is only a hint (faint enough that the page reads as blank); turned, it is
// the floor the model stands on.
import * as THREE from "three";
import { fadedGrid } from "./grid.js";

const CELL = 50;
const CELLS = 40;
const AXIS_LENGTH = 200;
const OPACITY = { top: 0.035, turned: 0.7 };

export class Ground {
  /// `view`: the 3D view (scene.js); the grid lies in its `world` (session coordinates).
  constructor(view) {
    this.view = view;
    this.grid = fadedGrid(CELL, CELLS);
    this.grid.renderOrder = -1;
    view.world.add(this.grid);
    this.axes = axes();
    view.world.add(this.axes);
    this.follow();
  }

  /// The grid under the camera's target (snapped to a cell), faint from straight above.
  follow() {
    const { target, top } = this.view.rig;
    const snap = (v) => Math.round(v / CELL) * CELL;
    this.grid.matrix.makeTranslation(snap(target.x), snap(target.y), 0);
    this.grid.material.opacity = top ? OPACITY.top : OPACITY.turned;
    this.axes.material.opacity = top ? OPACITY.top * 2 : 1;
    this.view.requestRender();
  }
}

/// The three axes from the origin, each AXIS_LENGTH long (y down the board, as session y):
/// one object, one draw call.
function axes() {
  const positions = [];
  const colours = [];
  for (const [to, hex] of [[[1, 0, 0], 0xd03030], [[0, 1, 0], 0x30a030], [[0, 0, 1], 0x3050d0]]) {
    const c = new THREE.Color(hex);
    positions.push(0, 0, 0, ...to.map((v) => v * AXIS_LENGTH));
    colours.push(c.r, c.g, c.b, c.r, c.g, c.b);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
  g.setAttribute("color", new THREE.Float32BufferAttribute(colours, 3));
  const lines = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ vertexColors: true, transparent: true, depthWrite: false }));
  lines.frustumCulled = false;
  return lines;
}
