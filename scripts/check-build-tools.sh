#!/usr/bin/env bash
# Fails when the README's first command (scripts/lab.sh: penmesh-lab, default features, release)
# or the proxy image's build (deploy/Dockerfile: penmesh-proxy) needs a build tool that what
# runs it does not install (issue 48). Run by .ci/run; needs only cargo (no build).
#
# A crate's build script runs a native tool through a few crates; which of them are in a
# binary's dependency tree (`cargo tree -e normal,build`) says which tools its build needs:
#   cc, cxx-build -> a C/C++ compiler;  cmake -> cmake;  manifold-rs -> ninja (its generator);
#   bindgen -> libclang. (The `pkg-config` crate is there too, for libsqlite3-sys, which with
#   sqlx's `bundled` SQLite compiles its own C and asks pkg-config for nothing.)
# Each needed Debian package must be in what installs the tools: `scripts/native-deps.sh --list
# build` for the README's command; the Dockerfile's build stage's apt-get line plus what its
# base image (rust:1-bookworm, on buildpack-deps: gcc, g++, libc6-dev, ca-certificates) has.
set -euo pipefail
cd "$(dirname "$0")/.."

# crate -> the Debian packages its presence needs.
needs() {
  case "$1" in
    cc | cxx-build) echo gcc g++ ;;
    cmake) echo cmake ;;
    manifold-rs) echo ninja-build ;;
    bindgen) echo libclang-dev ;;
  esac
}

# The Debian packages a build of `cargo tree` arguments "$@" needs.
needed_packages() {
  cargo tree -e normal,build --prefix none -f '{p}' "$@" | awk '{print $1}' | sort -u |
    while read -r crate; do
      for package in $(needs "$crate"); do echo "$package ($crate)"; done
    done | sort -u
}

# check NAME "INSTALLED PACKAGES" CARGO-TREE-ARGS...: each package the tree needs is installed.
failures=0
check() {
  local name=$1 installed=" $2 " missing=()
  shift 2
  while read -r package crate; do
    [ -n "$package" ] || continue
    case "$installed" in *" $package "*) ;; *) missing+=("$package $crate") ;; esac
  done < <(needed_packages "$@")
  if [ ${#missing[@]} -gt 0 ]; then
    echo "FAIL: $name needs ${missing[*]}, which it does not install" >&2
    return 1
  fi
  echo "ok: $name installs every build tool its dependencies need"
}

readme_installs=$(./scripts/native-deps.sh --list build | tr '\n' ' ')
# The build stage's apt-get install line(s) of deploy/Dockerfile (up to its `FROM` of the
# runtime stage), and what its base image brings.
image_installs="gcc g++ libc6-dev ca-certificates $(
  awk '/^FROM debian/{exit} !/^[[:space:]]*#/{print}' deploy/Dockerfile | tr '\\\n' '  ' |
    grep -o 'apt-get install[^&]*' | tr ' ' '\n' | grep -v -e '^-' -e '^apt-get$' -e '^install$' |
    tr '\n' ' '
)"

check "the README's first command (scripts/lab.sh: penmesh-lab, default features)" \
  "$readme_installs" -p penmesh-lab || failures=$((failures + 1))
check "the proxy image's build (deploy/Dockerfile: penmesh-proxy)" \
  "$image_installs" -p penmesh-proxy || failures=$((failures + 1))

# The check itself bites: the lab with the Poisson feature needs libclang through bindgen,
# which the README's first command does not install.
if check "(self-check) penmesh-lab --features poisson" "$readme_installs" \
  -p penmesh-lab --features poisson 2>/dev/null >/dev/null; then
  echo "FAIL: the self-check passed: the lab with --features poisson should need libclang" >&2
  failures=$((failures + 1))
else
  echo "ok: the self-check (penmesh-lab --features poisson needs libclang) is refused"
fi
exit $((failures > 0))
