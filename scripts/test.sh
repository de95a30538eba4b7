#!/usr/bin/env bash
# The test command of the README: every test of the workspace on the embedded default (SQLite),
# then the browser tests of the page (client/web/test/*.mjs, Debian's Chromium through
# playwright-core; installed here when missing, and a failure when it cannot be had), the GLB
# of every real stroke of ../shared/data through the glTF-Validator and three.js, and through
# the page's own GLB reader against three.js's (client/web/test/glb-reader.mjs), then, when
# PENMESH_TEST_POSTGRES_URL is set, the end-to-end suite again on PostgreSQL (a fresh
# database per test; a Postgres test that cannot run fails, it never skips).
set -euo pipefail
cd "$(dirname "$0")/.."
pg_url=${PENMESH_TEST_POSTGRES_URL:-}
# The property tests (shared/tests) draw the same cases on every run, so a red run is the
# change's, never the draw's; each runs its saved regressions first. To search new cases, set
# another seed (a case found that way goes into the test's .proptest-regressions file once
# it passes, or is reported). A random draw on 2026-11-26 found a case beyond the stated
# exceptions of the smooth-turn test, reported in shared/tests/centreline.rs; this seed's
# cases all pass.
export PROPTEST_RNG_SEED=${PROPTEST_RNG_SEED:-20261126}

# The page's dependencies from its lock file (proxy/build.rs would run this too).
(cd client/web && npm ci --no-audit --no-fund)

# The native tools: the build's (a C/C++ compiler, cmake and ninja for Manifold) and the
# tests' (libclang for the Poisson feature, PrusaSlicer), said before the build.
./scripts/native-deps.sh test

# The paper's Poisson mesher (PoissonRecon, C++ through bindgen) is a cargo feature of the client
# and the lab, off by default; every build here turns it on so that its tests run and one build
# serves all the steps.
features=(--features penmesh-lab/poisson)

env -u PENMESH_TEST_POSTGRES_URL cargo test --workspace --all-targets "${features[@]}"

echo "== browser test"
chromium=${PENMESH_CHROMIUM:-/usr/bin/chromium}
if [ ! -x "$chromium" ] && command -v apt-get >/dev/null 2>&1; then
  apt-get install -y chromium || { apt-get update && apt-get install -y chromium; } ||
    echo "could not install chromium with apt-get" >&2
fi
cargo build --bin penmesh --bin penmesh-proxy --bin penmesh-lab "${features[@]}"
# Fails (never skips) when Chromium is still missing.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/browser.mjs
# The drawing tool: undo, redo, the eraser, brushes and names, with two people (issue 29).
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/drawing-tool.mjs
# A stroke whose end was lost with the connection while the next was drawn: resumed and ended.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/lost-end.mjs
# A mesh build that fails: tried again; one that keeps failing is built after a reload.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/mesh-build.mjs
# A new user's first minutes, one check per item of issue 36 (tools, the view, ink, a bad link,
# a phone, live width, names and colours, feedback, sharing).
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/first-minutes.mjs
# The mesh's width against the ink's along straight strokes (issue 36, item 6).
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/stroke-width.mjs
# The page's binary codec (client/web/src/codec.js; Node, no browser): the examples of
# docs/protocol.md executed both ways, generated messages of every variant, malformed frames.
node client/web/test/codec.mjs
# The page's connection with a stand-in WebSocket (Node): binary and text frames into one
# receive, a frame that does not decode said and dropped, moves sent binary (or JSON).
node client/web/test/connection.mjs
# What a move costs the page on the wire (issue 37: at most 200 bytes), read through CDP from
# two pages; undo and redo; both encodings read at every moment; the codec against /raw.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/move-bytes.mjs
# The page as a modelling tool (issue 37): a placed copy stays wound outward (a mirror flips
# it; Node, no browser); then two planes, the gizmo, duplicate, undo, mirror: two pages, a late
# joiner and the proxy's placements agree.
node client/web/test/placement-bake.mjs
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/model.mjs
# The Export menu (issue 39): the scene valid to the glTF-Validator and its extras to
# docs/model-format.schema.json, the STL whole, a GLB dropped on a new session imported.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/export.mjs
# The model's orientation (issue 50): an F and a standing stroke drawn on the page read the same
# in the GLB, the STL and the 3MF as on the page.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/orientation.mjs
# The camera keeps up (issue 50): a sideways orbit keeps the up axis vertical, each view (Top,
# Front, Side, 3D; keys 1-4) shows the model from its side, zoom toward the pointer.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/camera.mjs
# The user test's house from user actions only (issue 50): walls on the floor's edges, the roof
# on the walls, one manifold STL part, a second page live, undo of typed moves, repeats,
# duplicates, deletes and imports.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/house.mjs
# Solids on the page (issue 51): a square made Filled with a typed depth and a hole drawn as
# one, live and after a reload on a second page, undo and redo, an open stroke's refusal in
# words, and the STL one manifold part with the hole cut out.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/solids.mjs
# The mesh bundle the page opens a session with (PMB3): each mesh once, a stroke's duplicates
# sharing it, every stroke at its placement and as its solid from the bundle alone.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/bundle.mjs
# The work plane at the model (the Plane tool, Front through the selection, a typed offset,
# [ and ] by the camera), the eraser on any plane, arrow nudges, the people list's colours.
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/workplane.mjs

echo "== GLB files of the real strokes: glTF-Validator and three.js (docs/performance.md, issue 26)"
glbs=$(mktemp -d)
"${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh-lab" eval ../shared/data --glb-sizes --glb-out "$glbs" >/dev/null
node client/web/test/glb-check.mjs "$glbs"
echo "== the page's GLB reader (client/web/src/glb.js) against GLTFLoader"
PENMESH_BIN="${CARGO_TARGET_DIR:-$PWD/target}/debug/penmesh" node client/web/test/glb-reader.mjs "$glbs"
rm -rf "$glbs"

if [ -n "$pg_url" ]; then
  echo "== end-to-end suite on PostgreSQL"
  PENMESH_TEST_POSTGRES_URL=$pg_url cargo test -p penmesh-e2e --all-targets \
    --features penmesh-client/poisson
  # Each test made its own database; drop them so runs do not pile up.
  if command -v psql >/dev/null 2>&1; then
    psql "$pg_url" -Atc "select datname from pg_database where datname like 'penmesh\_%'" 2>/dev/null |
      while read -r db; do psql "$pg_url" -qc "drop database if exists \"$db\"" >/dev/null 2>&1 || true; done
  fi
fi
