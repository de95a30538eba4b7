#!/usr/bin/env bash
# The native tools the workspace needs beyond Rust and Node, installed with apt-get when missing
# (as scripts/test.sh installs Chromium), and a clear failure when they cannot be had:
# - libclang and a C++ compiler: the client's screened Poisson mesher is Kazhdan's PoissonRecon
#   (C++), which the `poissonrecon` crate compiles and binds with bindgen (which loads libclang);
# - cmake and ninja: the print (print/, issue 39) unites solids with Manifold, whose C++ source
#   the `manifold-rs` crate vendors (no download) and builds with them;
# - PrusaSlicer's command line, which checks the exported STL and 3MF (print/tests/prusa_slicer.rs).
# Run by .ci/run and scripts/test.sh before the first cargo build. The proxy's image builds
# Manifold too (deploy/Dockerfile installs cmake and ninja itself) but not PoissonRecon.
set -euo pipefail
# libclang itself, not libclang-cpp (which other packages bring and bindgen cannot load).
have_libclang() {
  ldconfig -p 2>/dev/null | grep -q 'libclang[-.0-9]*\.so' ||
    compgen -G '/usr/lib/llvm-*/lib/libclang.so*' >/dev/null ||
    compgen -G '/usr/lib/llvm-*/lib/libclang-[0-9]*.so*' >/dev/null
}
missing=()
have_libclang || missing+=(libclang-dev)
for tool in c++:g++ cmake:cmake ninja:ninja-build prusa-slicer:prusa-slicer; do
  command -v "${tool%%:*}" >/dev/null 2>&1 || missing+=("${tool#*:}")
done
if [ ${#missing[@]} -gt 0 ] && command -v apt-get >/dev/null 2>&1; then
  apt-get install -y --no-install-recommends "${missing[@]}" ||
    { apt-get update && apt-get install -y --no-install-recommends "${missing[@]}"; } ||
    echo "could not install ${missing[*]} with apt-get" >&2
fi
have_libclang || { echo "libclang is missing: install libclang-dev (bindgen needs it for the poissonrecon crate)" >&2; exit 1; }
for tool in c++ cmake ninja prusa-slicer; do
  command -v "$tool" >/dev/null 2>&1 || { echo "$tool is missing: scripts/native-deps.sh could not install it" >&2; exit 1; }
done
