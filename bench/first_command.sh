#!/usr/bin/env bash
# Times the README's first command as a newcomer meets it: on a fresh, minimal Debian 12 (a
# `debootstrap --variant=minbase bookworm` root), as root, with the repository cloned into it.
# Prints the set-up's and the optimisation's wall seconds apart, the number of packages apt installed,
# the load average before and after (the figures mean something only on an idle machine) and the
# optimisation's last line (its ψ1 must be the record's).
#
#   sudo bash bench/first_command.sh [COMMIT] [ROOT]
#
# COMMIT defaults to HEAD; ROOT (default: a new folder under /var/tmp) must not exist and is removed at
# the end. Needs debootstrap and network access to Debian's archive; takes about as long as the command
# it times plus a minute for debootstrap. docs/guides/installing.md quotes its figures.
set -euo pipefail
commit="${1:-HEAD}"
root="${2:-}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
if [ "$(id -u)" -ne 0 ]; then
  echo "first_command: run as root (debootstrap and chroot need it)" >&2
  exit 2
fi
command -v debootstrap > /dev/null || {
  echo "first_command: debootstrap is missing (apt-get install debootstrap)" >&2
  exit 2
}
sha="$(git -C "$repo" rev-parse --verify "$commit^{commit}")" || {
  echo "first_command: '$commit' is not a commit of $repo" >&2
  exit 2
}
if [ -z "$root" ]; then
  root="$(mktemp -d /var/tmp/hindsight-first-command.XXXXXX)"
  rmdir "$root"
elif [ -e "$root" ]; then
  echo "first_command: ROOT '$root' exists; give a path that does not" >&2
  exit 2
fi
cleanup() {
  umount "$root/proc" 2> /dev/null || true
  rm -rf "$root"
}
trap cleanup EXIT
debootstrap --variant=minbase bookworm "$root" http://deb.debian.org/debian > /dev/null
base_packages="$(chroot "$root" dpkg-query -W -f='${db:Status-Status}\n' | grep -c '^installed$')"
mount -t proc proc "$root/proc"
cp /etc/resolv.conf "$root/etc/resolv.conf"
git clone -q "$repo" "$root/root/hindsight"
git -C "$root/root/hindsight" checkout -q "$sha"
echo "commit $sha"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
chroot "$root" /bin/bash -c '
  cd /root/hindsight
  start=$(date +%s)
  bash .ci/setup > /root/setup.log 2>&1 || { tail -20 /root/setup.log; exit 1; }
  built=$(date +%s)
  ./build/hindsight optimize --force > /root/optimize.log 2>&1 || { tail -20 /root/optimize.log; exit 1; }
  done=$(date +%s)
  echo "set-up $((built - start)) s, optimisation $((done - built)) s, in all $((done - start)) s"
  tail -1 /root/optimize.log'
echo "packages installed: $(($(chroot "$root" dpkg-query -W -f='${db:Status-Status}\n' | grep -c '^installed$') - base_packages))"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
