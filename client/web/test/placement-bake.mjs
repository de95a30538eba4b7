// The finished meshes grouped by person and placement (client/web/src/batch.js), checked in
// Node without a browser. Nothing is baked any more (the file keeps its name for
// scripts/test.sh): a group's object has the placement as its matrix and its vertices are the
// meshes' own, bit for bit. A closed solid (a tetrahedron, outward winding and normals) at the
// board, a turn, the front plane, a scale, a mirror and a mirror with a turn is drawn wound
// outward as three.js draws it (the face's winding in the scene, turned round where the
// object's world matrix mirrors, which is what three.js's renderer does with its culling).
// Strokes at one placement share one group (one draw call); a stroke placed anew moves to its
// new placement's group, hidden and lifted as it was, and a group left empty is dropped. Run
// by scripts/test.sh as `node client/web/test/placement-bake.mjs`.
import assert from "node:assert/strict";
import * as THREE from "three";
import { StrokeGroups } from "../src/batch.js";
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

// The scene's world flips y (scene.js), as the page's does.
const world = new THREE.Group();
world.scale.set(1, -1, 1);
const groups = new StrokeGroups(new THREE.MeshBasicMaterial(), world);

/// Checks a stroke's range: its group's object at the placement, its vertices the mesh's own,
/// every triangle wound outward as three.js draws it, the vertex normals (turned by the normal
/// matrix, as the shader does) along the faces.
function check(range, placement, what) {
  const group = range.group;
  assert.deepEqual(group.mesh.matrix.toArray(), matrixOf(placement).toArray(), `${what}: the group's matrix is not the placement`);
  assert.deepEqual(group.positions.slice(range.firstVertex * 3, (range.firstVertex + range.vertexCount) * 3), flat.positions, `${what}: the vertices are not the mesh's own`);
  world.updateMatrixWorld(true);
  const m = group.mesh.matrixWorld;
  // three.js's renderer: an object whose world matrix mirrors has its front face clockwise.
  const cw = m.determinant() < 0;
  const normalMatrix = new THREE.Matrix3().getNormalMatrix(m);
  const v = (i) => new THREE.Vector3().fromArray(group.positions, i * 3).applyMatrix4(m);
  const centre = new THREE.Vector3();
  for (const c of corners) centre.add(new THREE.Vector3(...c).applyMatrix4(m).multiplyScalar(1 / corners.length));
  for (let t = 0; t < range.indexCount; t += 3) {
    const [a, b, c] = [0, 1, 2].map((k) => v(group.indices[range.firstIndex + t + k]));
    const face = b.clone().sub(a).cross(c.clone().sub(a));
    if (cw) face.negate();
    const out = a.clone().add(b).add(c).multiplyScalar(1 / 3).sub(centre);
    assert.ok(face.dot(out) > 0, `${what}: triangle ${t / 3} is drawn wound inward`);
    const n = new THREE.Vector3().fromArray(group.normals, group.indices[range.firstIndex + t] * 3).applyMatrix3(normalMatrix).normalize();
    assert.ok(n.dot(face.normalize()) > 0.99, `${what}: triangle ${t / 3}'s normal is not its face's`);
  }
}

const ada = "ada";
const colour = new THREE.Color(0x336699);
const first = groups.add(flat, ada, colour, null); // another stroke before it
const turned = placementOf(new THREE.Matrix4().makeRotationAxis(new THREE.Vector3(1, 2, 3).normalize(), 0.7).setPosition(40, -5, 12));
const mirror = mirroredX(null, 25);
const mirrorTurned = mirroredX(turned, -3);
const scaledFront = placementOf(matrixOf(FRONT).multiply(new THREE.Matrix4().makeScale(2.5, 2.5, 2.5)));
let range = groups.add(flat, ada, colour, [...IDENTITY]);
assert.equal(range.group, first.group, "the identity is the board: one group");
check(range, null, "the board");
for (const [placement, what] of [[turned, "a turn"], [FRONT, "the front plane"], [scaledFront, "the front plane, scaled"], [mirror, "a mirror"], [mirrorTurned, "a mirror and a turn"]]) {
  assert.equal(mirrors(placement), what.includes("mirror"), `${what}: mirrors() says ${mirrors(placement)}`);
  const before = range.group;
  range = groups.place(range, ada, colour, placement);
  assert.notEqual(range.group, before, `${what}: the stroke did not move to another group`);
  check(range, placement, what);
  // Its own group, and the one it left dropped (but for the board's, which holds `first`).
  assert.equal(range.group.strokes, 1);
  assert.equal(groups.groups.size, 2, `${what}: ${groups.groups.size} groups`);
  assert.equal(world.children.length, 2, `${what}: ${world.children.length} objects in the scene`);
}

// Strokes of one person at one placement share a group; another person's are another group.
const again = groups.add(flat, ada, colour, [...mirrorTurned]);
assert.equal(again.group, range.group, "two strokes at one placement: one group");
assert.equal(again.group.strokes, 2);
const bob = groups.add(flat, "bob", colour, mirrorTurned);
assert.notEqual(bob.group, range.group, "another person's strokes are another group");
assert.equal(groups.groups.size, 3);

// Hidden, lifted out: collapsed; moved while hidden and lifted: still both; put back.
const collapsed = (r) => Array.from(r.group.indices.slice(r.firstIndex, r.firstIndex + r.indexCount)).every((i) => i === r.firstVertex);
range.group.setHidden(range, true);
range.group.setLifted(range, true);
assert.ok(collapsed(range), "a hidden, lifted stroke's triangles are collapsed");
const old = range;
range = groups.place(range, ada, colour, null);
assert.ok(range.hidden && range.lifted && collapsed(range), "moved, it stays hidden and lifted");
assert.ok(old.dropped && collapsed(old), "the range it left is collapsed");
assert.equal(again.group.strokes, 1, "the group it left keeps the other stroke");
range.group.setLifted(range, false);
range.group.setHidden(range, false);
assert.ok(!collapsed(range), "shown again");
check(range, null, "back on the board");
assert.equal(groups.place(range, ada, colour, [...IDENTITY]), range, "placed where it is: the same range");
assert.deepEqual(flat, frozen, "the mesh itself never changed");
console.log("PASS: groups at a turn, the front plane, a scale, a mirror, a mirror and a turn drawn wound outward; one group a placement; moves keep hidden and lifted; empty groups dropped; the mesh unchanged");
