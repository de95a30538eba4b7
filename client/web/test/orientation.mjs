// The model's orientation in every format (issue 50, docs/print.md "Orientation"): an "F" drawn
// with the pen on the board as the page shows it from above, and a stroke drawn up the Front
// plane; then the session exported as GLB, STL and 3MF through the proxy's API, and
// 1. the STL and the 3MF read as the page: the F's top arm (at the top of the page) at the back
//    of the bed (+Y), its stem at the left (-X), the standing stroke rising (+Z), the solid
//    wound outward (positive volume);
// 2. the GLB (glTF's Y up, read by three.js) the same way: the top arm at the back (-Z), the
//    standing stroke rising (+Y);
// 3. the print is the GLB turned to the bed's axes (X, -Z, Y) and scaled: every corner of the
//    print's box within 3 mm of the GLB's so turned, and PrusaSlicer finds it manifold.
// Run by scripts/test.sh as `node client/web/test/orientation.mjs`.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { writeFileSync } from "node:fs";
import { join } from "node:path";
import { inflateRawSync } from "node:zlib";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";
import { ARTIFACTS, browserTest, log, newSession, openPage, polyline, sessionUrl, until } from "./harness.mjs";

async function exported(base, s, format) {
  const res = await fetch(`${base}/v1/sessions/${s.session}/export?format=${format}`, { headers: { authorization: `Bearer ${s.token}` } });
  assert.equal(res.status, 200, `export ${format}: ${await res.clone().text()}`);
  return Buffer.from(await res.arrayBuffer());
}

/// The vertices of a binary STL.
function stlPoints(bytes) {
  const n = bytes.readUInt32LE(80);
  const points = [];
  for (let t = 0; t < n; t++) for (let v = 0; v < 3; v++) {
    const at = 84 + 50 * t + 12 + 12 * v;
    points.push([bytes.readFloatLE(at), bytes.readFloatLE(at + 4), bytes.readFloatLE(at + 8)]);
  }
  return points;
}

/// One file of a zip archive (a 3MF), found by its local header; stored or deflated.
function unzipped(zip, name) {
  for (let at = 0; at + 30 <= zip.length && zip.readUInt32LE(at) === 0x04034b50;) {
    const [method, size, nameLength, extraLength] = [zip.readUInt16LE(at + 8), zip.readUInt32LE(at + 18), zip.readUInt16LE(at + 26), zip.readUInt16LE(at + 28)];
    const start = at + 30 + nameLength + extraLength;
    if (zip.toString("utf8", at + 30, at + 30 + nameLength) === name) {
      const data = zip.subarray(start, start + size);
      return (method === 8 ? inflateRawSync(data) : data).toString("utf8");
    }
    at = start + size;
  }
  throw new Error(`no ${name} in the archive`);
}

/// The vertices of a 3MF's model.
function threeMfPoints(zip) {
  const xml = unzipped(zip, "3D/3dmodel.model");
  return [...xml.matchAll(/<vertex x="([^"]+)" y="([^"]+)" z="([^"]+)"\/>/g)].map((m) => [Number(m[1]), Number(m[2]), Number(m[3])]);
}

function bounds(points) {
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  for (const p of points) for (let a = 0; a < 3; a++) [lo[a], hi[a]] = [Math.min(lo[a], p[a]), Math.max(hi[a], p[a])];
  return { lo, hi };
}

/// The X range of the points whose Y lies in [y0, y1].
function xRange(points, y0, y1) {
  const { lo, hi } = bounds(points.filter((p) => p[1] >= y0 && p[1] <= y1));
  return [lo[0], hi[0]];
}

/// Checks points in the bed's axes (X right, Y back, Z up) read as the page: only the standing
/// stroke rises (the points above half the height), and on the board left of it (the points
/// below 5 % of the height) the F has its top arm at the back and its stem at the left.
function assertReadsAsThePage(points, what) {
  const { lo, hi } = bounds(points);
  const height = hi[2] - lo[2];
  assert.ok(height > 0.3 * (hi[0] - lo[0]), `${what}: the standing stroke rises ${height} (Z) on a model ${hi[0] - lo[0]} wide`);
  const standing = bounds(points.filter((p) => p[2] > lo[2] + 0.5 * height));
  const fPoints = points.filter((p) => p[2] < lo[2] + 0.05 * height && p[0] < standing.lo[0] - 0.1 * (hi[0] - lo[0]));
  const f = bounds(fPoints);
  const [width, depth] = [f.hi[0] - f.lo[0], f.hi[1] - f.lo[1]];
  assert.ok(depth > width, `${what}: the F is taller (${depth}) than wide (${width}) on the bed`);
  const back = xRange(fPoints, f.hi[1] - 0.1 * depth, f.hi[1]);
  const front = xRange(fPoints, f.lo[1], f.lo[1] + 0.1 * depth);
  assert.ok(back[1] - back[0] > 0.6 * width, `${what}: the F's top arm lies at the back (+Y): x ${back} of width ${width}`);
  assert.ok(front[1] - front[0] < 0.3 * width && front[1] < f.lo[0] + 0.3 * width, `${what}: only the stem, at the left, at the front: x ${front}`);
}

/// The signed volume of a triangle soup (three points a triangle).
function volume(points) {
  let v = 0;
  for (let i = 0; i + 2 < points.length; i += 3) {
    const [a, b, c] = [points[i], points[i + 1], points[i + 2]];
    v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return v / 6;
}

browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const s = await newSession(base);
  const page = await openPage(browser, sessionUrl(base, s));
  const cdp = page.cdp;

  // An F on the board, as the page shows it from above: the stem, the top arm, the middle arm.
  await polyline(cdp, [[300, 150], [300, 450]]);
  await polyline(cdp, [[300, 150], [500, 150]]);
  await polyline(cdp, [[300, 300], [420, 300]]);
  await until("the F's three meshes", () => page.evaluate(() => window.penmesh.meshes === 3 && !window.penmesh.pending));
  // The Front plane, seen in the three-quarter view (4): a stroke drawn up it from the board
  // to well above it, right of the F.
  await page.locator("#plane").selectOption("front");
  const plane = (await page.evaluate(() => window.penmesh.workPlane)).placement;
  await page.keyboard.press("4");
  // Its foot and top: points of its plane (x, y) with y the height above the board.
  // (The plane goes through the F's centre: its own x from there.)
  const up = await page.evaluate(([plane]) => [[650 - plane[12], 0], [650 - plane[12], 200]].map(([x, y]) => window.penmesh.toPage(x, y, plane)), [plane]);
  await polyline(cdp, up);
  await until("the standing stroke's mesh", () => page.evaluate(() => window.penmesh.meshes === 4 && !window.penmesh.pending));
  await page.screenshot({ path: join(ARTIFACTS, "orientation-page.png") });

  // 1. The STL and the 3MF.
  const stl = await exported(base, s, "stl");
  const threeMf = await exported(base, s, "3mf");
  const stlPts = stlPoints(stl);
  assertReadsAsThePage(stlPts, "STL");
  assert.ok(volume(stlPts) > 0, "the STL is wound outward");
  const mfPts = threeMfPoints(threeMf);
  assertReadsAsThePage(mfPts, "3MF");
  const stlFile = join(ARTIFACTS, "orientation.stl");
  writeFileSync(stlFile, stl);
  const info = execFileSync("prusa-slicer", ["--loglevel", "1", "--info", stlFile], { encoding: "utf8" });
  assert.match(info, /manifold = yes/, `prusa-slicer --info: ${info}`);

  // 2. The GLB, in glTF's axes (Y up, -Z back), turned to the bed's: (X, -Z, Y).
  const glb = await exported(base, s, "glb");
  const gltf = await new GLTFLoader().setMeshoptDecoder(MeshoptDecoder).parseAsync(glb.buffer.slice(glb.byteOffset, glb.byteOffset + glb.length), "");
  gltf.scene.updateMatrixWorld(true);
  const glbPts = [];
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    const p = o.geometry.attributes.position;
    for (let i = 0; i < p.count; i++) {
      const v = new THREE.Vector3().fromBufferAttribute(p, i).applyMatrix4(o.matrixWorld);
      glbPts.push([v.x, -v.z, v.y]);
    }
  });
  assertReadsAsThePage(glbPts, "GLB");

  // 3. The print's box is the GLB's, turned and scaled to millimetres (the print's parts are
  //    at least 0.8 mm thick and its meshes are solids: within 3 mm).
  const [g, p] = [bounds(glbPts), bounds(stlPts)];
  const k = Math.max(...[0, 1, 2].map((a) => p.hi[a] - p.lo[a])) / Math.max(...[0, 1, 2].map((a) => g.hi[a] - g.lo[a]));
  for (let a = 0; a < 3; a++) {
    const size = [(g.hi[a] - g.lo[a]) * k, p.hi[a] - p.lo[a]];
    assert.ok(Math.abs(size[0] - size[1]) < 3, `axis ${"XYZ"[a]}: the GLB's side ${size[0]} mm, the print's ${size[1]} mm`);
  }
  log(`F and a standing stroke: the STL, the 3MF and the GLB read as the page (print ${p.hi.map((v, a) => (v - p.lo[a]).toFixed(1)).join(" x ")} mm)`);
});
