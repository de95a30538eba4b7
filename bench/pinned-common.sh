# Sourced by the pinned benches (pinned-load.sh, pinned-replicas.sh, wal-pages.sh): what they
# share. Expects `root` (the checkout) to be set.

# The lab's binary (load, serve-proxy, ceiling): $PENMESH_LAB_BIN, or this checkout's build in
# the cargo profile $PENMESH_PROFILE (built if needed): `release` by default (stripped), or
# `profiling` (the release build with line tables and symbols) for `perf record`.
penmesh_binary() {
    if [ -n "${PENMESH_LAB_BIN:-}" ]; then
        echo "$PENMESH_LAB_BIN"
        return
    fi
    local profile=${PENMESH_PROFILE:-release}
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
    cargo build --profile "$profile" --quiet --manifest-path "$root/Cargo.toml" \
        -p penmesh-lab --bin penmesh-lab
    echo "$CARGO_TARGET_DIR/$profile/penmesh-lab"
}

# Moves the server that `penmesh-lab load --spawn-…` (pid $1, started on core 1) spawned to core 0,
# every thread (-a), as soon as it exists: threads it starts later inherit core 0 from their
# parent. Prints the server's pid; fails when it did not start within 10 s.
pin_spawned_server() {
    local load_pid="$1" pid=""
    for _ in $(seq 1 200); do
        pid="$(pgrep -P "$load_pid" | head -1 || true)"
        [ -n "$pid" ] && break
        sleep 0.05
    done
    [ -n "$pid" ] || { echo "the server did not start" >&2; return 1; }
    taskset -a -p -c 0 "$pid" > /dev/null
    echo "$pid"
}
