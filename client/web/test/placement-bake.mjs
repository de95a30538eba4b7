// The merged copy of a placed mesh (client/web/src/batch.js), checked in Node without a
// browser: a closed solid (a tetrahedron, outward winding and normals) baked at the board, a
// turn, a mirror and a mirror with a turn keeps every triangle wound outward (its face normal,
// from the winding, points away from the solid's centre and along its vertex normals), and its
// vertices are the mesh's moved by the placement. Setting the placement back restores the first
// copy bit for bit: the mesh itself never changes. Run by scripts/test.sh as
// `node client/web/test/placement-bake.mjs`.
import assert from "node:assert/strict";
import * as THREE from "three";
import { MergedMeshes } from "../src/batch.js";
import { FRONT, IDENTITY, matrixOf, mirroredX, mirrors, placementOf } from "../src/placement.js";

const corners = [[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]];
// Wound counter-clockwise seen from outside.
const faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
const positions = [];
const normals = [];
const indices = [];
for (const face of faces) {
  const [a, b, c] = face.map((i) => new THREE.Vector3(...corners[i]));
  const n = b.clone().sub(a).cross(c.clone().sub(a)).normalize();
  for (const p of [a, b, c]) {
    indices.push(positions.length / 3);
    positions.push(p.x, p.y, p.z);
    normals.push(n.x, n.y, n.z);
  }
}
const flat = { positions: new Float32Array(positions), normals: new Float32Array(normals), indices: new Uint32Array(indices) };
const frozen = { positions: flat.positions.slice(), normals: flat.normals.slice(), indices: flat.indices.slice() };

/// Checks the merged copy of `range`: outward winding, normals along the faces, vertices at
/// the placement.
function check(merged, range, placement, what) {
  const m = matrixOf(placement);
  const v = (i) => new THREE.Vector3().fromArray(merged.positions, i * 3);
  const centre = new THREE.Vector3();
  for (const c of corners) centre.add(new THREE.Vector3(...c).applyMatrix4(m).multiplyScalar(1 / corners.length));
  for (let t = 0; t < range.indexCount; t += 3) {
    const [a, b, c] = [0, 1, 2].map((k) => v(merged.indices[range.firstIndex + t + k]));
    const face = b.clone().sub(a).cross(c.clone().sub(a));
    const out = a.clone().add(b).add(c).multiplyScalar(1 / 3).sub(centre);
    assert.ok(face.dot(out) > 0, `${what}: triangle ${t / 3} is wound inward`);
    const n = new THREE.Vector3().fromArray(merged.normals, merged.indices[range.firstIndex + t] * 3);
    assert.ok(n.dot(face.normalize()) > 0.99, `${what}: triangle ${t / 3}'s normal is not its face's`);
  }
  for (let i = 0; i < range.vertexCount; i++) {
    const want = new THREE.Vector3().fromArray(flat.positions, i * 3).applyMatrix4(m);
    assert.ok(v(range.firstVertex + i).distanceTo(want) < 1e-4, `${what}: vertex ${i} is not at its placement`);
  }
}

const merged = new MergedMeshes(new THREE.MeshBasicMaterial());
merged.add(flat, new THREE.Color(0x336699)); // another stroke before it
const range = merged.add(flat, new THREE.Color(0x336699), null);
const board = { positions: merged.positions.slice(), indices: merged.indices.slice() };
check(merged, range, null, "the board");
const turned = placementOf(new THREE.Matrix4().makeRotationAxis(new THREE.Vector3(1, 2, 3).normalize(), 0.7).setPosition(40, -5, 12));
const mirror = mirroredX(null, 25);
const mirrorTurned = mirroredX(turned, -3);
const scaledFront = placementOf(matrixOf(FRONT).multiply(new THREE.Matrix4().makeScale(2.5, 2.5, 2.5)));
for (const [placement, what] of [[turned, "a turn"], [FRONT, "the front plane"], [scaledFront, "the front plane, scaled"], [mirror, "a mirror"], [mirrorTurned, "a mirror and a turn"]]) {
  assert.equal(mirrors(placement), what.includes("mirror"), `${what}: mirrors() says ${mirrors(placement)}`);
  merged.setPlacement(range, placement);
  check(merged, range, placement, what);
}
// Lifted out (selected) and put back, then the board again: the first copy, bit for bit.
merged.setLifted(range, true);
for (let i = 0; i < range.indexCount; i++) assert.equal(merged.indices[range.firstIndex + i], range.firstVertex, "a lifted stroke's triangles are collapsed");
merged.setLifted(range, false);
merged.setPlacement(range, IDENTITY);
assert.deepEqual(merged.positions.slice(0, board.positions.length), board.positions, "back on the board: the same vertices");
assert.deepEqual(merged.indices.slice(0, board.indices.length), board.indices, "back on the board: the same triangles");
assert.deepEqual(flat, frozen, "the mesh itself never changed");
console.log("PASS: placed copies wound outward at a turn, the front plane, a scale, a mirror, a mirror and a turn; the mesh unchanged");
