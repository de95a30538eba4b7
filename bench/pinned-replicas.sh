#!/usr/bin/env bash
# The pinned setting of issue 13 on PostgreSQL: REPLICAS proxies (`penmesh-lab serve-proxy`) on one
# fresh database, the replicas AND the PostgreSQL server on core 0, one `penmesh-lab load --url`
# per replica on core 1, the pens split evenly. Records each load tool's JSON as
# OUT_DIR/pinned-postgres-rREPLICAS-PENS-I.json and the combined figures (acknowledged samples/s,
# worst p99, lost, CPU per acknowledged sample of the replicas and of PostgreSQL) as
# OUT_DIR/pinned-postgres-rREPLICAS-PENS.json, and prints them.
# Usage: bench/pinned-replicas.sh OUT_DIR SECONDS PENS REPLICAS [-- PROXY_ARG...]
#   PENMESH_PG: the server's URL without a database (default postgres://postgres@127.0.0.1:5432);
#   PENMESH_PG_QUERY: appended to the replicas' database URL, e.g. "?sslmode=disable".
# PostgreSQL's processes are moved to core 0 for the run and back to every core after it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
usage="usage: bench/pinned-replicas.sh OUT_DIR SECONDS PENS REPLICAS [-- PROXY_ARG...]"
out="${1:?$usage}" seconds="${2:?$usage}" pens="${3:?$usage}" replicas="${4:?$usage}"
shift 4
[ "${1:-}" = "--" ] && shift
pg="${PENMESH_PG:-postgres://postgres@127.0.0.1:5432}"

# shellcheck source=bench/pinned-common.sh
. "$here/pinned-common.sh"
penmesh="$(penmesh_binary)"
mkdir -p "$out"
work="$(mktemp -d)"
db="penmesh_bench_$$"
pids=()
cleanup() {
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    wait 2>/dev/null || true
    for pid in $(pgrep -x postgres); do taskset -a -p -c "0-$(($(nproc) - 1))" "$pid" >/dev/null 2>&1 || true; done
    psql "$pg/postgres" -qc "DROP DATABASE IF EXISTS $db" >/dev/null 2>&1 || true
    rm -rf "$work"
}
trap cleanup EXIT
psql "$pg/postgres" -qc "CREATE DATABASE $db" >/dev/null
for pid in $(pgrep -x postgres); do taskset -a -p -c 0 "$pid" >/dev/null; done

# PostgreSQL's CPU ticks: its live processes plus what its postmaster reaped (ended backends).
pg_ticks() {
    local postmaster live=0 reaped
    postmaster="$(pgrep -o -x postgres)"
    for pid in $(pgrep -x postgres); do
        live=$((live + $(cut -d' ' -f14,15 "/proc/$pid/stat" 2>/dev/null | tr ' ' '+' || echo 0)))
    done
    reaped=$(($(cut -d' ' -f16,17 "/proc/$postmaster/stat" | tr ' ' '+')))
    echo $((live + reaped))
}

pg_before="$(pg_ticks)"
ports=()
for i in $(seq 1 "$replicas"); do
    port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
    RUST_LOG=warn taskset -c 0 "$penmesh" serve-proxy --host 127.0.0.1 --port "$port" \
        --database-url "$pg/$db${PENMESH_PG_QUERY:-}" --max-connections-per-session 64 --session-rate-per-minute 0 \
        --max-connections 10000 --max-connections-per-address 0 --idle-timeout-secs 600 "$@" > "$work/replica-$i.log" 2>&1 &
    pids+=($!)
    ports+=("$port")
done
for port in "${ports[@]}"; do
    for _ in $(seq 1 200); do
        curl -fs "http://127.0.0.1:$port/healthz" >/dev/null 2>&1 && break
        sleep 0.1
    done
done
loads=()
for i in $(seq 1 "$replicas"); do
    share=$((pens / replicas + (i <= pens % replicas ? 1 : 0)))
    taskset -c 1 "$penmesh" load --url "http://127.0.0.1:${ports[$((i - 1))]}" \
        --proxy-pid "${pids[$((i - 1))]}" --clients "$share" --rate 200 --batch-ms 12 \
        --duration "$seconds" --ramp 10 --label "pinned-postgres-r$replicas-$pens-$i" \
        --json "$out/pinned-postgres-r$replicas-$pens-$i.json" > "$work/load-$i.log" 2>&1 &
    loads+=($!)
done
for pid in "${loads[@]}"; do wait "$pid" || echo "(a load tool reported a failure; see its JSON)" >&2; done
for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null || true; done
for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
pids=()
pg_after="$(pg_ticks)"

python3 - "$out" "$replicas" "$pens" "$seconds" "$((pg_after - pg_before))" "$(getconf CLK_TCK)" <<'PY'
import json, sys
out, replicas, pens, seconds, pg_ticks, hz = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6])
runs = [json.load(open(f"{out}/pinned-postgres-r{replicas}-{pens}-{i}.json")) for i in range(1, replicas + 1)]
acked = sum(r["throughput"]["acked_per_s"] for r in runs)
stored = sum(r["samples"]["stored"] or 0 for r in runs)
proxy_cpu = sum(r["server"]["cpu_percent"] for r in runs)
summary = {
    "replicas": replicas, "pens": pens, "seconds": seconds,
    "acked_per_s": acked,
    "p99_sample_to_ack_ms": max(r["latency_ms"]["sample_to_ack"]["p99"] for r in runs),
    "p99_pen_up_to_stroke_done_ms": max(r["latency_ms"]["pen_up_to_stroke_done"]["p99"] for r in runs),
    "lost": sum(r["samples"]["lost"] for r in runs),
    "sent": sum(r["samples"]["sent"] for r in runs),
    "stored": stored,
    # The replicas over the steady window, per sample acknowledged in it.
    "proxy_cpu_percent": proxy_cpu,
    "proxy_cpu_us_per_acked_sample": proxy_cpu / 100 * 1e6 / max(acked, 1e-9),
    # PostgreSQL over the whole run (ramp and drain included), per stored sample.
    "postgres_cpu_seconds": pg_ticks / hz,
    "postgres_cpu_us_per_stored_sample": pg_ticks / hz * 1e6 / max(stored, 1),
}
json.dump(summary, open(f"{out}/pinned-postgres-r{replicas}-{pens}.json", "w"), indent=2)
print(f"postgres, {replicas} replica(s), {pens} pens: acked {acked:8.0f}/s, p99 ack "
      f"{summary['p99_sample_to_ack_ms']:8.1f} ms, done {summary['p99_pen_up_to_stroke_done_ms']:8.1f} ms, "
      f"lost {summary['lost']}, replicas {proxy_cpu:.0f} % = {summary['proxy_cpu_us_per_acked_sample']:.2f} us/sample, "
      f"PostgreSQL {summary['postgres_cpu_seconds']:.1f} CPU s = {summary['postgres_cpu_us_per_stored_sample']:.2f} us/stored sample")
PY
