// Records test/raw-frames.json, the reference codec.mjs holds the page's codec to on long
// batches: a real proxy's `/raw` of three long generated strokes (scribble, figure8, leaf drawn
// by `penmesh draw --synth`, seeded: the same strokes every time), each as its JSON samples and
// as the binary `retained {first: 0}` frame the proxy's Rust codec writes (in hex). Not a test:
//   cargo build --bin penmesh --bin penmesh-proxy && node client/web/test/record-raw.mjs
import { execFileSync, spawn } from "node:child_process";
import { mkdtempSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { BIN, PROXY_BIN, root, until } from "./harness.mjs";

const dir = mkdtempSync(join(tmpdir(), "penmesh-raw-"));
const port = 20000 + Math.floor(Math.random() * 20000);
const base = `http://127.0.0.1:${port}`;
const proxy = spawn(PROXY_BIN, ["--host", "127.0.0.1", "--port", String(port), "--database-url", `sqlite://${dir}/t.db`], { stdio: "ignore" });
try {
  await until("the proxy", async () => (await fetch(`${base}/healthz`)).ok);
  const s = await (await fetch(`${base}/v1/sessions`, { method: "POST" })).json();
  for (const shape of ["scribble", "figure8", "leaf"]) {
    execFileSync(BIN, ["draw", "--server", base, "--session", s.session, "--token", s.token, "--synth", shape, "--size", "600", "--speed", "200"], { stdio: "ignore" });
  }
  const auth = { authorization: `Bearer ${s.token}` };
  const { strokes } = await (await fetch(`${base}/v1/sessions/${s.session}/strokes`, { headers: auth })).json();
  const frames = [];
  for (const { id } of strokes) {
    const { samples } = await (await fetch(`${base}/v1/strokes/${id}/raw`, { headers: auth })).json();
    const bytes = Buffer.from(await (await fetch(`${base}/v1/strokes/${id}/raw`, { headers: { ...auth, accept: "application/octet-stream" } })).arrayBuffer());
    frames.push({ message: { retained: { stroke: id, first: 0, points: samples } }, hex: bytes.toString("hex") });
    console.log(`${id}: ${samples.length} samples, a frame of ${bytes.length} bytes`);
  }
  writeFileSync(join(root, "client/web/test/raw-frames.json"), JSON.stringify({ recorded_by: "client/web/test/record-raw.mjs", frames }) + "\n");
} finally {
  proxy.kill();
}
