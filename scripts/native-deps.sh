#!/usr/bin/env bash
# The native build tools the workspace needs beyond Rust: the client's screened Poisson mesher
# is Kazhdan's PoissonRecon (C++), which the `poissonrecon` crate compiles with the system's C++
# compiler and binds with bindgen, which loads libclang. Installed with apt-get when missing
# (as scripts/test.sh installs Chromium), a clear failure when they cannot be had. Sourced or
# run by .ci/run and scripts/test.sh before the first cargo build; the proxy alone (its
# Dockerfile) links none of it and needs neither.
set -euo pipefail
have_libclang() {
  ldconfig -p 2>/dev/null | grep -q 'libclang[-.0-9]*\.so' ||
    compgen -G '/usr/lib/llvm-*/lib/libclang*.so*' >/dev/null
}
if ! have_libclang || ! command -v c++ >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1; then
    apt-get install -y libclang-dev g++ || { apt-get update && apt-get install -y libclang-dev g++; } ||
      echo "could not install libclang-dev and g++ with apt-get" >&2
  fi
fi
if ! have_libclang; then
  echo "libclang is missing: install libclang-dev (bindgen needs it to build the poissonrecon crate)" >&2
  exit 1
fi
command -v c++ >/dev/null 2>&1 || { echo "no C++ compiler (c++): install g++" >&2; exit 1; }
