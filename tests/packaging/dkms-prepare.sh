#!/usr/bin/env bash
# Add, build and install the drivers with the real dkms against one kernel
# tree, on the host, into OUTDIR instead of the system's directories, for
# tests/guest/test_packaging.py (a build in the emulated guest takes over
# ten minutes; here it takes seconds).
#
#   tests/packaging/dkms-prepare.sh KDIR OUTDIR
#
# It runs in a private mount namespace where OUTDIR/dkms, OUTDIR/src and
# OUTDIR/modules are bind-mounted over /var/lib/dkms, /usr/src and
# /lib/modules, so dkms runs with its usual paths (depmod included) and the
# host's own directories are untouched. OUTDIR/modules/KVER/build points at
# KDIR. The guest test copies the three into tmpfs at the same places.
set -euo pipefail
if [ $# -ne 2 ]; then
	echo "usage: $0 KDIR OUTDIR" >&2
	exit 2
fi
kdir=$(cd "$1" && pwd)
out=$2
top=$(cd "$(dirname "$0")/../.." && pwd)
command -v dkms >/dev/null || { echo "dkms-prepare: dkms is not installed (tests/install-deps.sh)" >&2; exit 1; }
[ "$(id -u)" = 0 ] || { echo "dkms-prepare: needs root (a mount namespace, dkms)" >&2; exit 1; }
kver=$(sed -n 's/^#define UTS_RELEASE "\(.*\)"/\1/p' "$kdir/include/generated/utsrelease.h")
[ -n "$kver" ] || { echo "dkms-prepare: no kernel release in $kdir" >&2; exit 1; }
ver=$(sed -n 's/^PACKAGE_VERSION="\(.*\)"/\1/p' "$top/dkms.conf")

rm -rf "$out"
mkdir -p "$out/dkms" "$out/src" "$out/modules/$kver"
ln -s "$kdir" "$out/modules/$kver/build"
# What the kernel's modules_install leaves for depmod.
for f in modules.builtin modules.builtin.modinfo modules.order; do
	[ ! -f "$kdir/$f" ] || cp "$kdir/$f" "$out/modules/$kver/"
done
log=$out/dkms.log
export top out kver ver
if ! unshare -m --propagation private bash -euc '
	mount --bind "$out/dkms" /var/lib/dkms
	mount --bind "$out/src" /usr/src
	mount --bind "$out/modules" /lib/modules
	make -s -C "$top" dkms-source
	for step in add build install; do
		dkms $step -m lego-mindstorms -v "$ver" -k "$kver"
	done
' >"$log" 2>&1; then
	cat "$log" >&2
	echo "dkms-prepare: dkms failed for $kver (log: $log)" >&2
	exit 1
fi
echo "$kver" > "$out/kernel-release"
echo "dkms-prepare: lego-mindstorms/$ver built and installed for $kver in $out" >&2
