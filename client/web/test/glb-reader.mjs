// The page's own GLB reader (src/glb.js) against the path it replaces: for every GLB, readGlb
// must give what three.js's GLTFLoader (with its MeshoptDecoder) and batch.js's flatten give:
// the same vertex count and indices, positions within 1e-4 relative (of the larger of the
// coordinate and 1), normals within 1e-3. Files:
// - penmesh's own, made here with $PENMESH_BIN (default target/debug/penmesh): `penmesh synth`
//   strokes and real recordings of ../shared/data through `penmesh mesh --glb meshopt|quantized|
//   plain` (readGlb must read these itself, never fall back);
// - every .glb of the folders or files given (`penmesh-lab eval --glb-out`, all real strokes);
// - GLBs made here of other layouts a tool may write: a node hierarchy with matrices and
//   rotations, normalised and integer positions, interleaved views, u8/u16/u32 indices,
//   unindexed triangles, missing normals, several primitives;
// - and ones readGlb must leave to GLTFLoader (sparse accessors, triangle strips, another
//   required extension, morph targets): readGlb answers null, GLTFLoader still reads them.
// Prints the largest differences and both paths' time; exits 1 on any failure.
//   node client/web/test/glb-reader.mjs [DIR_OR_GLB...]
import { execFileSync } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, readdirSync, rmSync, statSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";
import { flatten } from "../src/batch.js";
import { plan, readGlb, splitGlb } from "../src/glb.js";

const root = resolve(dirname(fileURLToPath(import.meta.url)), "../../..");
const BIN = process.env.PENMESH_BIN || join(root, "target/debug/penmesh");
const DATA = resolve(root, "../shared/data");
const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
const theirs = async (glb) => flatten((await loader.parseAsync(glb, "")).scene);
const arrayBuffer = (bytes) => bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);

let failed = 0;
let compared = 0;
const worst = { position: 0, normal: 0 };
const time = { mine: 0, theirs: 0 };
const fail = (name, why) => {
  console.error(`FAIL ${name}: ${why}`);
  failed += 1;
};

/// readGlb against GLTFLoader + flatten on one GLB; `own`: penmesh's, which readGlb must read.
async function check(name, glb, { own = false } = {}) {
  let t = performance.now();
  const mine = await readGlb(glb);
  time.mine += performance.now() - t;
  t = performance.now();
  const want = await theirs(glb);
  time.theirs += performance.now() - t;
  compared += 1;
  if (mine === null) {
    const split = splitGlb(glb);
    const why = split ? plan(split.json, split.bin).unsupported : "not a GLB";
    return fail(name, `readGlb left it to GLTFLoader (${why})`);
  }
  const nv = want.positions.length / 3;
  if (mine.positions.length !== want.positions.length || mine.normals.length !== want.normals.length) {
    return fail(name, `${mine.positions.length / 3} vertices, GLTFLoader ${nv}`);
  }
  if (mine.indices.length !== want.indices.length || mine.indices.some((v, i) => v !== want.indices[i])) {
    return fail(name, `indices differ (${mine.indices.length} against ${want.indices.length})`);
  }
  let dp = 0;
  let dn = 0;
  for (let i = 0; i < mine.positions.length; i++) {
    dp = Math.max(dp, Math.abs(mine.positions[i] - want.positions[i]) / Math.max(1, Math.abs(want.positions[i])));
    dn = Math.max(dn, Math.abs(mine.normals[i] - want.normals[i]));
  }
  if (!(dp <= 1e-4)) fail(name, `positions differ by ${dp} (relative)`);
  if (!(dn <= 1e-3)) fail(name, `normals differ by ${dn}`);
  worst.position = Math.max(worst.position, dp);
  worst.normal = Math.max(worst.normal, dn);
  if (own && nv === 0) fail(name, "no vertices (a test file that tests nothing)");
}

// --- penmesh's own GLBs -----------------------------------------------------------------
if (!existsSync(BIN)) {
  console.error(`FAIL: no penmesh binary at ${BIN}; build it (cargo build --bin penmesh) or set PENMESH_BIN`);
  process.exit(1);
}
const work = mkdtempSync(join(tmpdir(), "penmesh-glb-reader-"));
const inputs = [];
for (const shape of ["figure8", "scribble", "leaf"]) {
  const csv = join(work, `${shape}.csv`);
  execFileSync(BIN, ["synth", shape, "--out", csv], { stdio: "ignore" });
  inputs.push([shape, csv, []]);
}
const firstOf = (dir, pattern) => readdirSync(join(DATA, dir)).filter((f) => pattern.test(f)).sort()[0];
inputs.push(["svc2004", join(DATA, "svc2004", firstOf("svc2004", /\.txt$/i)), ["--px-per-unit", String(96 / 2540)]]);
inputs.push(["sigcomp2011", join(DATA, "sigcomp2011_dutch", firstOf("sigcomp2011_dutch", /\.hwr$/i)), ["--px-per-unit", String(96 / 5080)]]);
for (const [name, input, extra] of inputs) {
  for (const encoding of ["meshopt", "quantized", "plain"]) {
    const out = join(work, `${name}.${encoding}.glb`);
    execFileSync(BIN, ["mesh", input, "--out", out, "--glb", encoding, ...extra], { stdio: "ignore" });
    await check(`${name} (${encoding}, penmesh mesh)`, arrayBuffer(readFileSync(out)), { own: true });
  }
}
rmSync(work, { recursive: true, force: true });

const files = process.argv.slice(2).flatMap((path) =>
  statSync(path).isDirectory()
    ? readdirSync(path).filter((name) => name.endsWith(".glb")).sort().map((name) => join(path, name))
    : [path],
);
for (const file of files) await check(file, arrayBuffer(readFileSync(file)), { own: true });
const penmeshFiles = compared;

// --- other layouts, made here -------------------------------------------------------------
/// A glTF document with one buffer (the GLB's binary chunk) built view by view.
class Doc {
  constructor() {
    this.json = { asset: { version: "2.0" }, buffers: [{ byteLength: 0 }], bufferViews: [], accessors: [], meshes: [], nodes: [], scenes: [{ nodes: [] }], scene: 0 };
    this.bin = [];
    this.length = 0;
  }
  /// A view of `bytes`, starting `skew` bytes past a 4-byte boundary; its index.
  view(bytes, { stride, skew = 0 } = {}) {
    const pad = (4 - (this.length % 4)) % 4 + skew;
    this.bin.push(new Uint8Array(pad), new Uint8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength));
    const view = { buffer: 0, byteOffset: this.length + pad, byteLength: bytes.byteLength };
    if (stride) view.byteStride = stride;
    this.length += pad + bytes.byteLength;
    return this.json.bufferViews.push(view) - 1;
  }
  accessor(a) {
    return this.json.accessors.push(a) - 1;
  }
  glb() {
    this.json.buffers[0].byteLength = this.length;
    const json = new TextEncoder().encode(JSON.stringify(this.json));
    const jsonLength = Math.ceil(json.length / 4) * 4;
    const binLength = Math.ceil(this.length / 4) * 4;
    const out = new Uint8Array(12 + 8 + jsonLength + 8 + binLength);
    const view = new DataView(out.buffer);
    view.setUint32(0, 0x46546c67, true);
    view.setUint32(4, 2, true);
    view.setUint32(8, out.length, true);
    view.setUint32(12, jsonLength, true);
    view.setUint32(16, 0x4e4f534a, true);
    out.fill(0x20, 20, 20 + jsonLength);
    out.set(json, 20);
    view.setUint32(20 + jsonLength, binLength, true);
    view.setUint32(24 + jsonLength, 0x004e4942, true);
    let at = 28 + jsonLength;
    for (const chunk of this.bin) {
      out.set(chunk, at);
      at += chunk.length;
    }
    return out.buffer;
  }
}

/// The first `nTriangles` triangles of a flat mesh, its vertices renumbered from 0.
function subset({ positions, normals, indices }, nTriangles) {
  const map = new Map();
  const p = [];
  const n = [];
  const index = [];
  for (const v of indices.subarray(0, nTriangles * 3)) {
    if (!map.has(v)) {
      map.set(v, map.size);
      p.push(...positions.subarray(v * 3, v * 3 + 3));
      n.push(...normals.subarray(v * 3, v * 3 + 3));
    }
    index.push(map.get(v));
  }
  return { positions: new Float32Array(p), normals: new Float32Array(n), indices: new Uint32Array(index) };
}

const bounds = (positions) => {
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < positions.length; i++) {
    lo[i % 3] = Math.min(lo[i % 3], positions[i]);
    hi[i % 3] = Math.max(hi[i % 3], positions[i]);
  }
  return { lo, hi };
};

/// Vertices interleaved: each attribute `[values, Type, offset]` written at `offset` of every
/// `stride`-byte vertex.
function interleave(count, stride, attributes) {
  const bytes = new Uint8Array(count * stride);
  const view = new DataView(bytes.buffer);
  const set = {
    Float32Array: (at, v) => view.setFloat32(at, v, true),
    Int16Array: (at, v) => view.setInt16(at, v, true),
    Uint16Array: (at, v) => view.setUint16(at, v, true),
    Int8Array: (at, v) => view.setInt8(at, v),
    Uint8Array: (at, v) => view.setUint8(at, v),
  };
  for (const [values, Type, offset] of attributes) {
    for (let i = 0; i < count; i++) for (let c = 0; c < 3; c++) set[Type.name](i * stride + offset + c * Type.BYTES_PER_ELEMENT, values[i * 3 + c]);
  }
  return bytes;
}

const quaternion = (axis, angle) => {
  const l = Math.hypot(...axis);
  const s = Math.sin(angle / 2) / l;
  return [axis[0] * s, axis[1] * s, axis[2] * s, Math.cos(angle / 2)];
};

// The source geometry: the first real stroke's mesh, as GLTFLoader reads its plain GLB.
const sourceGlb = join(mkdtempSync(join(tmpdir(), "penmesh-glb-reader-")), "source.glb");
execFileSync(BIN, ["mesh", inputs[3][1], "--out", sourceGlb, "--glb", "plain", ...inputs[3][2]], { stdio: "ignore" });
const source = await theirs(arrayBuffer(readFileSync(sourceGlb)));
rmSync(dirname(sourceGlb), { recursive: true, force: true });
const small = subset(source, 80); // fewer than 256 vertices: u8 indices and positions
const F32 = 5126;

const layouts = {
  // Floats in separate views, u32 indices, a mesh used by two nodes: a rotated, scaled,
  // translated root whose child has a matrix (rotation, non-uniform scale, translation), and a
  // second root node with only a rotation.
  "node hierarchy, matrix and TRS": () => {
    const d = new Doc();
    const n = source.positions.length / 3;
    const { lo, hi } = bounds(source.positions);
    const position = d.accessor({ bufferView: d.view(source.positions), componentType: F32, count: n, type: "VEC3", min: lo, max: hi });
    const normal = d.accessor({ bufferView: d.view(source.normals), componentType: F32, count: n, type: "VEC3" });
    const indices = d.accessor({ bufferView: d.view(source.indices), componentType: 5125, count: source.indices.length, type: "SCALAR" });
    d.json.meshes.push({ primitives: [{ attributes: { POSITION: position, NORMAL: normal }, indices }] });
    const [c, s] = [Math.cos(0.3), Math.sin(0.3)];
    d.json.nodes.push(
      { translation: [10, -20, 5], rotation: quaternion([1, 2, 3], 0.7), scale: [2, 0.5, 1.5], children: [1] },
      { matrix: [c * 3, s * 3, 0, 0, -s, c, 0, 0, 0, 0, 0.25, 0, 7, 8, 9, 1], mesh: 0 },
      { rotation: quaternion([0, 0, 1], 2), mesh: 0, name: "second" },
    );
    d.json.scenes[0].nodes = [0, 2];
    return d.glb();
  },
  // KHR_mesh_quantization's normalised i16 positions (the node scales them back) and normals,
  // interleaved in one view of 16-byte vertices, u16 indices.
  "normalised i16, interleaved": () => {
    const d = new Doc();
    d.json.extensionsUsed = d.json.extensionsRequired = ["KHR_mesh_quantization"];
    const n = source.positions.length / 3;
    const { lo, hi } = bounds(source.positions);
    const centre = lo.map((l, k) => (l + hi[k]) / 2);
    const half = Math.max(...hi.map((h, k) => h - lo[k])) / 2;
    const q = source.positions.map((v, i) => Math.round(((v - centre[i % 3]) / half) * 32767));
    const nq = source.normals.map((v) => Math.round(v * 32767));
    const view = d.view(interleave(n, 16, [[q, Int16Array, 0], [nq, Int16Array, 8]]), { stride: 16 });
    const position = d.accessor({ bufferView: view, componentType: 5122, normalized: true, count: n, type: "VEC3", min: [-32767, -32767, -32767], max: [32767, 32767, 32767] });
    const normal = d.accessor({ bufferView: view, byteOffset: 8, componentType: 5122, normalized: true, count: n, type: "VEC3" });
    const indices = d.accessor({ bufferView: d.view(Uint16Array.from(source.indices)), componentType: 5123, count: source.indices.length, type: "SCALAR" });
    d.json.meshes.push({ primitives: [{ attributes: { POSITION: position, NORMAL: normal }, indices, mode: 4 }] });
    d.json.nodes.push({ translation: centre, scale: [half, half, half], mesh: 0 });
    d.json.scenes[0].nodes = [0];
    return d.glb();
  },
  // Unnormalised u8 positions and normalised i8 normals in views that start off 4-byte
  // boundaries, u8 indices, the accessors at an offset into their views.
  "u8 positions, i8 normals, u8 indices, skewed": () => {
    const d = new Doc();
    d.json.extensionsUsed = d.json.extensionsRequired = ["KHR_mesh_quantization"];
    const n = small.positions.length / 3;
    const { lo, hi } = bounds(small.positions);
    const step = Math.max(...hi.map((h, k) => h - lo[k])) / 255;
    const q = small.positions.map((v, i) => Math.round((v - lo[i % 3]) / step));
    const nq = small.normals.map((v) => Math.round(v * 127));
    const pv = d.view(new Uint8Array([9, 9, 9, ...q]), { skew: 1 });
    const nv = d.view(interleave(n, 4, [[nq, Int8Array, 0]]), { stride: 4, skew: 3 });
    const position = d.accessor({ bufferView: pv, byteOffset: 3, componentType: 5121, count: n, type: "VEC3", min: [0, 0, 0], max: [255, 255, 255] });
    const normal = d.accessor({ bufferView: nv, componentType: 5120, normalized: true, count: n, type: "VEC3" });
    const indices = d.accessor({ bufferView: d.view(new Uint8Array([7, ...small.indices]), { skew: 2 }), byteOffset: 1, componentType: 5121, count: small.indices.length, type: "SCALAR" });
    d.json.meshes.push({ primitives: [{ attributes: { POSITION: position, NORMAL: normal }, indices }] });
    d.json.nodes.push({ translation: lo, scale: [step, step, step], mesh: 0 });
    d.json.scenes[0].nodes = [0];
    return d.glb();
  },
  // No NORMAL: normals computed from the faces (indexed), in a rotated node.
  "indexed, no normals": () => {
    const d = new Doc();
    const n = source.positions.length / 3;
    const { lo, hi } = bounds(source.positions);
    const position = d.accessor({ bufferView: d.view(source.positions), componentType: F32, count: n, type: "VEC3", min: lo, max: hi });
    const indices = d.accessor({ bufferView: d.view(Uint16Array.from(source.indices)), componentType: 5123, count: source.indices.length, type: "SCALAR" });
    d.json.meshes.push({ primitives: [{ attributes: { POSITION: position }, indices }] });
    d.json.nodes.push({ rotation: quaternion([1, 1, 0], 1), mesh: 0 });
    d.json.scenes[0].nodes = [0];
    return d.glb();
  },
  // Unindexed triangles, without normals, u16 normalised positions: a normal per face.
  "unindexed, no normals, normalised u16": () => {
    const d = new Doc();
    d.json.extensionsUsed = d.json.extensionsRequired = ["KHR_mesh_quantization"];
    const corners = Array.from(small.indices, (v) => [...small.positions.subarray(v * 3, v * 3 + 3)]).flat();
    const { lo, hi } = bounds(corners);
    const size = Math.max(...hi.map((h, k) => h - lo[k]));
    const q = Uint16Array.from(corners, (v, i) => Math.round(((v - lo[i % 3]) / size) * 65535));
    const position = d.accessor({ bufferView: d.view(q), componentType: 5123, normalized: true, count: corners.length / 3, type: "VEC3", min: [0, 0, 0], max: [65535, 65535, 65535] });
    d.json.meshes.push({ primitives: [{ attributes: { POSITION: position } }] });
    d.json.nodes.push({ translation: lo, scale: [size, size, size], mesh: 0 });
    d.json.scenes[0].nodes = [0];
    return d.glb();
  },
  // One mesh of two primitives (the triangles split in two, each with its own vertices), a
  // third primitive of no triangles, and a node with no mesh between the roots.
  "several primitives": () => {
    const d = new Doc();
    const half = Math.floor(source.indices.length / 6);
    const parts = [subset(source, half), subset({ ...source, indices: source.indices.subarray(half * 3) }, source.indices.length / 3 - half)];
    const primitives = parts.map((part) => {
      const n = part.positions.length / 3;
      const { lo, hi } = bounds(part.positions);
      const position = d.accessor({ bufferView: d.view(part.positions), componentType: F32, count: n, type: "VEC3", min: lo, max: hi });
      const normal = d.accessor({ bufferView: d.view(part.normals), componentType: F32, count: n, type: "VEC3" });
      const indices = d.accessor({ bufferView: d.view(part.indices), componentType: 5125, count: part.indices.length, type: "SCALAR" });
      return { attributes: { POSITION: position, NORMAL: normal }, indices };
    });
    const empty = d.accessor({ componentType: F32, count: 0, type: "VEC3", min: [0, 0, 0], max: [0, 0, 0] });
    primitives.push({ attributes: { POSITION: empty } });
    d.json.meshes.push({ primitives });
    d.json.nodes.push({ name: "empty" }, { mesh: 0, translation: [1, 2, 3] });
    d.json.scenes[0].nodes = [0, 1];
    return d.glb();
  },
};
for (const [name, make] of Object.entries(layouts)) await check(`${name} (made here)`, make());

/// A layout from `layouts` changed so that readGlb must leave it to GLTFLoader.
const unhandled = {
  "a sparse accessor": ["node hierarchy, matrix and TRS", (json) => {
    const bv = json.bufferViews.push({ buffer: 0, byteOffset: 0, byteLength: 12 }) - 1;
    json.accessors[0].sparse = { count: 1, indices: { bufferView: bv, componentType: 5125 }, values: { bufferView: bv, byteOffset: 0 } };
  }],
  "a triangle strip": ["indexed, no normals", (json) => (json.meshes[0].primitives[0].mode = 5)],
  "another required extension": ["indexed, no normals", (json) => (json.extensionsUsed = json.extensionsRequired = ["KHR_texture_basisu"])],
  "morph targets": ["indexed, no normals", (json) => (json.meshes[0].primitives[0].targets = [{ POSITION: 0 }])],
};
for (const [name, [base, change]] of Object.entries(unhandled)) {
  const { json, bin } = splitGlb(layouts[base]());
  change(json);
  const d = new Doc();
  d.json = json;
  d.bin = [bin];
  d.length = bin.length;
  const glb = d.glb();
  compared += 1;
  if ((await readGlb(glb)) !== null) fail(name, "readGlb read it instead of leaving it to GLTFLoader");
  if (!plan(json, bin).unsupported) fail(name, "plan does not say why");
  if (name !== "another required extension") {
    try {
      await theirs(glb); // the fallback can read it
    } catch (err) {
      fail(name, `GLTFLoader cannot read it either: ${err.message}`);
    }
  }
}

console.log(
  `${compared - failed} passed, ${failed} failed (${penmeshFiles} of penmesh's GLBs, ${Object.keys(layouts).length} other layouts, ` +
    `${Object.keys(unhandled).length} left to GLTFLoader); largest differences: positions ${worst.position.toExponential(2)} relative, ` +
    `normals ${worst.normal.toExponential(2)}; readGlb ${time.mine.toFixed(0)} ms, GLTFLoader + flatten ${time.theirs.toFixed(0)} ms`,
);
process.exit(failed === 0 ? 0 : 1);
