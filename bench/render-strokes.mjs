// Side-by-side pictures of the same raw strokes: as drawn (the dense raw polyline, width from
// pressure), as perfect-freehand's outline, as the paper's straight LRPDP mesh and as the smooth
// LRPDP mesh (the default), the meshes rendered with three.js in headless Chromium.
//
// Usage (from the repository root, after `cargo build --release -p penmesh-client` (with
// `--features poisson` for --meshers) and
// `npm ci --prefix bench`):
//   node bench/render-strokes.mjs IN.{txt,hwr,csv,json} OUT.png [--px-per-unit K] [--zoom F]
//        [--meshers [--poisson-depth D]]
// --zoom F renders the middle 1/F of the picture, F times larger, to show corners close up.
// --meshers shows the direct solid and the paper's screened Poisson mesh of the same strokes
// (both on the default smooth outline) in the two 3D panels instead of the two outlines.
// Needs Debian's Chromium (/usr/bin/chromium, or CHROMIUM=path); three.js is served from
// bench/node_modules, nothing is fetched.

import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync } from 'node:fs';
import { createServer } from 'node:http';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { getStroke } from 'perfect-freehand';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '..');
const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  if (i < 0) return fallback;
  const [, value] = args.splice(i, 2);
  return value;
};
const pxPerUnit = option('--px-per-unit', null);
const zoom = Number(option('--zoom', '1'));
const poissonDepth = option('--poisson-depth', null);
const meshers = args.includes('--meshers');
if (meshers) args.splice(args.indexOf('--meshers'), 1);
const [input, output] = args;
if (!input || !output || !(zoom >= 1)) {
  console.error('usage: node bench/render-strokes.mjs IN OUT.png [--px-per-unit K] [--zoom F >= 1]');
  process.exit(2);
}
const penmesh = process.env.PENMESH ?? join(root, 'target/release/penmesh');
const work = mkdtempSync(join(tmpdir(), 'penmesh-render-'));

// Both meshes come from `penmesh mesh --json`, which also returns the raw samples it read.
function mesh(centreline, mesher = 'direct') {
  const glb = join(work, `${centreline}-${mesher}.glb`);
  const cmd = ['mesh', input, '--out', glb, '--json', '--centreline', centreline, '--mesher', mesher];
  if (pxPerUnit) cmd.push('--px-per-unit', pxPerUnit);
  if (poissonDepth) cmd.push('--poisson-depth', poissonDepth);
  const report = JSON.parse(execFileSync(penmesh, cmd, { encoding: 'utf8', maxBuffer: 1 << 28 }));
  return { report, glb: readFileSync(glb).toString('base64') };
}
// The two 3D panels: the straight and smooth outlines' solids, or (--meshers) the direct solid
// and the Poisson mesh of the smooth outline.
const straight = meshers ? mesh('smooth', 'poisson') : mesh('straight');
const smooth = mesh('smooth');
const raw = smooth.report.raw;
const brush = smooth.report.parameters.brush;
// perfect-freehand's outline of each raw stroke, at the same full-pressure diameter.
const freehand = raw.map((stroke) =>
  getStroke(stroke, { size: 2 * brush.size * brush.pressure_response, thinning: 0.6,
    smoothing: 0.5, streamline: 0.5, simulatePressure: false, last: true }));

const panels = [
  { title: `as drawn: raw polyline (${smooth.report.samples} samples)` },
  { title: 'perfect-freehand outline' },
  { title: meshers
    ? `screened Poisson (paper): ${straight.report.vertices} vertices, ${straight.report.bytes} B`
    : `straight LRPDP (paper): ${straight.report.vertices} vertices, ${straight.report.bytes} B` },
  { title: meshers
    ? `direct solid (default): ${smooth.report.vertices} vertices, ${smooth.report.bytes} B`
    : `smooth LRPDP (default): ${smooth.report.vertices} vertices, ${smooth.report.bytes} B` },
];

const page = `<!doctype html><html><head><meta charset="utf-8"><style>
body { margin: 0; background: #fff; font: 14px sans-serif; }
.grid { display: grid; grid-template-columns: repeat(2, 640px); gap: 8px; padding: 8px; }
.cell { width: 640px; } .cell div { padding: 2px 0 4px; color: #333; }
canvas { width: 640px; height: 400px; display: block; border: 1px solid #ccc; }
</style><script type="importmap">{ "imports": {
  "three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/" } }</script>
</head><body><div class="grid">${panels.map((p, i) =>
    `<div class="cell"><div>${p.title}</div><canvas id="c${i}" width="1280" height="800"></canvas></div>`).join('')}
</div><script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
const data = window.DATA;
const all = data.raw.flat();
const xs = all.map((p) => p[0]), ys = all.map((p) => p[1]);
const pad = 10;
let [x0, x1, y0, y1] = [Math.min(...xs) - pad, Math.max(...xs) + pad, Math.min(...ys) - pad, Math.max(...ys) + pad];
// Zoom on the middle of the picture.
const [cx, cy] = [(x0 + x1) / 2, (y0 + y1) / 2];
const half = Math.max((x1 - x0) / 2, (y1 - y0) / 2 * 1.6) / data.zoom;
[x0, x1, y0, y1] = [cx - half, cx + half, cy - half / 1.6, cy + half / 1.6];
const W = 1280, H = 800;
// Pen y grows downwards on screen, as on the tablet: flip nothing in 2D, flip the camera in 3D.
const toCanvas = (x, y) => [(x - x0) / (x1 - x0) * W, (y - y0) / (y1 - y0) * H];
const scale = W / (x1 - x0);
function ctx2d(id) { const c = document.getElementById(id).getContext('2d'); c.fillStyle = '#fff'; c.fillRect(0, 0, W, H); return c; }
{ // As drawn: each raw segment as wide as the pen's radius there.
  const c = ctx2d('c0'); c.strokeStyle = '#1d3557'; c.lineCap = 'round';
  for (const s of data.raw) for (let k = 1; k < s.length; k++) {
    const r = Math.max(data.brush.min_radius, data.brush.size * data.brush.pressure_response * (s[k - 1][2] + s[k][2]) / 2);
    c.lineWidth = 2 * r * scale; c.beginPath(); c.moveTo(...toCanvas(s[k - 1][0], s[k - 1][1])); c.lineTo(...toCanvas(s[k][0], s[k][1])); c.stroke();
  }
}
{ // perfect-freehand: its outline polygon, filled.
  const c = ctx2d('c1'); c.fillStyle = '#1d3557';
  for (const poly of data.freehand) { if (!poly.length) continue; c.beginPath(); c.moveTo(...toCanvas(...poly[0]));
    for (const p of poly.slice(1)) c.lineTo(...toCanvas(...p)); c.closePath(); c.fill('nonzero'); }
}
// penmesh's GLBs are meshopt-compressed by default.
const loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
async function render3d(id, base64) {
  const canvas = document.getElementById(id);
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setSize(W, H, false); renderer.setClearColor(0xffffff);
  const scene = new THREE.Scene();
  scene.add(new THREE.AmbientLight(0xffffff, 0.9));
  const light = new THREE.DirectionalLight(0xffffff, 2.2); light.position.set(-0.4, -0.5, 1); scene.add(light);
  // Looking down -z; top = y0 so the picture reads like the 2D panels (y down).
  const camera = new THREE.OrthographicCamera(x0, x1, -y0, -y1, -1000, 1000);
  camera.scale.set(1, 1, 1);
  const bytes = Uint8Array.from(atob(base64), (ch) => ch.charCodeAt(0));
  const gltf = await loader.parseAsync(bytes.buffer, '');
  const material = new THREE.MeshStandardMaterial({ color: 0x1d3557, roughness: 0.45, metalness: 0.1 });
  gltf.scene.traverse((o) => { if (o.isMesh) o.material = material; });
  const group = new THREE.Group(); group.scale.set(1, -1, 1); group.add(gltf.scene);
  // Mirroring y turns the winding inside out: draw both faces.
  material.side = THREE.DoubleSide;
  scene.add(group);
  renderer.render(scene, camera);
}
await render3d('c2', data.straight);
await render3d('c3', data.smooth);
window.DONE = true;
</script></body></html>`;

const types = { '.js': 'text/javascript', '.html': 'text/html' };
const server = createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  if (url === '/') { res.writeHead(200, { 'content-type': 'text/html' }); res.end(page); return; }
  if (url.startsWith('/three/') && !url.includes('..')) {
    try {
      const body = readFileSync(join(here, 'node_modules', url));
      res.writeHead(200, { 'content-type': types[url.slice(url.lastIndexOf('.'))] ?? 'application/octet-stream' });
      res.end(body);
      return;
    } catch { /* fall through to 404 */ }
  }
  res.writeHead(404); res.end();
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--headless=new'],
});
try {
  const tab = await browser.newPage({ viewport: { width: 1304, height: 880 } });
  tab.on('pageerror', (e) => console.error('page error:', e.message));
  await tab.addInitScript((d) => { window.DATA = d; }, {
    raw, freehand, brush, zoom, straight: straight.glb, smooth: smooth.glb,
  });
  await tab.goto(`http://127.0.0.1:${server.address().port}/`);
  await tab.waitForFunction(() => window.DONE === true, null, { timeout: 60_000 });
  await tab.screenshot({ path: output, fullPage: true });
  console.log(`${output}: ${panels.map((p) => p.title).join('; ')}`);
} finally {
  await browser.close();
  server.close();
}
