#!/usr/bin/env bash
# The tools the print needs (print/, issue 39), installed with apt-get when missing:
# cmake and ninja build Manifold's C++ source, which the `manifold-rs` crate vendors (no
# download), and PrusaSlicer's command line checks the exported STL and 3MF
# (print/tests/prusa_slicer.rs). A tool that is still missing fails the build or the test.
set -euo pipefail
missing=()
for tool in cmake:cmake ninja:ninja-build g++:g++ prusa-slicer:prusa-slicer; do
  command -v "${tool%%:*}" >/dev/null 2>&1 || missing+=("${tool#*:}")
done
if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null 2>&1; then
  apt-get install -y --no-install-recommends "${missing[@]}" ||
    { apt-get update && apt-get install -y --no-install-recommends "${missing[@]}"; } ||
    echo "could not install ${missing[*]} with apt-get" >&2
fi
