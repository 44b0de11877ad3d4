#!/usr/bin/env bash
# Build (or find in the cache) the QEMU test kernel for one kernel series.
#
#   tests/kernel/build-kernel.sh [--tree-only] [--arch ARCH] [--variant bench] [SERIES]
#
# SERIES: 6.12 (default), 6.1, any X.Y that Debian serves, or newest (the
# newest linux-source-X.Y of trixie-backports and sid; tests/kernel/fetch-source.sh).
# ARCH: x86 (default) or arm64; arm64 is
# cross-compiled (CROSS_COMPILE=aarch64-linux-gnu-) with test.config plus
# arm64.config, and cached as kernel-arm64-SERIES-<key>.
# --variant bench (x86): test.config plus bench.config, the debug checks off,
# for `make bench`; cached as kernel-bench-SERIES-<key>.
# --variant kcsan (x86): test.config plus kcsan.config, KCSAN instead of
# KASAN, for `make soak`; cached as kernel-kcsan-SERIES-<key>.
# --tree-only prints the cached tree if it is complete and builds nothing.
#
# The source comes from Debian's linux-source-SERIES package (installed, or
# fetched into the cache by fetch-source.sh). The build lives in
#   $LEGO_CACHE/kernel-SERIES-<key>/linux
# where <key> hashes the package version, the config fragment and the recipe number, so
# the kernel is rebuilt only when one of them changes. Prints the build directory
# on stdout (progress goes to stderr and to build.log in the cache entry).
set -euo pipefail

tree_only=0
arch=x86
variant=
while [ $# -gt 0 ]; do
	case "$1" in
	--tree-only) tree_only=1; shift ;;
	--arch) arch=$2; shift 2 ;;
	--variant) variant=$2; shift 2 ;;
	*) break ;;
	esac
done
series=${1:-6.12}
here=$(cd "$(dirname "$0")" && pwd)
prog=build-kernel
# shellcheck source=tests/kernel/lib.sh
. "$here/lib.sh"
fragment=$here/test.config
fragments=("$fragment")
# Per-architecture make variables and the options of test.config that the
# architecture does not have (skipped by the "not set as requested" check).
makevars=()
absent=
image=bzImage
case "$arch" in
x86) ;;
arm64)
	fragments+=("$here/arm64.config")
	makevars=(ARCH=arm64 CROSS_COMPILE=aarch64-linux-gnu-)
	image=Image
	absent="CONFIG_X86_MPPARSE CONFIG_EARLY_PRINTK CONFIG_KERNEL_GZIP CONFIG_IA32_EMULATION"
	;;
*) echo "build-kernel: unknown --arch $arch (x86 or arm64)" >&2; exit 2 ;;
esac
case "$arch/$variant" in
*/) ;;
x86/bench) fragments+=("$here/bench.config") ;;
x86/kcsan) fragments+=("$here/kcsan.config") ;;
*) echo "build-kernel: unknown --variant $variant for $arch (x86: bench, kcsan)" >&2; exit 2 ;;
esac
cache=$(kcache_dir)
# The series' source (newest: the newest Debian serves), its package version
# and tarball: tests/kernel/fetch-source.sh.
read -r series pkgver tarball < <("$here/fetch-source.sh" "$series") || exit 1
# Bump when the steps below change in a way that changes the result.
recipe=1
if [ -n "$variant" ]; then
	key=$( { echo "$variant $arch $series $pkgver recipe $recipe"; cat "${fragments[@]}"; } | sha256sum | cut -c1-16)
	entry=$cache/kernel-$variant-$series-$key
elif [ "$arch" = x86 ]; then
	# The x86 key predates --arch: keep it as it was so the cache stays valid.
	key=$( { echo "$series $pkgver recipe $recipe"; cat "$fragment"; } | sha256sum | cut -c1-16)
	entry=$cache/kernel-$series-$key
else
	key=$( { echo "$arch $series $pkgver recipe $recipe"; cat "${fragments[@]}"; } | sha256sum | cut -c1-16)
	entry=$cache/kernel-$arch-$series-$key
fi
tree=$entry/linux

kcache_lookup "$entry" "$tree_only"

mkdir -p "$entry"
exec 3>&2
log=$entry/build.log
echo "build-kernel: building linux-source-$series $pkgver into $entry (log: $log)" >&3
kcache_unpack "$tarball" "$tree"

jobs=$(nproc)
{
	make -C "$tree" "${makevars[@]}" tinyconfig
	env "${makevars[@]}" "$tree/scripts/kconfig/merge_config.sh" -m -O "$tree" "$tree/.config" "${fragments[@]}"
	make -C "$tree" "${makevars[@]}" olddefconfig
} >"$log" 2>&1

kconfig_verify "$tree/.config" "$absent" "${fragments[@]}" 2>&3 || exit 1

start=$(date +%s)
# Print a dot a minute so a long cold build shows progress.
( while sleep 60; do printf '.' >&3; done ) &
ticker=$!
trap 'kill $ticker 2>/dev/null || true' EXIT
if ! make -C "$tree" "${makevars[@]}" -j"$jobs" "$image" modules >>"$log" 2>&1; then
	echo >&3
	tail -n 40 "$log" >&3
	exit 1
fi
kill $ticker 2>/dev/null || true
echo >&3
echo "build-kernel: built in $(( $(date +%s) - start )) s" >&3
touch "$entry/.done"
echo "$tree"
