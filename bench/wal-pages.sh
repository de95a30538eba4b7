#!/usr/bin/env bash
# Which tables the SQLite write-ahead log's frames belong to, under `penmesh-lab load`: runs the
# proxy (pinned as in bench/pinned-load.sh) for 20 s, records the frame headers it writes for 4 s
# of the steady load (strace on pwrite64: each frame's 24-byte header starts with its page
# number and, on a commit's last frame, the database size), then maps each page to the table
# or index that owns it in the database file after the run. Prints frames per commit by owner.
# Usage: bench/wal-pages.sh PENS [-- PROXY_ARG...]   (needs strace and python3)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
n="${1:?usage: bench/wal-pages.sh PENS [-- PROXY_ARG...]}"
shift
[ "${1:-}" = "--" ] && shift
proxy_args=()
for arg in "$@"; do proxy_args+=("--proxy-arg=$arg"); done
# shellcheck source=bench/pinned-common.sh
. "$here/pinned-common.sh"
penmesh="$(penmesh_binary)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
taskset -c 1 "$penmesh" load --spawn-proxy --database-url "sqlite://$work/p.db" "${proxy_args[@]}" \
    --clients "$n" --rate 200 --batch-ms 12 --duration 20 --ramp 6 --json "$work/run.json" \
    > "$work/load.log" 2>&1 &
load_pid=$!
pid="$(pin_spawned_server "$load_pid")"
sleep 9
timeout 4 strace -f -q -e trace=pwrite64 -s 8 -x -e signal=none -p "$pid" -o "$work/strace" 2>/dev/null || true
wait "$load_pid" || true
python3 - "$work" <<'PY'
import collections, re, sqlite3, struct, sys
work = sys.argv[1]
db = open(f"{work}/p.db", "rb").read()
size = struct.unpack(">H", db[16:18])[0]
size = 65536 if size == 1 else size
page = lambda n: db[(n - 1) * size:n * size]
owner = {}

def varint(b, i):
    v = 0
    for k in range(9):
        c = b[i + k]
        if k == 8:
            return (v << 8) | c, i + 9
        v = (v << 7) | (c & 0x7F)
        if c < 0x80:
            return v, i + k + 1

def walk(n, name):
    """Marks page n and every page below it (children, overflow chains) as name's."""
    if n == 0 or n in owner or (n - 1) * size >= len(db):
        return
    owner[n] = name
    p = page(n)
    off = 100 if n == 1 else 0
    kind = p[off]
    ncell = struct.unpack(">H", p[off + 3:off + 5])[0]
    header = 12 if kind in (2, 5) else 8
    cells = [struct.unpack(">H", p[off + header + 2 * i:off + header + 2 * i + 2])[0] for i in range(ncell)]
    if kind in (2, 5):
        walk(struct.unpack(">I", p[off + 8:off + 12])[0], name)
        for c in cells:
            walk(struct.unpack(">I", p[c:c + 4])[0], name)
    if kind in (13, 10, 2):  # cells that may spill into overflow pages
        for c in cells:
            i = c + (4 if kind == 2 else 0)
            length, i = varint(p, i)
            if kind == 13:
                _, i = varint(p, i)
            most = size - 35 if kind == 13 else (size - 12) * 64 // 255 - 23
            if length > most:
                least = (size - 12) * 32 // 255 - 23
                local = least + (length - least) % (size - 4)
                local = local if local <= most else least
                ov = struct.unpack(">I", p[i + local:i + local + 4])[0]
                while ov and ov not in owner and (ov - 1) * size < len(db):
                    owner[ov] = name
                    ov = struct.unpack(">I", page(ov)[0:4])[0]

for name, root in sqlite3.connect(f"{work}/p.db").execute(
        "SELECT name, rootpage FROM sqlite_schema WHERE rootpage > 0"):
    walk(root, name)
owner.setdefault(1, "page 1 (database header + schema)")
by_owner, frames, commits = collections.Counter(), 0, 0
for line in open(f"{work}/strace"):
    m = re.search(r'pwrite64\(\d+, "((?:\\x[0-9a-f]{2}){8})"\.*, 24,', line)
    if not m:
        continue
    number, commit = struct.unpack(">II", bytes(int(h, 16) for h in re.findall(r"\\x([0-9a-f]{2})", m.group(1))))
    frames += 1
    commits += commit > 0
    by_owner[owner.get(number, "freed since (mostly the log's)")] += 1
print(f"{frames} frames of {size} bytes in {commits} commits: {frames / max(commits, 1):.2f} per commit")
for name, count in by_owner.most_common():
    print(f"  {name:40s} {count:6d}  {count / max(commits, 1):.2f} per commit")
PY
