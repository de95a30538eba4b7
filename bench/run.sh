#!/usr/bin/env bash
# Times penmesh against its peers on identical strokes, in one run, and prints the ratios:
# - LRPDP outline vs perfect-freehand getStroke (goal: at least 10x faster);
# - ACUTS (stage 1 + 2) vs simplify-js Douglas-Peucker at the same tolerance (goal: 3x).
# Usage: bench/run.sh [OUT_DIR]   (default bench/out; needs cargo, node 20 and npm)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
out="${1:-$here/out}"
mkdir -p "$out"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"

(cd "$here" && npm ci --no-audit --no-fund --silent)
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p penmesh-lab --bin penmesh-lab
penmesh="$CARGO_TARGET_DIR/release/penmesh-lab"

"$penmesh" peers export --out "$out/strokes.json"
node "$here/peers.mjs" "$out/strokes.json" "$out/node.json" > /dev/null
"$penmesh" peers compare --strokes "$out/strokes.json" --node "$out/node.json" \
    --json "$out/peers.json"
