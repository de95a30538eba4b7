// A grid as a finite patch that fades out toward its rim (so it never cuts across the whole
// view, nor through the model far from where one works): `cells` cells a side of `cell` units
// in the x-y plane of its object, centred on its origin, the two middle lines darker. Each
// line is cut at every cell: a line that passes behind the camera was not drawn at all in
// software WebGL (SwiftShader), whole. Vertex alpha does the fade.
import * as THREE from "three";

export function fadedGrid(cell, cells) {
  const half = (cell * cells) / 2;
  const positions = [];
  const colours = [];
  const [dark, light] = [new THREE.Color(0x8a8a80), new THREE.Color(0xb8b7af)];
  // Opaque in the middle half, then fading to nothing at the rim.
  const alpha = (x, y) => Math.max(0, Math.min(1, 2 - (2 * Math.hypot(x, y)) / half));
  for (let i = 0; i <= cells; i++) {
    const k = -half + i * cell;
    const c = i === cells / 2 ? dark : light;
    for (let j = 0; j < cells; j++) {
      const [a, b] = [-half + j * cell, -half + (j + 1) * cell];
      for (const [x, y] of [[a, k], [b, k], [k, a], [k, b]]) {
        positions.push(x, y, 0);
        colours.push(c.r, c.g, c.b, alpha(x, y));
      }
    }
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
  g.setAttribute("color", new THREE.Float32BufferAttribute(colours, 4));
  const grid = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ vertexColors: true, transparent: true, opacity: 0.8, depthWrite: false }));
  grid.matrixAutoUpdate = false;
  grid.frustumCulled = false;
  return grid;
}
