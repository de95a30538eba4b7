#!/usr/bin/env bash
# The README's first command: `./scripts/lab.sh demo` (any penmesh-lab arguments work) builds
# the lab in release and runs it, after installing with apt-get what a fresh machine with only
# Rust and Node lacks for that build (scripts/native-deps.sh build: a C/C++ compiler, cmake and
# ninja for the print's Manifold, CA certificates), said before the build starts. The lab's
# default features need no libclang (the Poisson mesher is the feature `poisson`).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/native-deps.sh build
exec cargo run --release --bin penmesh-lab -- "$@"
