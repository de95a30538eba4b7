// The mesh bundle the page opens a session with (PMB3, docs/protocol.md "HTTP"): each stored
// mesh once, every stroke with its placement and solid (issues 49 item 10, 51).
// 1. `penmesh draw` draws a leaf and a scribble made a hole; 6 duplicates of the leaf and one of
//    the hole are made over HTTP, placed apart.
// 2. The page's decoder (api.js) reads the session's PMB3 bundle: two meshes, every stored
//    stroke with its placement and solid as the proxy lists them, the leaf's copies sharing
//    its mesh's bytes, and the body about one leaf, one hole and a 173-byte entry per stroke.
// 3. A page whose WebSocket never reaches the proxy (routed to nothing) shows every stroke from
//    the bundle alone: its mesh, at its placement, the holes drawn as holes; no stroke's mesh is
//    fetched on its own.
// 4. A page as usual: synced, the same strokes, no mesh fetched on its own. Screenshot:
//    target/web-test/bundle.png.
// Run by scripts/test.sh as `node client/web/test/bundle.mjs`.
import assert from "node:assert/strict";
import { join } from "node:path";
import { randomBytes, randomUUID } from "node:crypto";
import { decodeMeshBundle } from "../src/api.js";
import { ARTIFACTS, browserTest, log, newSession, runPenmesh, storedStrokes, until } from "./harness.mjs";

const VIEW = { width: 1000, height: 700 };
const COPIES = 6;
const IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
const HOLE = { kind: "hole", depth: 24 };
const moved = (dx, dy) => IDENTITY.map((v, k) => (k === 12 ? dx : k === 13 ? dy : v));

browserTest(async ({ proxy, browser, children }) => {
  const { base } = proxy;
  const s = await newSession(base);
  const auth = { authorization: `Bearer ${s.token}` };
  const draw = (args) => runPenmesh(["draw", "--server", base, "--session", s.session, "--token", s.token, "--size", "200", ...args], children);
  await draw(["--synth", "leaf", "--name", "leaf"]);
  await draw(["--synth", "scribble", "--solid", "hole", "--depth", String(HOLE.depth), "--name", "hole"]);
  const [leaf, hole] = await storedStrokes(base, s);
  assert.deepEqual(hole.solid, HOLE, "the scribble is a hole");
  // Duplicates over HTTP, as the page's Select tool makes them, by a third participant.
  const key = randomBytes(16).toString("hex");
  const duplicate = async (source, placement) => {
    const res = await fetch(`${base}/v1/strokes/${source}/duplicate`, {
      method: "POST",
      headers: { ...auth, "x-penmesh-key": key, "content-type": "application/json" },
      body: JSON.stringify({ stroke: randomUUID(), placement: { matrix: placement } }),
    });
    assert.equal(res.status, 201, await res.text());
  };
  for (let k = 1; k <= COPIES; k++) await duplicate(leaf.id, moved(260 * k, 40 * k));
  await duplicate(hole.id, moved(0, 300));
  let stored;
  await until("every stroke with its mesh", async () => {
    stored = await storedStrokes(base, s);
    return stored.length === COPIES + 3 && stored.every((x) => x.has_mesh);
  });
  log(`${stored.length} strokes stored: a leaf, ${COPIES} copies, a hole and its copy`);

  // 2. The page's decoder.
  const res = await fetch(`${base}/v1/sessions/${s.session}/meshes?layout=PMB3`, { headers: { ...auth, "accept-encoding": "identity" } });
  assert.equal(res.status, 200);
  const body = await res.arrayBuffer();
  assert.equal(new TextDecoder().decode(body.slice(0, 4)), "PMB3");
  const bundle = decodeMeshBundle(body);
  assert.deepEqual(bundle.map((m) => m.stroke), stored.map((x) => x.id), "every stroke, in the list's order");
  for (const [m, x] of bundle.map((m, i) => [m, stored[i]])) {
    assert.equal(m.participant, x.participant);
    assert.deepEqual(m.placement, x.placement.matrix, `stroke ${x.id}'s placement`);
    assert.deepEqual(m.solid, x.solid, `stroke ${x.id}'s solid`);
    const own = await (await fetch(`${base}/v1/strokes/${x.id}/mesh`, { headers: auth })).arrayBuffer();
    assert.deepEqual(new Uint8Array(m.glb), new Uint8Array(own), `stroke ${x.id}'s mesh`);
  }
  const meshes = new Set(bundle.map((m) => m.glb));
  assert.equal(meshes.size, 2, "the leaf's mesh and the hole's, each read once");
  const meshBytes = [...meshes].reduce((n, glb) => n + 4 + glb.byteLength, 0);
  assert.equal(body.byteLength, 12 + meshBytes + 173 * bundle.length);
  log(`bundle: ${body.byteLength} bytes for ${bundle.length} strokes and 2 meshes (${meshBytes} bytes)`);
  // Bytes that are not a bundle: an Error naming where, never a stroke made up.
  const last = bundle.length - 1;
  const damaged = (at, set) => {
    const copy = body.slice(0);
    set(new DataView(copy), body.byteLength - at);
    return copy;
  };
  assert.throws(() => decodeMeshBundle(body.slice(0, body.byteLength - 1)), new RegExp(`ends inside stroke ${last}`));
  assert.throws(() => decodeMeshBundle(damaged(4, (v, at) => v.setUint32(at, 2, true))), new RegExp(`stroke ${last} shows mesh 2, but it has 2`));
  assert.throws(() => decodeMeshBundle(damaged(13, (v, at) => v.setUint8(at, 7))), new RegExp(`stroke ${last}'s solid is of kind 7`));
  assert.throws(() => decodeMeshBundle(body.slice(0, 10)), /ends inside its head/);

  const url = `${base}/s/${s.session}#token=${s.token}`;
  const open = async (name, routeSocket) => {
    const context = await browser.newContext({ viewport: VIEW, deviceScaleFactor: 1 });
    const page = await context.newPage();
    page.on("pageerror", (e) => console.error(`[${name}] page error:`, e.message));
    page.requests = [];
    page.on("request", (r) => page.requests.push(r.url()));
    // The WebSocket handled here and never answered: only the bundle can show anything.
    if (routeSocket) await page.routeWebSocket(/\/ws$/, () => {});
    await page.goto(url);
    await page.waitForFunction((n) => window.penmesh && window.penmesh.meshes === n, stored.length);
    return page;
  };
  // What a page shows of each stroke: its placement, its solid, and whether its mesh is drawn
  // among the holes.
  const shown = (page) =>
    page.evaluate(() =>
      Object.fromEntries(
        [...window.penmesh.strokes].map(([id, st]) => [id, { placement: st.placement, solid: st.solid, hole: st.mesh.group.key.includes(" hole ") }]),
      ),
    );
  const expected = Object.fromEntries(
    stored.map((x) => {
      const isHole = x.solid.kind === "hole";
      return [x.id, { placement: x.placement.matrix, solid: isHole ? x.solid : null, hole: isHole }];
    }),
  );
  const ownMeshFetches = (page) => page.requests.filter((u) => /\/v1\/strokes\/[^/]+\/mesh$/.test(u));

  // 3. The bundle alone.
  const cut = await open("no socket", true);
  assert.deepEqual(await shown(cut), expected, "the bundle alone gives every stroke its placement and solid");
  assert.ok(cut.requests.some((u) => u.endsWith("/meshes?layout=PMB3")), "the page asks for PMB3");
  assert.deepEqual(ownMeshFetches(cut), []);
  await cut.context().close();
  log("a page without its socket shows every stroke from the bundle, the holes as holes");

  // 4. As usual.
  const page = await open("usual", false);
  await page.waitForFunction(() => window.penmesh.synced);
  assert.deepEqual(await shown(page), expected);
  assert.deepEqual(ownMeshFetches(page), [], "no mesh fetched on its own");
  await page.locator("#gl").screenshot({ path: join(ARTIFACTS, "bundle.png") });
  log("a page as usual: the same, synced");
});
