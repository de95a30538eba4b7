// A stroke's placement (protocol 5, docs/protocol.md "Placements"): the similarity that maps its
// own plane (its samples and its mesh, z = 0 of its coordinates) into the session's 3D space,
// 16 numbers, column-major as glTF's `node.matrix`. Kept as a plain array of 16 doubles, so
// what the page sends is bit for bit what it was given (undo restores a placement exactly);
// THREE.Matrix4 only to compute. Session space is stroke-like (y down on the board); the
// scene's `world` group flips y for the screen (scene.js), so a placement is its node's matrix
// inside `world`.
import * as THREE from "three";

export const IDENTITY = Object.freeze([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
/// The plane standing on the board along x (docs/client.md: `penmesh draw --placement`).
export const FRONT = Object.freeze([1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1]);
/// The plane standing on the board along y: the front plane turned a quarter about z.
export const SIDE = Object.freeze([0, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 1]);

/// A THREE.Matrix4 of a placement (null: the identity).
export function matrixOf(placement) {
  return new THREE.Matrix4().fromArray(placement || IDENTITY);
}

/// A placement of a THREE.Matrix4: its 16 elements, column-major (a -0 made by the products
/// written 0, as JSON would).
export function placementOf(matrix) {
  return matrix.toArray(new Array(16)).map((v) => (v === 0 ? 0 : v));
}

export function isIdentity(placement) {
  return !placement || placement.every((v, i) => v === IDENTITY[i]);
}

/// Whether two placements are the same (null and the identity are the board).
export function samePlacement(a, b) {
  if (isIdentity(a) || isIdentity(b)) return isIdentity(a) && isIdentity(b);
  return a.every((v, i) => v === b[i]);
}

/// Whether a placement mirrors (a negative determinant): its mesh's winding is flipped.
export function mirrors(placement) {
  return Boolean(placement) && matrixOf(placement).determinant() < 0;
}

/// `placement` mirrored across the plane x = `cx` of session space.
export function mirroredX(placement, cx) {
  const mirror = new THREE.Matrix4().makeScale(-1, 1, 1).setPosition(2 * cx, 0, 0);
  return placementOf(mirror.multiply(matrixOf(placement)));
}

/// The placement of the plane through three points (THREE.Vector3, session space): origin at
/// the first, x toward the second, z its normal; null when they are (nearly) on one line.
export function planeThrough(a, b, c) {
  const x = b.clone().sub(a);
  const normal = x.clone().cross(c.clone().sub(a));
  if (x.length() < 1e-6 || normal.length() < 1e-6 * x.lengthSq()) return null;
  x.normalize();
  normal.normalize();
  const y = normal.clone().cross(x);
  return placementOf(new THREE.Matrix4().makeBasis(x, y, normal).setPosition(a));
}
