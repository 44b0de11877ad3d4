#!/usr/bin/env bash
# Build (or find in the cache) the arm64 root file system of the arm64 test VM.
#
#   tests/arm64/mkrootfs.sh
#
# The x86 test VM uses the host's own root over 9p; an arm64 guest needs arm64
# userspace. This is Debian bookworm arm64 (debootstrap, minbase) with what the
# guest tests use, plus the PyPI packages of tests/requirements.txt (pure
# Python, installed with pip --target from the host). It lives in
#   $LEGO_CACHE/rootfs-arm64-<key>/root
# where <key> hashes the package list, tests/requirements.txt and the recipe
# number. Prints the root directory on stdout; progress goes to stderr and
# to build.log in the cache entry.
#
# debootstrap's second stage runs the packages' maintainer scripts, which
# needs arm64 binaries to run on the host: binfmt_misc is not available in
# the container these tests were written in, so the second stage is done
# here without them: every downloaded package is unpacked with dpkg-deb -x,
# then the few things their scripts would have made (passwd and group, the
# awk alternative, the dynamic linker cache through qemu-aarch64-static) are
# made directly. The guest mounts the tree read-only and runs only the
# tests, so no package database is needed.
#
# Environment: LEGO_DEBIAN_MIRROR (default http://deb.debian.org/debian).
set -euo pipefail

top=$(cd "$(dirname "$0")/../.." && pwd)
cache=${LEGO_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/lego-mindstorms-linux}
mirror=${LEGO_DEBIAN_MIRROR:-http://deb.debian.org/debian}
suite=bookworm
# What the guest tests run: python3 and pytest, pyusb and libusb (nxt-python),
# udevadm and systemd-udevd (test_ev3_attach, the udev tests), iio_info and iio_readdev
# (libiio-utils, test_ev3_iio), libiio's daemon (iiod, test_ev3_iiod), i2c-tools
# (test_nxt_i2c), kmod (insmod, modprobe,
# rmmod), util-linux (ldattach), iproute2, procps, and a static busybox for
# the initramfs. python3-pil is python-ev3dev2's Pillow (compiled code).
packages=python3,python3-pytest,python3-usb,python3-pil,libusb-1.0-0,libiio-utils,iiod,i2c-tools,udev,systemd,kmod,iproute2,util-linux,procps,busybox-static
# Bump when the steps below change in a way that changes the result.
recipe=1
key=$( { echo "$suite arm64 $packages recipe $recipe"; cat "$top/tests/requirements.txt"; } |
	sha256sum | cut -c1-16)
entry=$cache/rootfs-arm64-$key
root=$entry/root

if [ -f "$entry/.done" ]; then
	echo "$root"
	exit 0
fi
for t in debootstrap dpkg-deb qemu-aarch64-static; do
	command -v "$t" >/dev/null || { echo "mkrootfs: $t missing (tests/install-deps.sh)" >&2; exit 1; }
done

mkdir -p "$entry"
log=$entry/build.log
echo "mkrootfs: building the arm64 root in $root (log: $log)" >&2
start=$(date +%s)
rm -rf "$root"
mkdir -p "$root" "$cache/debs-arm64"
if ! debootstrap --foreign --arch=arm64 --variant=minbase --include="$packages" \
	--cache-dir="$cache/debs-arm64" "$suite" "$root" "$mirror" >"$log" 2>&1; then
	tail -n 20 "$log" >&2
	echo "mkrootfs: debootstrap failed" >&2
	exit 1
fi

# The second stage without maintainer scripts: unpack every package.
n=0
for deb in "$root"/var/cache/apt/archives/*.deb; do
	dpkg-deb -x "$deb" "$root" || { echo "mkrootfs: cannot unpack $deb" >&2; exit 1; }
	n=$((n + 1))
done
echo "mkrootfs: unpacked $n packages" >>"$log"
rm -f "$root"/var/cache/apt/archives/*.deb
rm -rf "$root/debootstrap"
# What base-passwd's and mawk's scripts do.
cp "$root/usr/share/base-passwd/passwd.master" "$root/etc/passwd"
cp "$root/usr/share/base-passwd/group.master" "$root/etc/group"
[ -e "$root/usr/bin/awk" ] || ln -s mawk "$root/usr/bin/awk"
echo lego-arm64 > "$root/etc/hostname"
# The loader cache, with the guest's own (static) ldconfig run in user mode QEMU.
ldconfig=$root/sbin/ldconfig.real
[ -x "$ldconfig" ] || ldconfig=$root/sbin/ldconfig
qemu-aarch64-static "$ldconfig" -r "$root" >>"$log" 2>&1 ||
	echo "mkrootfs: ldconfig failed (the loader's default paths still apply)" >&2

# The PyPI packages of tests/requirements.txt, installed by the host's pip
# with --no-deps: they must be pure Python (checked below), and the host's
# Python must be the guest's minor version. pytest and pyusb come from
# Debian above (python3-pytest, python3-usb), as does Pillow (python3-pil,
# needed by python-ev3dev2): their PyPI builds would be the host's.
pyver=$(basename "$(readlink -f "$root/usr/bin/python3")")   # python3.11
hostver=$(python3 -c 'import sys; print("python%d.%d" % sys.version_info[:2])')
[ "$pyver" = "$hostver" ] || { echo "mkrootfs: host $hostver, guest $pyver: pip --target needs the same" >&2; exit 1; }
site=$root/usr/local/lib/$pyver/dist-packages
mkdir -p "$site"
reqs=$(grep -vE '^[[:space:]]*(#|$)' "$top/tests/requirements.txt" | grep -viE '^(pytest|pyusb)([<>=!~ ]|$)')
# shellcheck disable=SC2086  # one requirement a word
if ! python3 -m pip install --quiet --disable-pip-version-check --no-compile --no-deps \
	--target "$site" $reqs >>"$log" 2>&1; then
	tail -n 20 "$log" >&2
	echo "mkrootfs: pip install into the arm64 root failed" >&2
	exit 1
fi
if find "$site" -name '*.so*' | grep . >&2; then
	echo "mkrootfs: compiled (host) code among the PyPI packages: not usable on arm64" >&2
	exit 1
fi
file -L "$root/bin/busybox" | grep -q 'ARM aarch64.*statically linked' ||
	{ echo "mkrootfs: $root/bin/busybox is not a static arm64 busybox" >&2; exit 1; }

echo "mkrootfs: built in $(( $(date +%s) - start )) s" >&2
touch "$entry/.done"
echo "$root"
