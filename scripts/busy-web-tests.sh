#!/usr/bin/env bash
# The browser suites of scripts/test.sh (or the SUITEs named, e.g. `house workplane`), RUNS
# times (default 5), with both cores kept busy the whole time by stress-ng (two CPU workers at
# full load; installed with apt-get when missing), on top of whatever else the machine runs (docs/web.md, "On a busy machine"). Needs the debug
# binaries (cargo build --bin penmesh --bin penmesh-proxy) and client/web's npm ci. Prints one
# line per suite and run; exits 1 when any failed. Logs: $LOGS (default /tmp/penmesh-busy-web).
# Usage: scripts/busy-web-tests.sh [RUNS] [SUITE…]
set -uo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
shift || true
suites=("$@")
if [ ${#suites[@]} -eq 0 ]; then
  suites=(browser drawing-tool lost-end mesh-build first-minutes stroke-width move-bytes model export
    orientation camera house solids workplane)
fi
logs=${LOGS:-/tmp/penmesh-busy-web}
mkdir -p "$logs"
command -v stress-ng >/dev/null || apt-get install -y stress-ng || { apt-get update && apt-get install -y stress-ng; }
export PENMESH_BIN=${PENMESH_BIN:-${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh}
stress-ng --cpu 2 --cpu-load 100 --timeout 0 >"$logs/stress-ng.log" 2>&1 &
stress=$!
trap 'kill $stress' EXIT
failed=0
for run in $(seq "$runs"); do
  echo "== run $run at $(date -u +%H:%M:%S), load $(cut -d' ' -f1-3 /proc/loadavg)"
  for t in "${suites[@]}"; do
    start=$SECONDS
    if node "client/web/test/$t.mjs" >"$logs/run$run-$t.log" 2>&1; then r=PASS; else r=FAIL; failed=$((failed + 1)); fi
    echo "$t: $r in $((SECONDS - start)) s"
  done
done
echo "failed: $failed"
exit $((failed > 0))
