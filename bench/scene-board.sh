#!/bin/bash
# A small 3D session exported as a GLB scene, for the picture in docs/model-format.md: three
# leaves and two figure-eights drawn on the board by `penmesh draw`, each duplicated standing on
# the plane y = 260 and on the plane x = -60 (POST /v1/strokes/{id}/duplicate with a placement),
# then `penmesh export --format glb`. Usage (after `cargo build --bin penmesh --bin penmesh-proxy`
# and `npm ci --prefix bench`):
#   bash bench/scene-board.sh /tmp/scene.glb
#   node bench/render-print.mjs /tmp/scene.glb docs/figures/scene-board.png
set -euo pipefail
out=${1:?usage: bench/scene-board.sh OUT.glb}
bin=${CARGO_TARGET_DIR:-$PWD/target}/debug
dir=$(mktemp -d)
port=${PORT:-18391}
"$bin/penmesh-proxy" --port "$port" --database-url "sqlite://$dir/p.db" >"$dir/proxy.log" 2>&1 &
proxy=$!
trap 'kill $proxy 2>/dev/null; rm -rf "$dir"' EXIT
base=http://127.0.0.1:$port
for _ in $(seq 50); do curl -sf "$base/healthz" >/dev/null && break; sleep 0.2; done
created=$(curl -sf -X POST "$base/v1/sessions")
session=$(echo "$created" | python3 -c 'import json,sys; print(json.load(sys.stdin)["session"])')
token=$(echo "$created" | python3 -c 'import json,sys; print(json.load(sys.stdin)["token"])')
auth=(--server "$base" --session "$session" --token "$token")
"$bin/penmesh" draw "${auth[@]}" --synth leaf --count 3 --name Ann --json >/dev/null
"$bin/penmesh" draw "${auth[@]}" --synth figure8 --count 2 --name Bob --json >/dev/null
ids=$(curl -sf -H "authorization: Bearer $token" "$base/v1/sessions/$session/strokes" |
  python3 -c 'import json,sys; print(" ".join(s["id"] for s in json.load(sys.stdin)["strokes"]))')
key=0123456789abcdef0123456789abcdef
duplicate() {
  curl -sf -X POST -H "authorization: Bearer $token" -H "x-penmesh-key: $key" \
    -H 'content-type: application/json' -d "{\"placement\":{\"matrix\":$2}}" \
    "$base/v1/strokes/$1/duplicate" >/dev/null
}
i=0
for id in $ids; do
  duplicate "$id" "[1,0,0,0, 0,0,-1,0, 0,1,0,0, $((i * 40)),260,300,1]" # standing, facing -y
  duplicate "$id" "[0,0,1,0, 0,1,0,0, -1,0,0,0, -60,$((i * 45)),40,1]"  # standing, facing -x
  i=$((i + 1))
done
"$bin/penmesh" export "${auth[@]}" --format glb --out "$out"
