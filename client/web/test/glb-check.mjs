// Every .glb in the given folders (or files) is valid for the Khronos glTF-Validator (no error)
// and loads in three.js's GLTFLoader with its MeshoptDecoder, as the page loads meshes, with the
// vertex and triangle counts its accessors declare. The validator (2.0.0-dev.3.10) does not
// know EXT_meshopt_compression, so it checks such a file's document but not its compressed
// data; so a compressed file that has its uncompressed twin beside it (NAME.meshopt.glb and
// NAME.quantised.glb, as `penmesh-lab eval --glb-out` writes them) must load in three.js as the very
// same triangles, and the twin is validated in full. Prints the validator's warnings and infos
// by code; exits 1 on any failure. The real strokes of ../shared/data, every encoding:
//   cargo run --bin penmesh-lab -- eval ../shared/data --glb-sizes --glb-out /tmp/penmesh-glbs
//   node client/web/test/glb-check.mjs /tmp/penmesh-glbs
import { existsSync, readFileSync, readdirSync, statSync } from "node:fs";
import { join } from "node:path";
import validator from "gltf-validator";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";

const files = process.argv.slice(2).flatMap((path) =>
  statSync(path).isDirectory()
    ? readdirSync(path).filter((name) => name.endsWith(".glb")).sort().map((name) => join(path, name))
    : [path],
);
if (files.length === 0) {
  console.error("usage: node client/web/test/glb-check.mjs DIR_OR_GLB...");
  process.exit(2);
}

const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
const load = (file) => {
  const bytes = readFileSync(file);
  return loader.parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length), "");
};

// Each mesh's triangles as three.js will draw them: world positions and normals of the three
// corners, each triangle turned to start at its smallest corner, sorted.
function triangles(gltf) {
  const out = [];
  gltf.scene.updateMatrixWorld(true);
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    const { position, normal } = o.geometry.attributes;
    const corner = (i) => {
      const [x, y, z] = [position.getX(i), position.getY(i), position.getZ(i)];
      const e = o.matrixWorld.elements;
      const world = [0, 1, 2].map((r) => e[r] * x + e[4 + r] * y + e[8 + r] * z + e[12 + r]);
      return [...world, normal.getX(i), normal.getY(i), normal.getZ(i)].map((v) => v.toFixed(5)).join(",");
    };
    const index = o.geometry.index.array;
    for (let t = 0; t < index.length; t += 3) {
      const c = [corner(index[t]), corner(index[t + 1]), corner(index[t + 2])];
      const first = c.indexOf([...c].sort()[0]);
      out.push([c[first], c[(first + 1) % 3], c[(first + 2) % 3]].join(" "));
    }
  });
  return out.sort();
}

const notes = new Map(); // validator code -> [severity, count, one example]
let failed = 0;
for (const file of files) {
  const problems = [];
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), { maxIssues: 100, format: "glb" });
  for (const m of report.issues.messages) {
    if (m.severity === 0) problems.push(`validator: ${m.code} at ${m.pointer}: ${m.message}`);
    const note = notes.get(m.code) ?? [m.severity, 0, `${m.pointer}: ${m.message}`];
    note[1] += 1;
    notes.set(m.code, note);
  }
  try {
    const gltf = await load(file);
    const json = gltf.parser.json;
    // Each glTF mesh made once at least (a scene export's duplicates use their source's twice).
    const meshes = new Set();
    gltf.scene.traverse((o) => {
      if (!o.isMesh) return;
      meshes.add(gltf.parser.associations.get(o).meshes);
      const primitive = json.meshes[gltf.parser.associations.get(o).meshes].primitives[0];
      const want = [json.accessors[primitive.attributes.POSITION].count, json.accessors[primitive.indices].count];
      const got = [o.geometry.attributes.position.count, o.geometry.index.count];
      if (got.join() !== want.join()) problems.push(`three.js read ${got} vertices/indices, the file declares ${want}`);
    });
    if (meshes.size !== (json.meshes ?? []).length) problems.push(`three.js made ${meshes.size} of ${json.meshes.length} meshes`);
    const twin = file.replace(/\.meshopt\.glb$/, ".quantised.glb");
    if (twin !== file && existsSync(twin)) {
      const [mine, theirs] = [triangles(gltf), triangles(await load(twin))];
      if (mine.length !== theirs.length || mine.some((t, k) => t !== theirs[k])) {
        problems.push(`three.js draws other triangles than from ${twin}`);
      }
    }
  } catch (err) {
    problems.push(`three.js GLTFLoader: ${err.message}`);
  }
  for (const problem of problems) console.error(`FAIL ${file}: ${problem}`);
  failed += problems.length > 0 ? 1 : 0;
}
const severity = ["error", "warning", "info", "hint"];
for (const [code, [level, count, example]] of notes) {
  console.log(`validator ${severity[level]} ${code}: ${count} files (e.g. ${example})`);
}
console.log(`${files.length - failed} passed, ${failed} failed`);
process.exit(failed === 0 ? 0 : 1);
