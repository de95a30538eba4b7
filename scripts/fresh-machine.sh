#!/usr/bin/env bash
# Runs the README's two commands as a newcomer would, on a fresh Debian 12 (bookworm) made with
# debootstrap from Debian's packages, with only the Rust toolchain (this machine's rustup
# toolchain, copied in) and Node.js with npm (this machine's, copied in) added: no compiler, no
# cmake, no crates downloaded, no node_modules (docs/fresh-machine.md has a run's times).
#
#   sudo scripts/fresh-machine.sh [demo|test|both]     (default both: the demo first)
#
# The checkout is cloned from this one's HEAD (committed work only) into the chroot's
# /work/penmesh, and ../shared copied beside it. Each run starts from a pristine copy of the
# debootstrapped system (kept as a tarball in $FRESH_CACHE so that a second run skips the
# download). Each step's wall time is printed as "== STEP: ok|failed in N s". Needs root,
# debootstrap (installed with apt-get when missing) and the network to Debian's and the crate
# and npm registries. The chroot shares this machine's network and kernel; /proc, /sys, /dev,
# /dev/pts and /dev/shm (Chromium's) are mounted in it and unmounted at the end.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
shared=$(cd "$repo/../shared" && pwd -P)
steps=${1:-both}
case "$steps" in demo | test | both) ;; *) echo "usage: $0 [demo|test|both]" >&2; exit 2 ;; esac
root=${FRESH_ROOT:-/var/tmp/penmesh-fresh}
cache=${FRESH_CACHE:-/var/tmp/penmesh-fresh-bookworm.tar}
mirror=${FRESH_MIRROR:-http://deb.debian.org/debian}
say() { echo "[$(date -u +%H:%M:%S)] $*"; }

[ "$(id -u)" = 0 ] || { echo "$0: needs root (debootstrap, chroot, mounts)" >&2; exit 1; }
command -v debootstrap >/dev/null ||
  apt-get install -y debootstrap || { apt-get update && apt-get install -y debootstrap; }

unmount_all() {
  for m in dev/shm dev/pts dev sys proc; do
    mountpoint -q "$root/$m" && umount -l "$root/$m"
  done
  return 0
}
trap unmount_all EXIT

if [ ! -s "$cache" ]; then
  say "debootstrap bookworm (once; kept in $cache)"
  base=$(mktemp -d /var/tmp/penmesh-debootstrap.XXXXXX)
  debootstrap bookworm "$base" "$mirror"
  tar -C "$base" -cf "$cache.part" . && mv "$cache.part" "$cache"
  rm -rf "$base"
fi
unmount_all
rm -rf "$root"
mkdir -p "$root"
say "a pristine bookworm in $root"
tar -C "$root" -xf "$cache"

# The Rust toolchain as rustup installed it here (the default toolchain only), and Node.js.
toolchain=$(rustup show active-toolchain | awk '{print $1}')
mkdir -p "$root/root/.rustup/toolchains" "$root/root/.cargo"
cp -a "$(rustc --print sysroot)" "$root/root/.rustup/toolchains/$toolchain"
cp -a "${RUSTUP_HOME:-$HOME/.rustup}/settings.toml" "$root/root/.rustup/"
cp -a "${CARGO_HOME:-$HOME/.cargo}/bin" "$root/root/.cargo/"
node=$(command -v node)
npm_root=$(cd "$(dirname "$(readlink -f "$(command -v npm)")")/.." && pwd)
cp -a "$node" "$root/usr/bin/node"
mkdir -p "$root/usr/lib/node_modules"
cp -a "$npm_root" "$root/usr/lib/node_modules/npm"
ln -sf ../lib/node_modules/npm/bin/npm-cli.js "$root/usr/bin/npm"
ln -sf ../lib/node_modules/npm/bin/npx-cli.js "$root/usr/bin/npx"

# The checkout (HEAD) and ../shared beside it.
mkdir -p "$root/work"
git clone -q --no-hardlinks "$repo" "$root/work/penmesh"
cp -a "$shared" "$root/work/shared"
chmod -R u+w "$root/work/shared"
say "checkout $(git -C "$repo" rev-parse --short HEAD) in $root/work/penmesh"

cp /etc/resolv.conf "$root/etc/resolv.conf"
# The network's, not the project's: where this machine's network re-signs TLS (an egress proxy
# with its own CA, as on the machine this was written on), its CAs are copied in, so that the
# chroot reaches the registries as this machine does: Debian's ca-certificates (which the
# README's command installs) takes them in for cargo, and Node is pointed at them.
node_ca=()
if compgen -G '/usr/local/share/ca-certificates/*.crt' >/dev/null; then
  mkdir -p "$root/usr/local/share/ca-certificates"
  cp /usr/local/share/ca-certificates/*.crt "$root/usr/local/share/ca-certificates/"
  cat /usr/local/share/ca-certificates/*.crt >"$root/etc/network-extra-ca.pem"
  node_ca=(NODE_EXTRA_CA_CERTS=/etc/network-extra-ca.pem)
fi
# A chroot is no place to start daemons that a package may bring.
printf '#!/bin/sh\nexit 101\n' >"$root/usr/sbin/policy-rc.d" && chmod +x "$root/usr/sbin/policy-rc.d"
mount -t proc proc "$root/proc"
mount -t sysfs sys "$root/sys"
mount --bind /dev "$root/dev"
mount -t devpts devpts "$root/dev/pts" -o newinstance,ptmxmode=0666 || true
mount -t tmpfs -o size=2g tmpfs "$root/dev/shm"

# run NAME COMMAND: the command in the chroot's checkout, as root with a login's environment.
failed=0
run() {
  local name=$1 command=$2 start=$SECONDS
  say "== $name: $command"
  if chroot "$root" /usr/bin/env -i HOME=/root TERM=dumb LANG=C.UTF-8 "${node_ca[@]}" \
    PATH=/root/.cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    bash -c "cd /work/penmesh && $command"; then
    say "== $name: ok in $((SECONDS - start)) s"
  else
    say "== $name: failed in $((SECONDS - start)) s"
    failed=1
  fi
}
if [ "$steps" != test ]; then run demo "./scripts/lab.sh demo"; fi
if [ "$steps" != demo ]; then run test "./scripts/test.sh"; fi
exit $failed
