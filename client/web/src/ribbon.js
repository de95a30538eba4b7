// A live stroke before its mesh comes: the top face of what its mesh will be, a ribbon of its
// retained points, each as wide as the brush makes its pressure (the proxy's formula, shared/
// src/model.rs `Brush::radius`), at the height and with the normals of the mesh's rims
// (shared/src/mesh.rs), so the other person sees a live stroke at its width and shaded as its
// mesh will be.
import * as THREE from "three";

// The proxy's default brush (shared/src/model.rs), for a stroke whose brush is not known.
export const DEFAULT_BRUSH = { size: 8, pressure_response: 0.5, min_radius: 0.25 };
// The mesh's half-thickness, as a multiple of the radius (shared/src/mesh.rs DEFAULT_THICKNESS).
const THICKNESS = 0.5;

/// `max(r_min, E · chi · p)`.
export function radiusOf(brush, p) {
  const b = brush || DEFAULT_BRUSH;
  return Math.max(b.min_radius, b.size * b.pressure_response * p);
}

/// The ribbon of `points` (THREE.Vector3, stroke coordinates) with `pressures`, in `colour`.
export function ribbonGeometry(points, pressures, brush, colour) {
  const n = points.length;
  const positions = new Float32Array(n * 2 * 3);
  const normals = new Float32Array(n * 2 * 3);
  const colours = new Float32Array(n * 2 * 3);
  const index = [];
  const tilt = 1 / Math.hypot(THICKNESS, 1);
  for (let i = 0; i < n; i++) {
    const a = points[Math.max(0, i - 1)];
    const b = points[Math.min(n - 1, i + 1)];
    let [dx, dy] = [b.x - a.x, b.y - a.y];
    const length = Math.hypot(dx, dy) || 1;
    [dx, dy] = [dx / length, dy / length];
    const r = radiusOf(brush, pressures[i] ?? 0.5);
    for (const [side, sign] of [[0, 1], [1, -1]]) {
      // The outline's outward normal on this side: the direction turned by a quarter.
      const [ox, oy] = [-dy * sign, dx * sign];
      const o = (2 * i + side) * 3;
      positions.set([points[i].x + ox * r, points[i].y + oy * r, THICKNESS * r], o);
      normals.set([THICKNESS * ox * tilt, THICKNESS * oy * tilt, tilt], o);
      colours.set([colour.r, colour.g, colour.b], o);
    }
    if (i > 0) {
      const [u0, l0, u1, l1] = [2 * i - 2, 2 * i - 1, 2 * i, 2 * i + 1];
      index.push(u0, l0, u1, u1, l0, l1);
    }
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.BufferAttribute(positions, 3));
  g.setAttribute("normal", new THREE.BufferAttribute(normals, 3));
  g.setAttribute("colour", new THREE.BufferAttribute(colours, 3));
  g.setIndex(index);
  return g;
}
