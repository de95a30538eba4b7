// The browser test of the Export menu (client/web/src/export.js, issue 39): two strokes drawn
// on the page, then through the menu
// 1. GLB: the proxy's scene downloads, the Khronos glTF-Validator finds no error in it, three.js's
//    GLTFLoader (with its MeshoptDecoder) reads both strokes' meshes, and each stroke's node
//    carries its pen data, valid to docs/model-format.schema.json (ajv); the menu showed
//    progress while the proxy worked;
// 2. STL: the print downloads, a binary STL as long as its triangle count says, the menu's bar
//    moved by the proxy's progress lines through each stage (reading, solids, union);
// 3. import: the GLB dropped on the page of a new session comes back as two strokes of that
//    page's own, meshes and all; a file that is no penmesh GLB is refused, naming why.
// Run by scripts/test.sh.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { join } from "node:path";
import Ajv2020 from "ajv/dist/2020.js";
import validator from "gltf-validator";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { MeshoptDecoder } from "three/examples/jsm/libs/meshopt_decoder.module.js";
import { ARTIFACTS, browserTest, drawStroke, log, newSession, root, storedStrokes, synced, until } from "./harness.mjs";

// The layout of a stroke's pen data (docs/model-format.schema.json), checked on real exports.
const Ajv = Ajv2020.default ?? Ajv2020;
const schema = JSON.parse(readFileSync(join(root, "docs/model-format.schema.json"), "utf8"));
const validExtras = new Ajv({ allErrors: true }).compile(schema);

await browserTest(async ({ proxy, browser }) => {
  const { base } = proxy;
  const first = await newSession(base);
  const context = await browser.newContext({ viewport: { width: 1100, height: 700 }, deviceScaleFactor: 1, acceptDownloads: true });
  const page = await context.newPage();
  page.on("pageerror", (e) => console.error("page error:", e.message));
  await page.goto(`${base}/s/${first.session}#token=${first.token}`);
  await synced(page);
  const cdp = await context.newCDPSession(page);
  await drawStroke(cdp, { x0: 200, y0: 250, dx: 5, dy: 1, n: 60 });
  await drawStroke(cdp, { x0: 300, y0: 450, dx: 4, dy: -2, n: 60 });
  await until("both meshes shown", () => page.evaluate(() => window.penmesh.meshes >= 2));

  // Every status line the menu shows, in order.
  await page.evaluate(() => {
    window.exportStatuses = [];
    const status = document.getElementById("export-status");
    // (Each change is a record: a fast export sets several before the observer runs.)
    new MutationObserver((records) => {
      for (const r of records) for (const n of r.addedNodes) window.exportStatuses.push(n.textContent);
    }).observe(status, { childList: true });
    // And every value the bar took.
    window.exportBar = [];
    const bar = document.getElementById("export-progress");
    new MutationObserver((records) => {
      for (const r of records) window.exportBar.push(r.oldValue);
    }).observe(bar, { attributeFilter: ["value"], attributeOldValue: true });
  });
  if (!(await page.isVisible("#download"))) await page.click("#toggle-more");
  await page.click("#download");
  assert.ok(await page.isVisible("#export-menu"), "the Export menu opens");

  // --- 1. GLB ---------------------------------------------------------------------------
  const [glbDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-glb")]);
  assert.equal(glbDownload.suggestedFilename(), `penmesh-${first.session}.glb`);
  const glb = readFileSync(await glbDownload.path());
  const statuses = await page.evaluate(() => window.exportStatuses);
  assert.ok(statuses.some((s) => s.startsWith("the proxy is making the GLB")), `progress while the proxy works: ${statuses}`);
  assert.ok(statuses.some((s) => s.startsWith("GLB ready")), `${statuses}`);
  const report = await validator.validateBytes(new Uint8Array(glb), { maxIssues: 100, format: "glb" });
  const errors = report.issues.messages.filter((m) => m.severity === 0);
  assert.deepEqual(errors, [], "the glTF-Validator finds no error");
  const gltf = await new GLTFLoader().setMeshoptDecoder(MeshoptDecoder).parseAsync(glb.buffer.slice(glb.byteOffset, glb.byteOffset + glb.length), "");
  let meshes = 0;
  const strokes = [];
  gltf.scene.traverse((o) => {
    if (o.isMesh) meshes += 1;
    if (o.userData.penmesh) strokes.push(o.userData.penmesh);
  });
  assert.equal(meshes, 2, "three.js reads both strokes' meshes");
  assert.equal(strokes.length, 2, "two stroke nodes with pen data");
  const stored = await storedStrokes(base, first);
  for (const s of strokes) {
    assert.ok(stored.some((t) => t.id === s.stroke), `stroke ${s.stroke} is the session's`);
    assert.ok(s.samples.length >= 2 && s.samples[0].length === 4, "samples as [x, y, t, p]");
    assert.ok(validExtras(s), `extras.penmesh against the schema: ${JSON.stringify(validExtras.errors)}`);
  }
  log(`GLB: ${glb.length} bytes, valid (${report.issues.numWarnings} warnings), two strokes with their pen data`);

  // The download started: the menu closed itself, out of the board's way (issue 50).
  await until("the menu closed after the GLB's download", async () => !(await page.isVisible("#export-menu")));

  // --- 2. STL ---------------------------------------------------------------------------
  await page.click("#download");
  await page.evaluate(() => {
    window.exportStatuses.length = 0;
    window.exportBar.length = 0;
  });
  const [stlDownload] = await Promise.all([page.waitForEvent("download"), page.click("#export-stl")]);
  const stl = readFileSync(await stlDownload.path());
  // The proxy's progress lines moved the bar through each stage: the strokes meshed one by one,
  // then their union.
  const stlStatuses = await page.evaluate(() => window.exportStatuses);
  for (const stage of ["reading", "solids", "union"]) {
    assert.ok(stlStatuses.some((s) => s.startsWith(`STL: ${stage}`)), `the ${stage} stage shown: ${stlStatuses}`);
  }
  const solids = stlStatuses.filter((s) => s.startsWith("STL: solids")).map((s) => Number(s.split(" ")[2]));
  assert.deepEqual(solids, [...solids].sort((a, b) => a - b), `the strokes meshed count up: ${solids}`);
  const positions = await page.evaluate(() => [...window.exportBar, document.getElementById("export-progress").getAttribute("value")]);
  assert.ok(new Set(positions.filter((v) => v !== null)).size >= 3, `the bar moved: ${positions}`);
  assert.ok(stlStatuses.at(-1).startsWith("STL ready"), `${stlStatuses}`);
  const triangles = stl.readUInt32LE(80);
  assert.ok(triangles > 100, `${triangles} triangles`);
  assert.equal(stl.length, 84 + 50 * triangles, "a whole binary STL");
  log(`STL: ${triangles} triangles`);
  await until("the menu closed after the STL's download", async () => !(await page.isVisible("#export-menu")));

  // --- 3. import, by dropping the file on a new session's page ---------------------------
  const second = await newSession(base);
  const other = await context.newPage();
  await other.goto(`${base}/s/${second.session}#token=${second.token}`);
  await synced(other);
  const drop = (bytes, name) =>
    other.evaluate(([b64, name]) => {
      const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
      const data = new DataTransfer();
      data.items.add(new File([bytes], name));
      document.dispatchEvent(new DragEvent("drop", { dataTransfer: data, bubbles: true, cancelable: true }));
    }, [Buffer.from(bytes).toString("base64"), name]);
  // A print dropped is said so, naming it: the page brings back only GLB scenes (issue 50).
  await drop(Buffer.from("solid x\nendsolid x\n"), "house.stl");
  await until("the page to say the STL cannot be imported", () => other.evaluate(() => window.penmesh.errors.some((e) => e.includes("house.stl") && e.includes("only a GLB"))));
  // And one chosen in the menu.
  await other.click("#download");
  await other.setInputFiles("#import-file", { name: "house.3mf", mimeType: "model/3mf", buffer: Buffer.from("PK") });
  await until("the page to say the 3MF cannot be imported", () => other.evaluate(() => window.penmesh.errors.some((e) => e.includes("house.3mf") && e.includes("only a GLB"))));
  await other.click("#export-close");
  await drop(Buffer.from("not a model at all"), "junk.glb");
  await until("the page to say why the file is refused", () => other.evaluate(() => window.penmesh.errors.some((e) => e.includes("junk.glb") && e.includes("not a GLB"))));
  assert.equal((await storedStrokes(base, second)).length, 0, "nothing imported");
  await drop(glb, "model.glb");
  await until("both imported strokes shown with their meshes", () => other.evaluate(() => window.penmesh.meshes >= 2));
  const imported = await storedStrokes(base, second);
  assert.equal(imported.length, 2);
  const me = await other.evaluate(() => window.penmesh.me);
  assert.ok(imported.every((s) => s.participant === me && s.has_mesh), "the importer draws them, meshes built");
  await other.screenshot({ path: join(ARTIFACTS, "export-imported.png") });
  log("import: the dropped GLB came back as the page's own two strokes");
});
