#!/usr/bin/env bash
# The main job on the embedded default: generate strokes, simplify them, build their meshes.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/demo}
mkdir -p "$out"
cargo build --release --bin penmesh
bin=target/release/penmesh
for shape in figure8 semicircles chromosome leaf scribble; do
  "$bin" synth "$shape" --out "$out/$shape.csv"
  "$bin" simplify "$out/$shape.csv" --svg "$out/$shape.svg"
  "$bin" mesh "$out/$shape.csv" --out "$out/$shape.glb"
done
echo "GLB, SVG and CSV files are in $out/"
