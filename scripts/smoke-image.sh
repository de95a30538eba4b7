#!/usr/bin/env bash
# The container smoke test without a container engine: runs the release binary the way
# deploy/Dockerfile runs it, read from the Dockerfile itself (the COPY of the binary, USER,
# WORKDIR, ENV, ENTRYPOINT, STOPSIGNAL): as an unprivileged user, in an empty working directory
# standing for /data, with only the image's environment. Then: /readyz answers 200, one stroke
# is drawn through it with the client, SIGTERM stops it with exit status 0 within the shutdown
# grace, and a second start finds the stroke stored.
#
# The root file system is read-only except /data, as in the Kubernetes manifests. The
# differences from the real image, on purpose: the user is `nobody` (not 10001, which has no
# entry here), the host's libraries and file system instead of bookworm-slim's, /data is a
# temporary folder, and PORT is a free port set as a platform sets it (8080 may be taken).
#
# Usage: scripts/smoke-image.sh [DATABASE_URL]  (default: the image's own, SQLite under /data).
# Needs root (a mount namespace, then nobody), curl and jq; builds the release binaries.
set -euo pipefail
cd "$(dirname "$0")/.."
dockerfile=deploy/Dockerfile
database_override=${1:-}

fail() { echo "smoke-image: FAIL: $*" >&2; exit 1; }
[ "$(id -u)" = 0 ] || fail "needs root, to run the proxy as the unprivileged user nobody"

# The final stage of the Dockerfile, continuation lines joined.
final_stage=$(awk '/^FROM /{stage=""} {stage=stage $0 "\n"} END{printf "%s", stage}' "$dockerfile" |
  sed -e ':a' -e '/\\$/N; s/\\\n//; ta')
instruction() { grep -E "^$1 " <<<"$final_stage" | tail -n 1 | sed -E "s/^$1 +//"; }

entrypoint=$(instruction ENTRYPOINT | jq -r '.[0]') || fail "ENTRYPOINT is not an exec-form list"
[ "$(instruction ENTRYPOINT | jq length)" = 1 ] || fail "ENTRYPOINT has arguments this test does not pass"
workdir=$(instruction WORKDIR)
stop_signal=$(instruction STOPSIGNAL)
[ "$stop_signal" = SIGTERM ] || fail "STOPSIGNAL is '$stop_signal', the proxy stops gracefully on SIGTERM"
# The binary the image copies in, from the build stage's /src (the repository root).
copy=$(grep -E "^COPY --from=build .* $entrypoint\$" <<<"$final_stage") ||
  fail "no COPY --from=build puts a file at the ENTRYPOINT $entrypoint"
source_path=$(awk '{print $3}' <<<"$copy")
built=${source_path#/src/}
[ "$built" != "$source_path" ] || fail "the image copies $source_path, outside the build stage's /src"
binary_name=$(basename "$built")

# What the image's build stage runs (a no-op when target/release is current).
cargo build --release --locked -p penmesh-proxy -p penmesh-client
[ -x "$built" ] || fail "the Dockerfile copies $source_path, but the build makes no $built"

# The root of the pretend container: the binary where the image has it, and the data folder.
root=$(mktemp -d /tmp/penmesh-smoke.XXXXXX)
proxy_pid=
cleanup() {
  if [ -n "$proxy_pid" ]; then kill -KILL "$proxy_pid" 2>/dev/null || true; fi
  rm -rf "$root"
}
trap cleanup EXIT
chmod 755 "$root"
install -D -m 755 "$built" "$root/bin/$binary_name"
data="$root$workdir"
mkdir -p "$data"
chown nobody: "$data"
chmod 700 "$data"

port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# The image's environment, with its paths under the pretend root.
image_env=()
while read -r pair; do
  [ -n "$pair" ] || continue
  image_env+=("${pair//$workdir/$data}")
done < <(instruction ENV | tr ' ' '\n')
image_env+=(
  "PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
  "HOME=$data"
  "PORT=$port"
)
if [ -n "$database_override" ]; then image_env+=("PENMESH_DATABASE_URL=$database_override"); fi
grace=$(printf '%s\n' "${image_env[@]}" | sed -n 's/^PENMESH_SHUTDOWN_GRACE_SECS=//p' | tail -n 1)
grace=${grace:-10}

# Every PENMESH_* name the deploy files use is a setting the binary knows.
known=$("$built" --help)
for name in $(grep -ohE 'PENMESH_[A-Z_]+' deploy/Dockerfile deploy/compose.yaml deploy/k8s/*.yaml deploy/knative/*.yaml | sort -u); do
  grep -q "\[env: $name=" <<<"$known" || fail "deploy/ sets $name, which penmesh-proxy does not know"
done

# As the Kubernetes manifests run it: the root file system read-only, only /data writable
# (a mount namespace of its own: / and the usual scratch folders remounted read-only).
read_only_root='data=$1; shift
mount --bind "$data" "$data" && mount -o remount,bind,ro / || exit 1
for dir in /tmp /var/tmp /dev/shm /run; do
  if mountpoint -q "$dir"; then mount -o remount,bind,ro "$dir" || exit 1; fi
done
exec "$@"'

log="$root/proxy.log"
start_proxy() {
  (cd "$data" && exec unshare --mount sh -c "$read_only_root" read-only-root "$data" \
    env -i "${image_env[@]}" /usr/bin/setpriv --reuid=nobody --regid=nogroup \
    --clear-groups --no-new-privs "$root/bin/$binary_name") >>"$log" 2>&1 &
  proxy_pid=$!
  local until=$((SECONDS + 15))
  until curl -fsS -o /dev/null "http://127.0.0.1:$port/readyz" 2>/dev/null; do
    if ! kill -0 "$proxy_pid" 2>/dev/null; then
      cat "$log" >&2
      fail "the binary exited when started as the image starts it"
    fi
    [ $SECONDS -lt $until ] || { cat "$log" >&2; fail "/readyz never answered 200"; }
    sleep 0.1
  done
}

stop_proxy() {
  local started=$SECONDS status=0
  kill -TERM "$proxy_pid"
  local until=$((SECONDS + grace + 1))
  while kill -0 "$proxy_pid" 2>/dev/null; do
    [ $SECONDS -lt $until ] || { cat "$log" >&2; fail "still running ${grace}s after SIGTERM"; }
    sleep 0.1
  done
  wait "$proxy_pid" || status=$?
  proxy_pid=
  [ "$status" = 0 ] || { cat "$log" >&2; fail "exit status $status after SIGTERM"; }
  echo "smoke-image: stopped on SIGTERM with status 0 in $((SECONDS - started)) s (grace ${grace} s)"
}

start_proxy
echo "smoke-image: $binary_name ready as nobody in an empty $workdir, with the image's environment"
base="http://127.0.0.1:$port"
created=$(curl -fsS -X POST "$base/v1/sessions")
session=$(jq -r .session <<<"$created")
token=$(jq -r .token <<<"$created")
drawn=$(target/release/penmesh draw --server "$base" --session "$session" --token "$token" \
  --synth leaf --json) || fail "drawing one stroke through the proxy failed"
stroke=$(jq -r '.strokes[0].stroke' <<<"$drawn")
n_resampled=$(jq -r '.strokes[0].n_resampled' <<<"$drawn")
stop_proxy

# Stopped the moment it is ready (a platform may do that): still a clean stop.
start_proxy
stop_proxy

# A new start on the same data: the stroke is there, whole.
start_proxy
listed=$(curl -fsS -H "authorization: Bearer $token" "$base/v1/sessions/$session/strokes")
stop_proxy
jq -e --arg id "$stroke" --argjson n "$n_resampled" \
  '.strokes | length == 1 and .[0].id == $id and .[0].status == "done" and .[0].n_points == $n' \
  <<<"$listed" >/dev/null || fail "the stroke is not stored as drawn: drew $drawn; stored $listed"
echo "smoke-image: ok: one stroke of $n_resampled samples drawn, stopped, and found stored after a restart"
