// Finished meshes merged into one geometry per (person, placement), so they cost one draw call
// a group however many there are (docs/web.md). A group's object has the placement as its
// matrix: a mesh never moves, its node does, so a stroke's vertices are copied as they came and
// nothing is baked on the CPU (three.js turns the culling round itself for a group whose matrix
// mirrors). A stroke placed anew (moved, undone) leaves its group for the group of its new
// placement, its own when no other stroke is there; a group left empty is dropped.
//
// In a group a new mesh is appended and only its part is uploaded; the buffers double when
// full. Each stroke keeps its range, for the GLB export, its colour (a vertex colour: a person
// may draw in several) and being hidden (a stroke taken back, or one that left the group: its
// triangles collapse to one point). A selected stroke is lifted out (select.js): collapsed
// here, drawn as its own object with the placement as its matrix, put back when it is let go.
import * as THREE from "three";
import { isIdentity, matrixOf } from "./placement.js";

const FIRST_VERTICES = 4096;

/// The key of a placement's group (null and the identity are the board).
function placementKey(placement) {
  return isIdentity(placement) ? "board" : placement.join(",");
}

/// The key of the group of `participant`'s meshes at `placement`, holes apart.
function groupKey(participant, placement, hole) {
  return `${participant} ${hole ? "hole " : ""}${placementKey(placement)}`;
}

/// Every finished mesh of the scene, in groups of one person and one placement.
export class StrokeGroups {
  /// `parent`: the THREE.Object3D the groups' objects are added to. Holes (a stroke whose
  /// solid is a hole) go in groups of their own, drawn with `holeMaterial`.
  constructor(material, parent, holeMaterial = material) {
    this.material = material;
    this.holeMaterial = holeMaterial;
    this.parent = parent;
    this.groups = new Map(); // "participant placement" -> MergedMeshes
  }

  /// The groups' objects (for picking).
  get objects() {
    return [...this.groups.values()].map((g) => g.mesh);
  }

  /// Adds a stroke's mesh (`flat`, as batch.js `add` takes it) of `participant` in `colour` at
  /// `placement`, among the holes when `hole`: its range, which knows its group.
  add(flat, participant, colour, placement, hole = false) {
    const key = groupKey(participant, placement, hole);
    let group = this.groups.get(key);
    if (!group) {
      group = new MergedMeshes(hole ? this.holeMaterial : this.material, placement);
      group.key = key;
      this.parent.add(group.mesh);
      this.groups.set(key, group);
    }
    return group.add(flat, colour);
  }

  /// The range of a stroke moved to `placement` (`participant`'s, in `colour`, a hole or not):
  /// the same one when it is already in that group, else one in that group, hidden and lifted
  /// as it was, the old one collapsed (its group dropped when nothing is left in it).
  place(range, participant, colour, placement, hole = false) {
    if (range.group.key === groupKey(participant, placement, hole)) return range;
    const moved = this.add(range.flat, participant, colour, placement, hole);
    moved.group.setHidden(moved, range.hidden);
    moved.group.setLifted(moved, range.lifted);
    this.drop(range);
    return moved;
  }

  /// Takes a stroke's range out of its group for good.
  drop(range) {
    const group = range.group;
    range.dropped = true;
    group.writeIndices(range);
    group.strokes -= 1;
    if (group.strokes > 0) return;
    this.parent.remove(group.mesh);
    group.mesh.geometry.dispose();
    this.groups.delete(group.key);
  }
}

/// One group's meshes merged into one geometry, its object at `placement` (16 numbers; null:
/// the board).
export class MergedMeshes {
  constructor(material, placement = null) {
    this.material = material;
    this.vertexCount = 0;
    this.indexCount = 0;
    this.strokes = 0; // ranges in it not dropped
    this.positions = new Float32Array(0);
    this.normals = new Float32Array(0);
    this.colours = new Uint8Array(0);
    this.indices = new Uint32Array(0);
    this.mesh = new THREE.Mesh(new THREE.BufferGeometry(), material);
    this.mesh.matrixAutoUpdate = false;
    this.mesh.matrix.copy(matrixOf(placement));
    // The drawing is one connected board; culling per group would save little.
    this.mesh.frustumCulled = false;
  }

  /// Appends a mesh given as flat `positions`, `normals` (Float32Array, 3 per vertex) and
  /// `indices` (into its own vertices), in `colour` (a THREE.Color); returns its range.
  add(flat, colour) {
    const nVertices = flat.positions.length / 3;
    this.reserve(this.vertexCount + nVertices, this.indexCount + flat.indices.length);
    const range = { group: this, firstVertex: this.vertexCount, vertexCount: nVertices, firstIndex: this.indexCount, indexCount: flat.indices.length, hidden: false, lifted: false, dropped: false, flat };
    this.vertexCount += nVertices;
    this.indexCount += flat.indices.length;
    this.strokes += 1;
    const at = range.firstVertex * 3;
    this.positions.set(flat.positions, at);
    this.normals.set(flat.normals, at);
    const g = this.mesh.geometry;
    for (const attribute of [g.attributes.position, g.attributes.normal]) {
      attribute.addUpdateRange(at, nVertices * 3);
      attribute.needsUpdate = true;
    }
    this.writeIndices(range);
    this.setColour(range, colour);
    g.setDrawRange(0, this.indexCount);
    return range;
  }

  /// Lifts one stroke's mesh out of the merged one (drawn on its own while selected), or
  /// puts it back.
  setLifted(range, lifted) {
    if (range.lifted === lifted) return;
    range.lifted = lifted;
    this.writeIndices(range);
  }

  /// Writes a range's indices: its own triangles, or, hidden, lifted out or dropped, every
  /// index at its first vertex (triangles of no area, which draw nothing).
  writeIndices(range) {
    const { firstVertex, firstIndex, flat } = range;
    const local = flat.indices;
    const gone = range.hidden || range.lifted || range.dropped;
    for (let i = 0; i < local.length; i++) this.indices[firstIndex + i] = gone ? firstVertex : local[i] + firstVertex;
    const index = this.mesh.geometry.index;
    index.addUpdateRange(firstIndex, local.length);
    index.needsUpdate = true;
  }
  /// Hides (`hidden`) or shows again one stroke's mesh.
  setHidden(range, hidden) {
    if (range.hidden === hidden) return;
    range.hidden = hidden;
    this.writeIndices(range);
  }

  /// Paints one stroke's mesh in `colour` (a THREE.Color).
  setColour(range, colour) {
    const [r, g, b] = [colour.r, colour.g, colour.b].map((c) => Math.round(c * 255));
    for (let v = range.firstVertex; v < range.firstVertex + range.vertexCount; v++) {
      this.colours[v * 3] = r;
      this.colours[v * 3 + 1] = g;
      this.colours[v * 3 + 2] = b;
    }
    const attribute = this.mesh.geometry.attributes.colour;
    attribute.addUpdateRange(range.firstVertex * 3, range.vertexCount * 3);
    attribute.needsUpdate = true;
  }

  /// Room for this many vertices and indices: a new geometry with buffers twice as large (the
  /// GPU's buffers cannot grow), the old one disposed.
  reserve(nVertices, nIndices) {
    if (nVertices * 3 <= this.positions.length && nIndices <= this.indices.length) return;
    const vertices = Math.max(FIRST_VERTICES, nVertices, (this.positions.length / 3) * 2);
    const indices = Math.max(vertices * 3, nIndices, this.indices.length * 2);
    const grow = (Type, old, n) => {
      const a = new Type(n);
      a.set(old);
      return a;
    };
    this.positions = grow(Float32Array, this.positions, vertices * 3);
    this.normals = grow(Float32Array, this.normals, vertices * 3);
    this.colours = grow(Uint8Array, this.colours, vertices * 3);
    this.indices = grow(Uint32Array, this.indices, indices);
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(this.positions, 3).setUsage(THREE.DynamicDrawUsage));
    g.setAttribute("normal", new THREE.BufferAttribute(this.normals, 3).setUsage(THREE.DynamicDrawUsage));
    g.setAttribute("colour", new THREE.BufferAttribute(this.colours, 3, true).setUsage(THREE.DynamicDrawUsage));
    g.setIndex(new THREE.BufferAttribute(this.indices, 1).setUsage(THREE.DynamicDrawUsage));
    g.setDrawRange(0, this.indexCount);
    this.mesh.geometry.dispose();
    this.mesh.geometry = g;
  }

  /// One stroke's mesh on its own, in its own plane's coordinates (for the export and for a
  /// stroke lifted out): copies of its mesh, with its colour.
  geometryOf({ firstVertex, vertexCount, flat }) {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(flat.positions.slice(), 3));
    g.setAttribute("normal", new THREE.BufferAttribute(flat.normals.slice(), 3));
    g.setAttribute("colour", new THREE.BufferAttribute(this.colours.slice(firstVertex * 3, (firstVertex + vertexCount) * 3), 3, true));
    g.setIndex(Array.from(flat.indices));
    return g;
  }
}

/// The meshes of a loaded glTF scene as one flat mesh in the scene's frame: positions moved by
/// each node's transform (which also undoes KHR_mesh_quantization's scale), normals turned
/// with it, every attribute read back as floats.
export function flatten(gltfScene) {
  gltfScene.updateMatrixWorld(true);
  const parts = [];
  gltfScene.traverse((o) => {
    if (!o.isMesh) return;
    let g = o.geometry;
    if (!g.attributes.normal) {
      g = g.clone();
      g.computeVertexNormals();
    }
    parts.push({ g, matrix: o.matrixWorld });
  });
  let nVertices = 0;
  let nIndices = 0;
  for (const { g } of parts) {
    nVertices += g.attributes.position.count;
    nIndices += g.index ? g.index.count : g.attributes.position.count;
  }
  const positions = new Float32Array(nVertices * 3);
  const normals = new Float32Array(nVertices * 3);
  const indices = new Uint32Array(nIndices);
  const v = new THREE.Vector3();
  const normalMatrix = new THREE.Matrix3();
  let vertex = 0;
  let index = 0;
  for (const { g, matrix } of parts) {
    normalMatrix.getNormalMatrix(matrix);
    const p = g.attributes.position;
    const n = g.attributes.normal;
    for (let i = 0; i < p.count; i++) {
      v.fromBufferAttribute(p, i).applyMatrix4(matrix).toArray(positions, (vertex + i) * 3);
      v.fromBufferAttribute(n, i).applyMatrix3(normalMatrix).normalize().toArray(normals, (vertex + i) * 3);
    }
    if (g.index) for (let i = 0; i < g.index.count; i++) indices[index + i] = g.index.getX(i) + vertex;
    else for (let i = 0; i < p.count; i++) indices[index + i] = i + vertex;
    vertex += p.count;
    index += g.index ? g.index.count : p.count;
  }
  return { positions, normals, indices };
}
