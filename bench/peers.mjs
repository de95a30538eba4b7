// Times the peers on the strokes penmesh exported (`penmesh-lab peers export`):
// - perfect-freehand's getStroke (the outline most web drawing apps use for pressure strokes),
// - simplify-js (Douglas-Peucker; highQuality = pure DP, and the default radial pre-pass + DP)
//   at the same tolerance as ACUTS.
// Usage: node peers.mjs STROKES.json OUT.json
// Each measurement is the median of 7 runs of as many calls as fill 100 ms, after a warm-up.

import { readFileSync, writeFileSync } from "node:fs";
import { getStroke } from "perfect-freehand";
import simplify from "simplify-js";

const [input, output] = process.argv.slice(2);
if (!input || !output) {
  console.error("usage: node peers.mjs STROKES.json OUT.json");
  process.exit(2);
}
const data = JSON.parse(readFileSync(input, "utf8"));

function nsPerCall(fn) {
  for (let i = 0; i < 50; i++) fn();
  let calls = 1;
  for (;;) {
    const t0 = process.hrtime.bigint();
    for (let i = 0; i < calls; i++) fn();
    const ns = Number(process.hrtime.bigint() - t0);
    if (ns > 100e6) break;
    calls *= 2;
  }
  const runs = [];
  for (let r = 0; r < 7; r++) {
    const t0 = process.hrtime.bigint();
    for (let i = 0; i < calls; i++) fn();
    runs.push(Number(process.hrtime.bigint() - t0) / calls);
  }
  runs.sort((a, b) => a - b);
  return runs[3];
}

// perfect-freehand's size is the diameter; penmesh's brush size E is the radius at full
// pressure with a pressure response of 1. thinning plays the part of the pressure response.
const freehandOptions = {
  size: 2 * data.brush_size,
  thinning: data.pressure_response,
  smoothing: 0.5,
  streamline: 0.5,
  simulatePressure: false,
  last: true,
};

const strokes = data.strokes.map((stroke) => {
  const points = stroke.samples.map(([x, y, , p]) => [x, y, p]);
  const xy = stroke.samples.map(([x, y]) => ({ x, y }));
  let outline = [];
  let keptHq = [];
  let keptFast = [];
  const freehand_ns = nsPerCall(() => {
    outline = getStroke(points, freehandOptions);
  });
  const simplify_hq_ns = nsPerCall(() => {
    keptHq = simplify(xy, data.tolerance, true);
  });
  const simplify_fast_ns = nsPerCall(() => {
    keptFast = simplify(xy, data.tolerance, false);
  });
  return {
    name: stroke.name,
    n_samples: points.length,
    freehand_ns,
    freehand_outline_points: outline.length,
    simplify_hq_ns,
    simplify_hq_kept: keptHq.length,
    simplify_fast_ns,
    simplify_fast_kept: keptFast.length,
  };
});

writeFileSync(
  output,
  JSON.stringify({ runtime: `node ${process.version}`, options: freehandOptions, strokes }, null, 2),
);
for (const s of strokes) {
  console.log(
    `${s.name.padEnd(16)} n=${String(s.n_samples).padStart(6)}  getStroke ${(s.freehand_ns / 1000).toFixed(1)} us  ` +
      `simplify(hq) ${(s.simplify_hq_ns / 1000).toFixed(1)} us  simplify ${(s.simplify_fast_ns / 1000).toFixed(1)} us`,
  );
}
