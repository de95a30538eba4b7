// One person's finished meshes merged into one geometry, so they cost one draw call however
// many there are (docs/web.md). A new mesh is appended and only its part is uploaded; the
// buffers double when full. Each stroke keeps its range, for the GLB export, its colour (a
// vertex colour: a person may draw in several) and being hidden (a stroke taken back: its
// triangles collapse to one point, and come back when it is brought back).
//
// A stroke's mesh is in its own plane's coordinates and never changes (range.flat keeps it);
// its placement (placement.js) is baked into the merged copy, a render cache rewritten when the
// placement changes. A mirroring placement flips the copy's winding, so the solid stays closed
// and lit outward. A selected stroke is lifted out (select.js): hidden here, drawn as its own
// object with the placement as its matrix, baked back when it is let go.
import * as THREE from "three";
import { matrixOf, mirrors } from "./placement.js";

const FIRST_VERTICES = 4096;

export class MergedMeshes {
  constructor(material) {
    this.material = material;
    this.vertexCount = 0;
    this.indexCount = 0;
    this.positions = new Float32Array(0);
    this.normals = new Float32Array(0);
    this.colours = new Uint8Array(0);
    this.indices = new Uint32Array(0);
    this.mesh = new THREE.Mesh(new THREE.BufferGeometry(), material);
    // The drawing is one connected board; culling per person would save nothing.
    this.mesh.frustumCulled = false;
  }

  /// Appends a mesh given as flat `positions`, `normals` (Float32Array, 3 per vertex) and
  /// `indices` (into its own vertices), in `colour` (a THREE.Color), at `placement` (16
  /// numbers; null: as it is); returns its range.
  add(flat, colour, placement = null) {
    const nVertices = flat.positions.length / 3;
    this.reserve(this.vertexCount + nVertices, this.indexCount + flat.indices.length);
    const range = { firstVertex: this.vertexCount, vertexCount: nVertices, firstIndex: this.indexCount, indexCount: flat.indices.length, hidden: false, lifted: false, flip: false, flat };
    this.vertexCount += nVertices;
    this.indexCount += flat.indices.length;
    range.local = flat.indices;
    this.setPlacement(range, placement);
    this.setColour(range, colour);
    this.mesh.geometry.setDrawRange(0, this.indexCount);
    return range;
  }

  /// Bakes `placement` into one stroke's copy: its vertices moved, its normals turned, its
  /// winding flipped where the placement mirrors.
  setPlacement(range, placement) {
    const { positions, normals } = range.flat;
    const at = range.firstVertex * 3;
    if (!placement) {
      this.positions.set(positions, at);
      this.normals.set(normals, at);
    } else {
      const m = matrixOf(placement);
      const n = new THREE.Matrix3().getNormalMatrix(m);
      const v = new THREE.Vector3();
      for (let i = 0; i < range.vertexCount; i++) {
        v.fromArray(positions, i * 3).applyMatrix4(m).toArray(this.positions, at + i * 3);
        v.fromArray(normals, i * 3).applyMatrix3(n).normalize().toArray(this.normals, at + i * 3);
      }
    }
    const g = this.mesh.geometry;
    for (const attribute of [g.attributes.position, g.attributes.normal]) {
      attribute.addUpdateRange(at, range.vertexCount * 3);
      attribute.needsUpdate = true;
    }
    range.flip = mirrors(placement);
    this.writeIndices(range);
  }

  /// Lifts one stroke's mesh out of the merged one (drawn on its own while selected), or
  /// puts it back.
  setLifted(range, lifted) {
    if (range.lifted === lifted) return;
    range.lifted = lifted;
    this.writeIndices(range);
  }

  /// Writes a range's indices: its own triangles (each turned the other way round when its
  /// placement mirrors), or, hidden or lifted out, every index at its first vertex (triangles
  /// of no area, which draw nothing).
  writeIndices(range) {
    const { firstVertex, firstIndex, local } = range;
    const gone = range.hidden || range.lifted;
    for (let i = 0; i < local.length; i++) {
      // In a flipped range the second and third index of each triangle swap places.
      const from = range.flip && i % 3 !== 0 ? i + (i % 3 === 1 ? 1 : -1) : i;
      this.indices[firstIndex + i] = gone ? firstVertex : local[from] + firstVertex;
    }
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
