// A stroke's GLB read straight into the flat arrays the page merges (batch.js): positions and
// normals in the scene's frame and indices, exactly what `flatten` makes of three.js's
// GLTFLoader scene, without the scene graph, materials and buffer attributes the loader builds
// per mesh (docs/performance-log.md, "A GLB reader of our own layout"). It reads what penmesh
// writes (shared/src/glb.rs: quantised attributes with KHR_mesh_quantization, buffer views
// compressed with EXT_meshopt_compression, or plain floats) and the like from other tools:
// any component type and normalised flag for POSITION, NORMAL and the indices, interleaved or
// not, node transforms (matrix or TRS) through the hierarchy of the default scene, normals
// computed when absent, several triangle primitives. Anything else (another required
// extension, sparse accessors, morph targets, skins, strips, lines, points, data URIs, ...)
// makes `readGlb` answer null, and the caller loads the file with GLTFLoader instead; `plan`
// alone decides.
import { Matrix3, Matrix4, Quaternion, Vector3 } from "three";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";

const GLB_MAGIC = 0x46546c67; // "glTF"
const CHUNK_JSON = 0x4e4f534a;
const CHUNK_BIN = 0x004e4942;
const MESHOPT = "EXT_meshopt_compression";
/// The required extensions this reader implements.
const HANDLED = new Set(["KHR_mesh_quantization", MESHOPT]);
const MESHOPT_MODES = new Set(["ATTRIBUTES", "TRIANGLES", "INDICES"]);
const MESHOPT_FILTERS = new Set([undefined, "NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL"]);
const TRIANGLES = 4;
const UTF8 = new TextDecoder();

const COMPONENT_TYPES = {
  5120: Int8Array,
  5121: Uint8Array,
  5122: Int16Array,
  5123: Uint16Array,
  5125: Uint32Array,
  5126: Float32Array,
};
/// What a normalised component is divided by, as three.js's `denormalize` does (signed ones
/// are then clamped at -1); floats are read as they are.
const NORMALISED = { 5120: 127, 5121: 255, 5122: 32767, 5123: 65535, 5125: 4294967295 };
const SIGNED = new Set([5120, 5122]);

class Unsupported extends Error {}

function need(condition, why) {
  if (!condition) throw new Unsupported(why);
}

const isIndex = (i, list) => Number.isInteger(i) && i >= 0 && Array.isArray(list) && i < list.length;
const isNumbers = (a, n) => Array.isArray(a) && a.length === n && a.every((v) => typeof v === "number" && Number.isFinite(v));

/// The GLB's JSON document and binary chunk (a Uint8Array, or null), or null when the bytes are
/// not a GLB of version 2 with a JSON chunk first.
export function splitGlb(glb) {
  const bytes = ArrayBuffer.isView(glb) ? new Uint8Array(glb.buffer, glb.byteOffset, glb.byteLength) : new Uint8Array(glb);
  if (bytes.byteLength < 20) return null;
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (view.getUint32(0, true) !== GLB_MAGIC || view.getUint32(4, true) !== 2) return null;
  const length = Math.min(view.getUint32(8, true), bytes.byteLength);
  let json = null;
  let bin = null;
  for (let at = 12; at + 8 <= length; ) {
    const chunkLength = view.getUint32(at, true);
    const type = view.getUint32(at + 4, true);
    const start = at + 8;
    if (start + chunkLength > length) return null;
    if (json === null) {
      if (type !== CHUNK_JSON) return null;
      try {
        json = JSON.parse(UTF8.decode(bytes.subarray(start, start + chunkLength)));
      } catch {
        return null;
      }
    } else if (type === CHUNK_BIN) {
      bin = bytes.subarray(start, start + chunkLength); // the last, as GLTFLoader takes it
    }
    at = start + chunkLength;
  }
  return json && typeof json === "object" ? { json, bin } : null;
}

/// A node's own matrix as three.js makes it: TRS composed; a `matrix` decomposed into TRS and
/// composed again (GLTFLoader's `applyMatrix4`), which is the same matrix unless it shears.
function localMatrix(node) {
  const m = new Matrix4();
  const position = new Vector3();
  const quaternion = new Quaternion();
  const scale = new Vector3(1, 1, 1);
  if (node.matrix !== undefined) {
    need(isNumbers(node.matrix, 16), "a node's matrix is not 16 numbers");
    new Matrix4().fromArray(node.matrix).decompose(position, quaternion, scale);
  } else {
    if (node.translation !== undefined) {
      need(isNumbers(node.translation, 3), "a node's translation is not 3 numbers");
      position.fromArray(node.translation);
    }
    if (node.rotation !== undefined) {
      need(isNumbers(node.rotation, 4), "a node's rotation is not 4 numbers");
      quaternion.fromArray(node.rotation);
    }
    if (node.scale !== undefined) {
      need(isNumbers(node.scale, 3), "a node's scale is not 3 numbers");
      scale.fromArray(node.scale);
    }
  }
  return m.compose(position, quaternion, scale);
}

/// What an accessor reads: `count` elements of `size` components of `type`, `stride` bytes
/// apart from `offset` in buffer view `view` (undefined: zeros), checked against the view.
function accessorPlan(json, bin, index, sizes, what) {
  need(isIndex(index, json.accessors), `${what} has no accessor`);
  const a = json.accessors[index];
  need(a.sparse === undefined, "a sparse accessor");
  need(a.extensions === undefined, "an accessor extension");
  const Type = COMPONENT_TYPES[a.componentType];
  need(Type !== undefined, `${what}: component type ${a.componentType}`);
  const size = { SCALAR: 1, VEC3: 3 }[a.type];
  need(sizes.includes(size), `${what}: accessor type ${a.type}`);
  need(Number.isInteger(a.count) && a.count >= 0, `${what}: count ${a.count}`);
  const item = Type.BYTES_PER_ELEMENT * size;
  const plan = {
    Type,
    size,
    count: a.count,
    normalised: a.normalized === true && a.componentType !== 5126 ? NORMALISED[a.componentType] : 0,
    signed: SIGNED.has(a.componentType),
    view: a.bufferView,
    offset: a.byteOffset ?? 0,
    stride: item,
  };
  if (a.bufferView === undefined) return plan;
  need(isIndex(a.bufferView, json.bufferViews), `${what}: no buffer view ${a.bufferView}`);
  const v = json.bufferViews[a.bufferView];
  const length = viewPlan(json, bin, v).length;
  plan.stride = v.byteStride ?? item;
  need(Number.isInteger(plan.offset) && plan.offset >= 0 && plan.offset % Type.BYTES_PER_ELEMENT === 0, `${what}: byte offset ${plan.offset}`);
  need(Number.isInteger(plan.stride) && plan.stride >= item && plan.stride % Type.BYTES_PER_ELEMENT === 0, `${what}: byte stride ${plan.stride}`);
  need(a.count === 0 || plan.offset + (a.count - 1) * plan.stride + item <= length, `${what}: past the end of its buffer view`);
  return plan;
}

/// A buffer view's bytes: in the binary chunk, or compressed there with EXT_meshopt_compression
/// (decoded to `count * byteStride` bytes, which then are the view, as GLTFLoader takes them).
function viewPlan(json, bin, v) {
  const chunk = (buffer, offset, length) => {
    need(buffer === 0 && isIndex(0, json.buffers) && json.buffers[0].uri === undefined && bin !== null, "a buffer outside the GLB's binary chunk");
    need(Number.isInteger(offset) && offset >= 0 && Number.isInteger(length) && length >= 0 && offset + length <= bin.byteLength, "a buffer view past the end of the binary chunk");
  };
  const extensions = Object.keys(v.extensions ?? {});
  need(extensions.every((e) => e === MESHOPT), `a buffer view extension (${extensions})`);
  const m = v.extensions?.[MESHOPT];
  if (m) {
    need(MeshoptDecoder.supported, "no WebAssembly for MeshoptDecoder");
    need(MESHOPT_MODES.has(m.mode) && MESHOPT_FILTERS.has(m.filter), `meshopt mode ${m.mode}, filter ${m.filter}`);
    need(Number.isInteger(m.count) && m.count >= 0 && Number.isInteger(m.byteStride) && m.byteStride > 0, "meshopt count or stride");
    chunk(m.buffer, m.byteOffset ?? 0, m.byteLength ?? 0);
    return { length: m.count * m.byteStride, meshopt: m };
  }
  chunk(v.buffer, v.byteOffset ?? 0, v.byteLength);
  return { length: v.byteLength, start: v.byteOffset ?? 0 };
}

/// What `readGlb` will read: every triangle primitive of the default scene with its node's
/// world matrix, in the order three.js's `traverse` meets them (a node's primitives, then its
/// children); `{unsupported: why}` when the document holds something this reader does not
/// handle (the caller then uses GLTFLoader). The one place that decides.
export function plan(json, bin) {
  try {
    for (const e of json.extensionsRequired ?? []) need(HANDLED.has(e), `required extension ${e}`);
    const sceneIndex = json.scene || 0;
    need(isIndex(sceneIndex, json.scenes), "no default scene");
    const parts = [];
    const seen = new Set();
    const visit = (index, parentMatrix) => {
      need(isIndex(index, json.nodes) && !seen.has(index), `node ${index} missing or used twice`);
      seen.add(index);
      const node = json.nodes[index];
      need(node.skin === undefined && node.weights === undefined, "a skin or morph weights");
      const matrix = parentMatrix ? new Matrix4().multiplyMatrices(parentMatrix, localMatrix(node)) : localMatrix(node);
      if (node.mesh !== undefined) {
        need(isIndex(node.mesh, json.meshes), `node ${index}: no mesh ${node.mesh}`);
        const mesh = json.meshes[node.mesh];
        need(mesh.extensions === undefined && mesh.weights === undefined && Array.isArray(mesh.primitives), "a mesh extension or morph weights");
        for (const p of mesh.primitives) {
          need((p.mode ?? TRIANGLES) === TRIANGLES, `primitive mode ${p.mode}`);
          need(p.extensions === undefined && p.targets === undefined, "a primitive extension or morph targets");
          const attributes = p.attributes ?? {};
          const position = accessorPlan(json, bin, attributes.POSITION, [3], "POSITION");
          const normal = attributes.NORMAL === undefined ? null : accessorPlan(json, bin, attributes.NORMAL, [3], "NORMAL");
          need(!normal || normal.count === position.count, "NORMAL and POSITION counts differ");
          const indices = p.indices === undefined ? null : accessorPlan(json, bin, p.indices, [1], "indices");
          need(!indices || ([Uint8Array, Uint16Array, Uint32Array].includes(indices.Type) && !indices.normalised), "indices of a signed, float or normalised type");
          need((indices ? indices.count : position.count) % 3 === 0, "not whole triangles");
          parts.push({ matrix, position, normal, indices });
        }
      }
      for (const child of node.children ?? []) visit(child, matrix);
    };
    for (const index of json.scenes[sceneIndex].nodes ?? []) visit(index, null);
    return { parts };
  } catch (err) {
    if (err instanceof Unsupported) return { unsupported: err.message };
    throw err;
  }
}

/// The elements of an accessor as a typed array over its view's bytes (`views` caches them,
/// decoded), from its first element; `step` components from one element to the next.
function elements(json, bin, views, a) {
  if (a.view === undefined) return { array: new a.Type(a.count * a.size), step: a.size };
  let bytes = views.get(a.view);
  if (!bytes) {
    const v = json.bufferViews[a.view];
    const p = viewPlan(json, bin, v);
    if (p.meshopt) {
      const m = p.meshopt;
      const offset = m.byteOffset ?? 0;
      bytes = new Uint8Array(m.count * m.byteStride);
      MeshoptDecoder.decodeGltfBuffer(bytes, m.count, m.byteStride, bin.subarray(offset, offset + (m.byteLength ?? 0)), m.mode, m.filter);
    } else {
      bytes = bin.subarray(p.start, p.start + p.length);
    }
    views.set(a.view, bytes);
  }
  const width = a.Type.BYTES_PER_ELEMENT;
  const n = a.count === 0 ? 0 : ((a.count - 1) * a.stride) / width + a.size;
  const at = bytes.byteOffset + a.offset;
  const array = at % width === 0 ? new a.Type(bytes.buffer, at, n) : new a.Type(bytes.slice(a.offset, a.offset + n * width).buffer);
  return { array, step: a.stride / width };
}

/// Component `c` of element `i`, denormalised as three.js's BufferAttribute.getX does.
function reader(a, e) {
  const { array, step } = e;
  if (!a.normalised) return (i, c) => array[i * step + c];
  const d = a.normalised;
  return a.signed ? (i, c) => Math.max(array[i * step + c] / d, -1) : (i, c) => array[i * step + c] / d;
}

/// Vertex normals of an unnormalised mesh, as three.js's `computeVertexNormals`: the sum of the
/// faces' cross products at each vertex (each face's own for unindexed triangles), normalised.
function computeNormals(count, get, index) {
  const n = new Float32Array(count * 3);
  const p = (v, out) => {
    out[0] = get(v, 0);
    out[1] = get(v, 1);
    out[2] = get(v, 2);
  };
  const a = [0, 0, 0];
  const b = [0, 0, 0];
  const c = [0, 0, 0];
  const triangles = index ? index.length : count;
  for (let t = 0; t < triangles; t += 3) {
    const [va, vb, vc] = index ? [index[t], index[t + 1], index[t + 2]] : [t, t + 1, t + 2];
    p(va, a);
    p(vb, b);
    p(vc, c);
    const [cbx, cby, cbz] = [c[0] - b[0], c[1] - b[1], c[2] - b[2]];
    const [abx, aby, abz] = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    const x = cby * abz - cbz * aby;
    const y = cbz * abx - cbx * abz;
    const z = cbx * aby - cby * abx;
    for (const v of [va, vb, vc]) {
      if (index) {
        n[v * 3] += x;
        n[v * 3 + 1] += y;
        n[v * 3 + 2] += z;
      } else {
        n[v * 3] = x;
        n[v * 3 + 1] = y;
        n[v * 3 + 2] = z;
      }
    }
  }
  for (let v = 0; v < count; v++) {
    const [x, y, z] = [n[v * 3], n[v * 3 + 1], n[v * 3 + 2]];
    const s = 1 / (Math.sqrt(x * x + y * y + z * z) || 1);
    n[v * 3] = x * s;
    n[v * 3 + 1] = y * s;
    n[v * 3 + 2] = z * s;
  }
  return (i, k) => n[i * 3 + k];
}

/// The meshes of a GLB as `{positions, normals, indices}` (Float32Array, Float32Array,
/// Uint32Array) in the scene's frame, what `flatten` gives for GLTFLoader's scene of it; null
/// when `plan` says this reader does not handle the file.
export async function readGlb(glb) {
  const split = splitGlb(glb);
  if (!split) return null;
  const { json, bin } = split;
  const { parts, unsupported } = plan(json, bin);
  if (unsupported) return null;
  if (parts.some((p) => [p.position, p.normal, p.indices].some((a) => a && a.view !== undefined && json.bufferViews[a.view].extensions?.[MESHOPT]))) {
    await MeshoptDecoder.ready;
  }
  let nVertices = 0;
  let nIndices = 0;
  for (const p of parts) {
    nVertices += p.position.count;
    nIndices += p.indices ? p.indices.count : p.position.count;
  }
  const positions = new Float32Array(nVertices * 3);
  const normals = new Float32Array(nVertices * 3);
  const indices = new Uint32Array(nIndices);
  const views = new Map();
  const normalMatrix = new Matrix3();
  let vertex = 0;
  let at = 0;
  for (const part of parts) {
    const count = part.position.count;
    const position = reader(part.position, elements(json, bin, views, part.position));
    let index = null;
    if (part.indices) {
      const e = elements(json, bin, views, part.indices);
      index = e.step === 1 ? e.array.subarray(0, part.indices.count) : Array.from({ length: part.indices.count }, (_, i) => e.array[i * e.step]);
    }
    const normal = part.normal ? reader(part.normal, elements(json, bin, views, part.normal)) : computeNormals(count, position, index);
    // Vector3.applyMatrix4 and applyMatrix3(normalMatrix).normalize(), as flatten does.
    const e = part.matrix.elements;
    const m = normalMatrix.getNormalMatrix(part.matrix).elements;
    for (let i = 0; i < count; i++) {
      const x = position(i, 0);
      const y = position(i, 1);
      const z = position(i, 2);
      const w = 1 / (e[3] * x + e[7] * y + e[11] * z + e[15]);
      const o = (vertex + i) * 3;
      positions[o] = (e[0] * x + e[4] * y + e[8] * z + e[12]) * w;
      positions[o + 1] = (e[1] * x + e[5] * y + e[9] * z + e[13]) * w;
      positions[o + 2] = (e[2] * x + e[6] * y + e[10] * z + e[14]) * w;
      const nx = normal(i, 0);
      const ny = normal(i, 1);
      const nz = normal(i, 2);
      const tx = m[0] * nx + m[3] * ny + m[6] * nz;
      const ty = m[1] * nx + m[4] * ny + m[7] * nz;
      const tz = m[2] * nx + m[5] * ny + m[8] * nz;
      const s = 1 / (Math.sqrt(tx * tx + ty * ty + tz * tz) || 1);
      normals[o] = tx * s;
      normals[o + 1] = ty * s;
      normals[o + 2] = tz * s;
    }
    if (index) for (let i = 0; i < index.length; i++) indices[at + i] = index[i] + vertex;
    else for (let i = 0; i < count; i++) indices[at + i] = i + vertex;
    vertex += count;
    at += index ? index.length : count;
  }
  return { positions, normals, indices };
}
