#!/usr/bin/env bash
# The load sweep of docs/performance-log.md: the proxy and the ceiling server at rising pen counts,
# the same settings for both (200 Hz, 12 ms batches, 30 s, one session per pen), then the idle
# memory run, the table and the plots.
# Usage: bench/load-sweep.sh [OUT_DIR] [PENS...]   (default docs/load, 250 500 1000 1500 2000)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
out="${1:-$root/docs/load}"
shift || true
pens=("${@:-250 500 1000 1500 2000}")
read -r -a pens <<< "${pens[*]}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p penmesh-lab --bin penmesh-lab
penmesh="$CARGO_TARGET_DIR/release/penmesh-lab"
mkdir -p "$out"

for n in "${pens[@]}"; do
    for target in proxy ceiling; do
        echo "== $target, $n pens ($(cut -d' ' -f1-3 /proc/loadavg))"
        "$penmesh" load "--spawn-$target" --clients "$n" --rate 200 --batch-ms 12 \
            --duration 30 --ramp 10 --label "sweep-$target-$n" \
            --json "$out/sweep-$target-$n.json" || true
    done
done
"$penmesh" load --spawn-proxy --idle --clients 2000 --duration 25 --ramp 10 \
    --label idle-2000 --json "$out/idle-2000.json"
"$penmesh" load-report --out-dir "$root/docs/figures" "$out"/sweep-*.json
