#!/usr/bin/env bash
# What the proxy spends per stored sample, by thread, and what it writes to storage: the
# per-thread CPU and write-amplification numbers of docs/performance.md and docs/storage.md.
# Runs `penmesh load --spawn-proxy` (SQLite in a temporary folder) and samples the spawned
# proxy's /proc/PID/task/*/stat and /proc/PID/io until it exits.
# The SQLite file is kept until the end, to weigh what it holds per stored sample.
# Usage: bench/proxy-cost.sh PENS [SECONDS] [-- PROXY_ARG...]
#   e.g. bench/proxy-cost.sh 500 25 -- --commit-interval-ms=12
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
pens="${1:?usage: bench/proxy-cost.sh PENS [SECONDS] [-- PROXY_ARG...]}"
shift
seconds=25
if [ $# -gt 0 ] && [ "$1" != "--" ]; then seconds="$1"; shift; fi
[ "${1:-}" = "--" ] && shift
proxy_args=()
for arg in "$@"; do proxy_args+=("--proxy-arg=$arg"); done

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p penmesh-client --bin penmesh
penmesh="$CARGO_TARGET_DIR/release/penmesh"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# Our own SQLite file, to weigh what it holds per sample once the proxy has stopped.

"$penmesh" load --spawn-proxy --database-url "sqlite://$work/penmesh.db" "${proxy_args[@]}" --clients "$pens" --rate 200 \
    --duration "$seconds" --ramp 5 --label "proxy-cost-$pens" --json "$work/run.json" \
    > "$work/load.log" 2>&1 &
load_pid=$!
proxy_pid=""
for _ in $(seq 1 100); do
    proxy_pid="$(pgrep -P "$load_pid" | head -1 || true)"
    [ -n "$proxy_pid" ] && break
    sleep 0.1
done
[ -n "$proxy_pid" ] || { echo "the proxy did not start" >&2; cat "$work/load.log" >&2; exit 1; }
# Keep the snapshot with the most CPU: threads vanish one by one while the proxy stops.
best=0
while kill -0 "$proxy_pid" 2>/dev/null; do
    snapshot="$(for t in /proc/"$proxy_pid"/task/*; do
        printf '%s|%s\n' "$(cat "$t/comm" 2>/dev/null)" "$(cut -d' ' -f14,15 "$t/stat" 2>/dev/null)"
    done)"
    total="$(awk -F'|' '{split($2, a, " "); t += a[1] + a[2]} END {print t + 0}' <<< "$snapshot")"
    if [ "$total" -ge "$best" ]; then
        best="$total"
        printf '%s\n' "$snapshot" > "$work/threads"
        cat /proc/"$proxy_pid"/io > "$work/io" 2>/dev/null || true
    fi
    sleep 0.5
done
wait "$load_pid" || { cat "$work/load.log" >&2; exit 1; }

python3 - "$work" "$(getconf CLK_TCK)" <<'PY'
import collections, json, sys
work, ticks_per_s = sys.argv[1], int(sys.argv[2])
run = json.load(open(f"{work}/run.json"))
stored = run["samples"]["stored"]
per_thread = collections.Counter()
for line in open(f"{work}/threads"):
    name, _, ticks = line.strip().partition("|")
    if ticks:
        user, system = map(int, ticks.split())
        per_thread["connection threads" if name.startswith("tokio-rt") else name] += user + system
us = lambda t: t * 1e6 / ticks_per_s / stored
io = dict(l.split(": ") for l in open(f"{work}/io").read().splitlines() if ": " in l)
lat = run["latency_ms"]["sample_to_ack"]
print(f"stored {stored} samples, {run['throughput']['acked_per_s']:.0f}/s acknowledged, "
      f"p50 / p99 sample->Ack {lat['p50']:.1f} / {lat['p99']:.1f} ms")
for name, t in per_thread.most_common():
    print(f"  {name:<20} {us(t):6.2f} us CPU per sample")
print(f"  {'all threads':<20} {us(sum(per_thread.values())):6.2f} us CPU per sample")
print(f"written to storage: {int(io['write_bytes']) / stored:.0f} bytes per sample")
import os
held = sum(os.path.getsize(f"{work}/penmesh.db{s}") for s in ("", "-wal")
           if os.path.exists(f"{work}/penmesh.db{s}"))
print(f"database file (with its log): {held / stored:.1f} bytes per sample")
PY
