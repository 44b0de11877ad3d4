#!/usr/bin/env bash
# Build the test VM's initramfs: busybox (static) and tests/vm/init.
#   tests/vm/mkinitramfs.sh OUTPUT.cpio.gz [BUSYBOX]
# BUSYBOX: a static busybox for the guest (default: the host's; the arm64
# VM passes the one of its root, tests/arm64/mkrootfs.sh).
set -euo pipefail
out=$1
here=$(cd "$(dirname "$0")" && pwd)
if [ -n "${2:-}" ]; then
	bb=$2
	file -L "$bb" 2>/dev/null | grep -q static || { echo "mkinitramfs: $bb is not a static busybox" >&2; exit 1; }
else
	bb=/bin/busybox
	[ -x "$bb" ] && file -L "$bb" 2>/dev/null | grep -q static || bb=/usr/bin/busybox
fi
[ -x "$bb" ] || { echo "mkinitramfs: busybox-static is not installed" >&2; exit 1; }

if [ -f "$out" ] && [ "$out" -nt "$here/init" ] && [ "$out" -nt "$0" ]; then
	exit 0
fi
root=$(mktemp -d)
trap 'rm -rf "$root"' EXIT
mkdir -p "$root"/{bin,dev,proc,sys,host,tmp}
cp "$bb" "$root/bin/busybox"
install -m 0755 "$here/init" "$root/init"
mkdir -p "$(dirname "$out")"
(cd "$root" && find . | cpio -o -H newc --quiet | gzip -1) > "$out.tmp"
mv "$out.tmp" "$out"
