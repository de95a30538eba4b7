#!/usr/bin/env bash
# A join storm as people make it (issue 25): N native clients (`penmesh draw --input`, each
# replaying one real recording of ../shared/data) join one session of the default proxy
# (SQLite) at the same moment, round after round. Prints, per round, the clients that
# failed, the strokes stored, done and with a mesh, and the 5xx answers the proxy counted.
#
#   bench/join-storm.sh [CLIENTS=30] [ROUNDS=5]
#
# Release binaries of this checkout (built if needed); the proxy's database is a temporary file.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
clients="${1:-30}"
rounds="${2:-5}"
data="$root/../shared/data"

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
cargo build --release --quiet --manifest-path "$root/Cargo.toml" \
    -p penmesh-proxy --bin penmesh-proxy -p penmesh-client --bin penmesh
bin="$CARGO_TARGET_DIR/release"

work="$(mktemp -d)"
trap 'kill "$proxy_pid" 2>/dev/null || true; rm -rf "$work"' EXIT
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
"$bin/penmesh-proxy" --host 127.0.0.1 --port "$port" --database-url "sqlite://$work/storm.db" \
    > "$work/proxy.log" 2>&1 &
proxy_pid=$!
server="http://127.0.0.1:$port"
for _ in $(seq 1 100); do curl -sf "$server/readyz" > /dev/null && break; sleep 0.1; done

mapfile -t files < <(ls "$data"/sigcomp2011_dutch/*.hwr "$data"/svc2004/*.TXT | sort)
server_errors() {
    curl -s "$server/metrics" | awk '/^penmesh_http_errors_total/ && /code="(internal|busy|shutting_down)"/ {n += $NF} END {print n + 0}'
}

echo "round clients failed strokes done meshed 5xx seconds"
for round in $(seq 1 "$rounds"); do
    created="$(curl -sf -X POST "$server/v1/sessions")"
    session="$(echo "$created" | python3 -c 'import json,sys; print(json.load(sys.stdin)["session"])')"
    token="$(echo "$created" | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')"
    errors_before="$(server_errors)"
    started="$(date +%s.%N)"
    pids=()
    for i in $(seq 0 $((clients - 1))); do
        file="${files[$(( (round * clients + i) % ${#files[@]} ))]}"
        "$bin/penmesh" draw --server "$server" --session "$session" --token "$token" \
            --name "person-$i" --input "$file" --json > "$work/client-$round-$i.json" 2> "$work/client-$round-$i.err" &
        pids+=("$!")
    done
    failed=0
    for pid in "${pids[@]}"; do wait "$pid" || failed=$((failed + 1)); done
    seconds="$(python3 -c "print(round($(date +%s.%N) - $started, 1))")"
    counts="$(curl -sf -H "authorization: Bearer $token" "$server/v1/sessions/$session/strokes" |
        python3 -c 'import json,sys; s=json.load(sys.stdin)["strokes"]; print(len(s), sum(x["status"]=="done" for x in s), sum(bool(x["has_mesh"]) for x in s))')"
    echo "$round $clients $failed $counts $(( $(server_errors) - errors_before )) $seconds"
    if [ "$failed" -gt 0 ]; then
        cat "$work"/client-"$round"-*.err | sort | uniq -c | sort -rn | head -5 >&2
    fi
done
