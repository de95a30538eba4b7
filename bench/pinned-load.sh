#!/usr/bin/env bash
# The pinned setting of issue 13: the server (the proxy or the no-op ceiling) on core 0, the load
# tool on core 1, 200 Hz pens, 12 ms batches. For each pen count, runs the ceiling then the proxy
# and records `penmesh-lab load`'s JSON as OUT_DIR/pinned-{ceiling,proxy}-PENS.json, with what this
# script reads from /proc added under "pinned": the server's bytes written to storage
# (/proc/PID/io write_bytes), its CPU by thread, and the database file's size after the run.
# Then prints one line per run: throughput, p99, CPU per acknowledged sample, bytes per sample.
# Usage: bench/pinned-load.sh OUT_DIR SECONDS PENS... [-- PROXY_ARG...]
#   e.g. bench/pinned-load.sh docs/load 30 500 1000 1500
#   PENMESH_TARGETS="proxy" (default "ceiling proxy") runs only some targets;
#   PENMESH_CEILING_ARGS="--answer-task" passes settings to the ceiling (space-separated);
#   PENMESH_DATABASE_URL=postgres://... runs the proxy on PostgreSQL (a fresh database each run
#   is the caller's business; the database server is then not pinned and not counted);
#   PENMESH_STALL_AT=S stops the server with SIGSTOP S seconds after the pens start, for
#   PENMESH_STALL_SECONDS (default 2), and says how long after it every second's p99
#   sample→Ack was back under 50 ms (issue 53's recovery goal);
#   --stage-timing after -- makes the proxy count its stages: the JSON then has "stages", and
#   the script prints them (docs/performance.md, "Where a sample's CPU goes").
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
out="${1:?usage: bench/pinned-load.sh OUT_DIR SECONDS PENS... [-- PROXY_ARG...]}"
seconds="${2:?seconds}"
shift 2
pens=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do pens+=("$1"); shift; done
[ "${1:-}" = "--" ] && shift
proxy_args=()
for arg in "$@"; do proxy_args+=("--proxy-arg=$arg"); done
targets="${PENMESH_TARGETS:-ceiling proxy}"

# shellcheck source=bench/pinned-common.sh
. "$here/pinned-common.sh"
penmesh="$(penmesh_binary)"
mkdir -p "$out"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

run_one() { # TARGET PENS
    local target="$1" n="$2" db_args=()
    rm -f "$work"/penmesh.db*
    if [ "$target" = proxy ]; then
        db_args=(--database-url "${PENMESH_DATABASE_URL:-sqlite://$work/penmesh.db}" "${proxy_args[@]}")
    else
        for arg in ${PENMESH_CEILING_ARGS:-}; do db_args+=("--ceiling-arg=$arg"); done
    fi
    # The load tool on core 1, the server it spawns on core 0.
    taskset -c 1 "$penmesh" load "--spawn-$target" "${db_args[@]}" --clients "$n" --rate 200 \
        --batch-ms 12 --duration "$seconds" --ramp 10 --label "pinned-$target-$n" \
        --json "$work/run.json" > "$work/load.log" 2>&1 &
    local load_pid=$! pid
    pid="$(pin_spawned_server "$load_pid")" || { cat "$work/load.log" >&2; return 1; }
    if [ -n "${PENMESH_STALL_AT:-}" ]; then
        # The pens start about 0.2 s after the load tool has made its sessions, which is at
        # most a second after the server is up: the stall lands within a second of S.
        (sleep "$PENMESH_STALL_AT"; kill -STOP "$pid"; sleep "${PENMESH_STALL_SECONDS:-2}"
         kill -CONT "$pid") &
    fi
    # Keep the snapshot with the most CPU: threads vanish one by one while the server stops.
    local best=0 snapshot total
    : > "$work/io"
    while kill -0 "$pid" 2>/dev/null; do
        snapshot="$(for t in /proc/"$pid"/task/*; do
            printf '%s|%s\n' "$(cat "$t/comm" 2>/dev/null)" "$(cut -d' ' -f14,15 "$t/stat" 2>/dev/null)"
        done)"
        total="$(awk -F'|' '{split($2, a, " "); t += a[1] + a[2]} END {print t + 0}' <<< "$snapshot")"
        if [ "$total" -ge "$best" ]; then
            best="$total"
            printf '%s\n' "$snapshot" > "$work/threads"
            cat /proc/"$pid"/io > "$work/io" 2>/dev/null || true
        fi
        sleep 0.5
    done
    wait "$load_pid" || echo "(the load tool reported a failure; see the JSON)" >&2
    [ -f "$work/run.json" ] || { cat "$work/load.log" >&2; return 1; }
    python3 - "$work" "$(getconf CLK_TCK)" "$out/pinned-$target-$n.json" "${PENMESH_STALL_AT:-}" <<'PY'
import collections, json, os, sys
work, ticks_per_s, dest, stall_at = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
run = json.load(open(f"{work}/run.json"))
per_thread = collections.Counter()
for line in open(f"{work}/threads"):
    name, _, ticks = line.strip().partition("|")
    if ticks:
        user, system = map(int, ticks.split())
        per_thread["connection threads" if name.startswith("tokio-rt") else name] += user + system
io = dict(l.split(": ") for l in open(f"{work}/io").read().splitlines() if ": " in l)
held = sum(os.path.getsize(f"{work}/penmesh.db{s}") for s in ("", "-wal")
           if os.path.exists(f"{work}/penmesh.db{s}"))
stored = run["samples"]["stored"] or run["samples"]["acknowledged"]
server = run["server"]
pinned = {
    "server_cpu": "0", "load_tool_cpu": "1",
    # CPU over the steady window per sample acknowledged in it.
    "server_cpu_us_per_acked_sample": server["cpu_percent"] / 100 * 1e6 / max(run["throughput"]["acked_per_s"], 1e-9),
    "server_cpu_us_per_stored_sample_by_thread": {k: v * 1e6 / ticks_per_s / stored for k, v in per_thread.most_common()},
    "write_bytes": int(io.get("write_bytes", 0)),
    "write_bytes_per_stored_sample": int(io.get("write_bytes", 0)) / stored,
    "database_bytes": held or None,
    "database_bytes_per_stored_sample": held / stored if held else None,
}
run["pinned"] = pinned
json.dump(run, open(dest, "w"), indent=2)
lat = run["latency_ms"]
held_txt = f", file {pinned['database_bytes_per_stored_sample']:.1f} B" if held else ""
print(f"{run['label']:>22}: acked {run['throughput']['acked_per_s']:8.0f}/s, p99 ack "
      f"{lat['sample_to_ack']['p99']:8.1f} ms, done {lat['pen_up_to_stroke_done']['p99']:8.1f} ms, "
      f"lost {run['samples']['lost']}, server {server['cpu_percent']:.0f} % = "
      f"{pinned['server_cpu_us_per_acked_sample']:.2f} us/sample, written "
      f"{pinned['write_bytes_per_stored_sample']:.1f} B/sample{held_txt}")
stages = run.get("stages")
if stages:
    rows = stages["stages"] + stages["threads"]
    print("  per sample: " + ", ".join(f"{r['name']} {r['us_per_sample']:.2f} us" for r in rows))
if stall_at:
    # A second's p99 is under 50 ms when under 1 % of its samples were slow (>= 50 ms).
    seconds = run["latency_ms"]["sample_to_ack_by_second"]
    bad = [s["second"] for s in seconds if s["acked"] and s["slow"] / s["acked"] >= 0.01
           and s["second"] < run["settings"]["duration_s"]]
    after = [b for b in bad if b >= int(stall_at)]
    last_bad = max(after) if after else None
    run["stall"] = {"at_s": int(stall_at), "last_second_p99_over_50ms": last_bad,
                    "seconds_over_50ms": bad}
    json.dump(run, open(dest, "w"), indent=2)
    print(f"  stall at {stall_at} s: seconds with p99 >= 50 ms: {bad}; "
          f"back under 50 ms from second {last_bad + 1 if last_bad is not None else int(stall_at)}")
PY
}

echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
for n in "${pens[@]}"; do
    for target in $targets; do
        run_one "$target" "$n"
    done
done
