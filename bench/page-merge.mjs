// The page's work to merge a board's meshes (docs/performance-log.md, "What bounds an orbit frame"
// and the three planes): the CPU time of putting every mesh of a saved bundle into the merged
// geometries, in Node (no WebGL: only the page's JavaScript, the part that runs before the GPU
// upload), for this checkout's client/web/src/batch.js (groups per person and placement) and an
// older one that baked each placement into a copy per person. CPU time (process.cpuUsage), so
// a busy machine disturbs it little; the arms in turn, ROUNDS times.
//
// Usage (after `node bench/busy-board.mjs --planes 3 --save-bundle BUNDLE.bin`):
//   git show 80055f8:client/web/src/batch.js > client/web/src/batch-old.js
//   node bench/page-merge.mjs BUNDLE.bin client/web/src/batch-old.js [--rounds 5]
//   rm client/web/src/batch-old.js
// Each round also gives each placed stroke its placement once more, as the history's
// `peer_placement` does after the bundle.
import { readFileSync } from "node:fs";
import { resolve } from "node:path";
import * as THREE from "../client/web/node_modules/three/build/three.module.js"; // the same module as the page's "three"
import { decodeMeshBundle } from "../client/web/src/api.js";
import { readGlb } from "../client/web/src/glb.js";
import { StrokeGroups } from "../client/web/src/batch.js";

const [bundleFile, oldBatch] = process.argv.slice(2);
if (!bundleFile || !oldBatch) throw new Error("usage: node bench/page-merge.mjs BUNDLE.bin OLD_BATCH.js [--rounds N]");
const i = process.argv.indexOf("--rounds");
const ROUNDS = i < 0 ? 5 : Number(process.argv[i + 1]);
const { MergedMeshes } = await import(resolve(oldBatch));

const body = readFileSync(bundleFile);
const meshes = decodeMeshBundle(body.buffer.slice(body.byteOffset, body.byteOffset + body.length));
const flats = await Promise.all(meshes.map((m) => readGlb(m.glb)));
if (flats.some((f) => !f)) throw new Error("a GLB the page's reader leaves to GLTFLoader: not measured here");
const placed = meshes.filter((m) => m.placement && m.placement.some((v, k) => v !== (k % 5 === 0 ? 1 : 0))).length;
const colour = new THREE.Color(0x336699);
const material = new THREE.MeshBasicMaterial();

const arms = {
  // One merged copy per person, each placed stroke baked into it (and again when its placement
  // comes once more).
  baked() {
    const people = new Map();
    const ranges = meshes.map((m, k) => {
      if (!people.has(m.participant)) people.set(m.participant, new MergedMeshes(material));
      return people.get(m.participant).add(flats[k], colour, m.placement);
    });
    meshes.forEach((m, k) => people.get(m.participant).setPlacement(ranges[k], m.placement));
    return people.size;
  },
  // One group per person and placement, its object at the placement.
  grouped() {
    const groups = new StrokeGroups(material, new THREE.Group());
    const ranges = meshes.map((m, k) => groups.add(flats[k], m.participant, colour, m.placement));
    meshes.forEach((m, k) => groups.place(ranges[k], m.participant, colour, m.placement));
    return groups.groups.size;
  },
};

const cpuMs = () => {
  const u = process.cpuUsage();
  return (u.user + u.system) / 1000;
};
const out = { meshes: meshes.length, placed, vertices: flats.reduce((a, f) => a + f.positions.length / 3, 0), rounds: {} };
for (const name of Object.keys(arms)) out.rounds[name] = [];
arms.baked(); // warm both
arms.grouped();
for (let r = 0; r < ROUNDS; r++) {
  for (const [name, run] of r % 2 ? Object.entries(arms).reverse() : Object.entries(arms)) {
    const t = cpuMs();
    out.draw_calls ??= {};
    out.draw_calls[name] = run();
    out.rounds[name].push(Number((cpuMs() - t).toFixed(1)));
  }
}
const median = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];
out.median_ms = Object.fromEntries(Object.entries(out.rounds).map(([k, v]) => [k, median(v)]));
console.log(JSON.stringify(out));
