// A picture of an exported model: a print's STL (penmesh-print's output, millimetres) rendered
// with three.js's STLLoader, or a scene's GLB (`export?format=glb`, metres, Y up, meshopt) with
// its GLTFLoader and MeshoptDecoder, in its strokes' colours, in headless Chromium, seen from
// above at an angle, with its size.
//
// Usage (from the repository root, after `npm ci --prefix bench`):
//   cargo run --release -p penmesh-print --example print_board -- 30 /tmp/board.stl
//   node bench/render-print.mjs /tmp/board.stl docs/figures/print-board.png
//   node bench/render-print.mjs /tmp/board.glb docs/figures/scene-board.png
// Needs Debian's Chromium (/usr/bin/chromium, or CHROMIUM=path); three.js is served from
// bench/node_modules, nothing is fetched.

import { readFileSync } from 'node:fs';
import { createServer } from 'node:http';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const [input, output] = process.argv.slice(2);
if (!input || !output) {
  console.error('usage: node bench/render-print.mjs IN.stl|IN.glb OUT.png');
  process.exit(2);
}
const stl = readFileSync(input).toString('base64');
const kind = input.toLowerCase().endsWith('.glb') ? 'glb' : 'stl';

const page = `<!doctype html><html><head><meta charset="utf-8"><style>
body { margin: 0; background: #fff; font: 14px sans-serif; } #t { padding: 6px 8px; color: #333; }
canvas { width: 1200px; height: 750px; display: block; }
</style><script type="importmap">{ "imports": {
  "three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/" } }</script>
</head><body><div id="t"></div><canvas id="c" width="2400" height="1500"></canvas><script type="module">
import * as THREE from 'three';
import { STLLoader } from 'three/addons/loaders/STLLoader.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
const bytes = Uint8Array.from(atob(window.STL), (ch) => ch.charCodeAt(0));
let object, label;
if (window.KIND === 'glb') {
  // The scene is in metres with Y up: turned Z up and scaled to mm, for the same camera.
  const gltf = await new GLTFLoader().setMeshoptDecoder(MeshoptDecoder).parseAsync(bytes.buffer, '');
  object = new THREE.Group();
  object.rotation.x = Math.PI / 2;
  object.scale.setScalar(1000);
  object.add(gltf.scene);
  let strokes = 0;
  gltf.scene.traverse((o) => { if (o.userData.penmesh) strokes += 1; });
  label = 'exported scene (GLB, ' + strokes + ' strokes with their pen data): ';
} else {
  const geometry = new STLLoader().parse(bytes.buffer);
  object = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ color: 0xe07a2f, roughness: 0.5, flatShading: true }));
  label = 'exported print (STL, ' + geometry.attributes.position.count / 3 + ' triangles): ';
}
object.updateMatrixWorld(true);
const box = new THREE.Box3().setFromObject(object), size = new THREE.Vector3(), centre = new THREE.Vector3();
box.getSize(size); box.getCenter(centre);
document.getElementById('t').textContent = label +
  size.x.toFixed(1) + ' × ' + size.y.toFixed(1) + ' × ' + size.z.toFixed(2) + ' mm';
const renderer = new THREE.WebGLRenderer({ canvas: document.getElementById('c'), antialias: true, preserveDrawingBuffer: true });
renderer.setSize(2400, 1500, false); renderer.setClearColor(0xffffff);
const scene = new THREE.Scene();
scene.add(new THREE.AmbientLight(0xffffff, 0.6));
const light = new THREE.DirectionalLight(0xffffff, 2.4); light.position.set(-0.5, -0.8, 1.2); scene.add(light);
// A print bed under the model, 5 mm past it on each side.
const bed = new THREE.Mesh(new THREE.PlaneGeometry(size.x + 10, size.y + 10),
  new THREE.MeshStandardMaterial({ color: 0xe8e8e8 }));
bed.position.set(centre.x, centre.y, box.min.z - 0.01); scene.add(bed);
scene.add(object);
const camera = new THREE.PerspectiveCamera(30, 1.6, 1, 10000);
const d = Math.max(size.x, size.y, size.z * 1.6) * 1.55;
camera.up.set(0, 0, 1);
camera.position.set(centre.x, centre.y - d * 0.75, centre.z + d * 0.8);
camera.lookAt(centre);
renderer.render(scene, camera);
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
  const tab = await browser.newPage({ viewport: { width: 1200, height: 790 } });
  tab.on('pageerror', (e) => console.error('page error:', e.message));
  await tab.addInitScript(([s, k]) => { window.STL = s; window.KIND = k; }, [stl, kind]);
  await tab.goto(`http://127.0.0.1:${server.address().port}/`);
  await tab.waitForFunction(() => window.DONE === true, null, { timeout: 60_000 });
  await tab.screenshot({ path: output, fullPage: true });
  console.log(`${output}: ${await tab.textContent('#t')}`);
} finally {
  await browser.close();
  server.close();
}
