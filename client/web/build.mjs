// Bundles the page into one ES module with esbuild: node build.mjs OUT_DIR
// (proxy/build.rs runs it; the proxy embeds OUT_DIR/{index.html,app.js,app.js.gz}).
import { build } from "esbuild";
import { copyFileSync, mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { gzipSync } from "node:zlib";
import { join } from "node:path";

const out = process.argv[2];
if (!out) {
  console.error("usage: node build.mjs OUT_DIR");
  process.exit(2);
}
mkdirSync(out, { recursive: true });
await build({
  entryPoints: ["src/app.js"],
  bundle: true,
  format: "esm",
  minify: true,
  target: "es2020",
  outfile: join(out, "app.js"),
  logLevel: "warning",
});
copyFileSync("src/index.html", join(out, "index.html"));
writeFileSync(join(out, "app.js.gz"), gzipSync(readFileSync(join(out, "app.js")), { level: 9 }));
