#!/usr/bin/env bash
# The native tools the workspace needs beyond Rust and Node, installed with apt-get when missing
# (as scripts/test.sh installs Chromium), announced before anything is installed or built, and a
# clear failure when they cannot be had.
#
#   scripts/native-deps.sh build   what a release build of the binaries needs (scripts/lab.sh,
#                                  the README's first command, runs this):
#     - a C and C++ compiler: cargo links with `cc`, and build scripts compile C (ring, SQLite)
#       and C++ (the print's Manifold, through `cxx`);
#     - cmake and ninja: the print (print/) unites solids with Manifold, whose C++ source the
#       `manifold-rs` crate vendors (no download) and builds with them;
#     - CA certificates: cargo downloads the crates over HTTPS.
#   scripts/native-deps.sh test    the above, and what the test command adds (scripts/test.sh and
#                                  .ci/run run this):
#     - libclang: the client's and the lab's cargo feature `poisson` (Kazhdan's PoissonRecon, C++,
#       which the `poissonrecon` crate binds with bindgen, which loads libclang);
#     - PrusaSlicer's command line, which checks the exported STL and 3MF (print/tests).
#   scripts/native-deps.sh --list build|test   prints the Debian packages of that set, one a
#                                  line, and installs nothing (scripts/check-build-tools.sh).
#
# The image's build stage (deploy/Dockerfile) installs its own: its base image has the compilers
# and certificates; it adds cmake and ninja.
set -euo pipefail

usage() { echo "usage: $0 [--list] build|test" >&2; exit 2; }
list=false
if [ "${1:-}" = --list ]; then list=true; shift; fi
set_name=${1:-test}
case "$set_name" in build | test) ;; *) usage ;; esac

# Each tool as "command-or-test:debian-package:why".
tools=(
  "cc:gcc:cargo links with cc; build scripts compile C"
  "c++:g++:build scripts compile C++ (Manifold)"
  "cmake:cmake:manifold-rs builds Manifold with cmake"
  "ninja:ninja-build:manifold-rs builds Manifold with ninja"
  "ca-certificates:ca-certificates:cargo downloads crates over HTTPS"
)
if [ "$set_name" = test ]; then
  tools+=(
    "libclang:libclang-dev:the poisson feature's bindgen loads libclang"
    "prusa-slicer:prusa-slicer:the print's tests check STL and 3MF with PrusaSlicer"
  )
fi

if $list; then
  for tool in "${tools[@]}"; do
    rest=${tool#*:}
    echo "${rest%%:*}"
  done
  exit 0
fi

# libclang itself, not libclang-cpp (which other packages bring and bindgen cannot load).
have_libclang() {
  ldconfig -p 2>/dev/null | grep -q 'libclang[-.0-9]*\.so' ||
    compgen -G '/usr/lib/llvm-*/lib/libclang.so*' >/dev/null ||
    compgen -G '/usr/lib/llvm-*/lib/libclang-[0-9]*.so*' >/dev/null
}
have() {
  case "$1" in
    libclang) have_libclang ;;
    ca-certificates) [ -s /etc/ssl/certs/ca-certificates.crt ] ;;
    *) command -v "$1" >/dev/null 2>&1 ;;
  esac
}

missing=()
reasons=()
for tool in "${tools[@]}"; do
  name=${tool%%:*}
  rest=${tool#*:}
  if ! have "$name"; then
    missing+=("${rest%%:*}")
    reasons+=("  ${rest%%:*}: ${rest#*:}")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

# Said before apt-get and before the long build, so that nothing surprises after minutes.
{
  echo "scripts/native-deps.sh: installing with apt-get what the $set_name needs and this machine lacks:"
  printf '%s\n' "${reasons[@]}"
} >&2
if command -v apt-get >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y --no-install-recommends "${missing[@]}" ||
    { apt-get update && apt-get install -y --no-install-recommends "${missing[@]}"; } ||
    echo "could not install ${missing[*]} with apt-get (run as root?)" >&2
else
  echo "no apt-get here: install ${missing[*]} (or your system's equivalents) by hand" >&2
fi
for tool in "${tools[@]}"; do
  name=${tool%%:*}
  rest=${tool#*:}
  have "$name" || { echo "${rest%%:*} is missing (${rest#*:}): scripts/native-deps.sh could not install it" >&2; exit 1; }
done
