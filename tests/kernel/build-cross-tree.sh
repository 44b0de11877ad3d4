#!/usr/bin/env bash
# Prepare (or find in the cache) a kernel tree to compile the modules
# against: for an ARM architecture (cross-compiled), or for x86 where a
# series is built against but not booted (make check boots the newest).
#
#   tests/kernel/build-cross-tree.sh [--tree-only] ARCH [SERIES]
#
# ARCH: arm64, armhf or x86; SERIES: 6.12 (default) or any that
# tests/kernel/fetch-source.sh finds.
#
# --tree-only prints the cached tree if it is complete and builds nothing.
# Prints the tree on stdout; progress goes to stderr and build.log in the
# cache entry. Build against it with
#   make -C TREE ARCH=<karch> CROSS_COMPILE=<prefix> M=...
# (tests/cross-build.sh does; `. <entry>/env` sets KARCH and CROSS).
#
# The source is Debian's linux-source-SERIES, as for the test kernel. The tree
# is the architecture's defconfig (arm64: defconfig; armhf: multi_v7_defconfig,
# the ARMv7 multiplatform config that matches Debian's armhf baseline and the
# 32-bit Raspberry Pi 2/3; x86: x86_64_defconfig) merged with tests/kernel/cross-common.config, then
# `make modules_prepare`. It lives in
#   $LEGO_CACHE/cross-ARCH-<key>/linux (cross-ARCH-SERIES-<key> but for 6.12)
# where <key> hashes the package version, the fragment and the recipe number.
#
# modpost needs the kernel's exported symbols (Module.symvers) to reject a
# module that uses a symbol the kernel does not export (on armhf, a 64-bit
# division calls __aeabi_uldivmod, which the kernel does not provide). A
# full defconfig build to get the real file would cost many times what
# preparing the tree does, so Module.symvers is generated from the sources
# (everything but the other architectures; see below). That list is a
# superset of what this config exports: a symbol exported only by code the
# config leaves out passes here, but not in the x86 builds against the
# complete test kernel.
set -euo pipefail

tree_only=0
if [ "${1:-}" = --tree-only ]; then
	tree_only=1
	shift
fi
arch=${1:-}
case "$arch" in
arm64) karch=arm64 cross=aarch64-linux-gnu- defconfig=defconfig ;;
armhf) karch=arm cross=arm-linux-gnueabihf- defconfig=multi_v7_defconfig ;;
x86) karch=x86 cross= defconfig=x86_64_defconfig ;;
*) echo "usage: $0 [--tree-only] arm64|armhf|x86 [SERIES]" >&2; exit 2 ;;
esac
series=${2:-6.12}
here=$(cd "$(dirname "$0")" && pwd)
prog=build-cross-tree
# shellcheck source=tests/kernel/lib.sh
. "$here/lib.sh"
fragment=$here/cross-common.config
cache=$(kcache_dir)

read -r series pkgver tarball < <("$here/fetch-source.sh" "$series") || exit 1
command -v "${cross}gcc" >/dev/null || { echo "build-cross-tree: ${cross}gcc missing (tests/install-deps.sh installs it)" >&2; exit 1; }
# Bump when the steps below change in a way that changes the result.
recipe=5
key=$( { echo "$arch $series $pkgver $defconfig recipe $recipe"; cat "$fragment"; } | sha256sum | cut -c1-16)
# (6.12's entries keep the name they had before other series.)
entry=$cache/cross-$arch-$key
[ "$series" = 6.12 ] || entry=$cache/cross-$arch-$series-$key
tree=$entry/linux

kcache_lookup "$entry" "$tree_only"

mkdir -p "$entry"
exec 3>&2
log=$entry/build.log
echo "build-cross-tree: preparing linux-source-$series $pkgver for $arch in $entry (log: $log)" >&3
start=$(date +%s)
kcache_unpack "$tarball" "$tree"

kmake() { nice -n 15 make -C "$tree" ARCH="$karch" CROSS_COMPILE="$cross" "$@"; }
{
	kmake "$defconfig"
	ARCH=$karch CROSS_COMPILE=$cross "$tree/scripts/kconfig/merge_config.sh" -m -O "$tree" "$tree/.config" "$fragment"
	kmake olddefconfig
} >"$log" 2>&1

kconfig_verify "$tree/.config" "" "$fragment" 2>&3 || exit 1

if ! kmake -j"$(nproc)" modules_prepare >>"$log" 2>&1; then
	tail -n 40 "$log" >&3
	exit 1
fi

# Module.symvers: "CRC<TAB>symbol<TAB>module<TAB>export type<TAB>namespace",
# from the exports of arch/$karch and of everything outside arch/.
# 1. EXPORT_SYMBOL*(name[, namespace]) and EXPORT_PER_CPU_SYMBOL*(name)
#    lines of the sources (x86's this_cpu_off and pcpu_hot are per-CPU).
# 2. Exports a macro builds (EXPORT_SYMBOL(func) in a #define, or with ##,
#    like _dev_warn or param_ops_int, or x86's __x86_indirect_thunk_rax in
#    an assembler file): their files are compiled and the
#    __export_symbol_* markers read from the objects; a file that does not
#    compile for this architecture is skipped. These are entered without
#    namespace or GPL restriction (the modules are GPL and import only
#    EXPORTED_FOR_KUNIT_TESTING, which they export themselves).
(
	cd "$tree"
	dirs=$(ls -d ./*/ | grep -vxE '\./(arch|Documentation|tools|samples|scripts|usr)/')
	# shellcheck disable=SC2086
	grep -rhoE --include='*.[chS]' \
		'^[[:space:]]*EXPORT_(PER_CPU_)?SYMBOL(_GPL|_NS|_NS_GPL)?\([[:space:]]*[A-Za-z_][A-Za-z0-9_]*[[:space:]]*(,[[:space:]]*[A-Za-z_][A-Za-z0-9_]*)?[[:space:]]*\)' \
		$dirs "arch/$karch" |
	sed -E 's/^[[:space:]]*//; s/[[:space:]]//g' |
	awk -F'[(),]' '{
		type = ($1 ~ /GPL/) ? "EXPORT_SYMBOL_GPL" : "EXPORT_SYMBOL"
		printf "0x00000000\t%s\tvmlinux\t%s\t%s\n", $2, type, ($1 ~ /_NS/) ? $3 : ""
	}' >.lego-exports

	# shellcheck disable=SC2086
	grep -rlE --include='*.[cS]' 'EXPORT_SYMBOL' $dirs "arch/$karch" |
	xargs awk 'FNR == 1 { prev = "" }
		/EXPORT_SYMBOL/ && (prev ~ /\\$/ || $0 ~ /##|\\$|^[[:space:]]*#[[:space:]]*define/) { print FILENAME; nextfile }
		{ prev = $0 }' | sed 's|^\./||; s|\.[cS]$|.o|' >.lego-macro-objs
	# shellcheck disable=SC2046
	kmake -k -j"$(nproc)" $(cat .lego-macro-objs) >>"$log" 2>&1 || true
	# Single targets of one directory built in parallel can race (two jobs
	# building x86's retpoline.o: "fixdep: error opening file", and the
	# object deleted): what is missing is tried again, one job at a time.
	missing=$(while read -r o; do [ -f "$o" ] || echo "$o"; done <.lego-macro-objs)
	# shellcheck disable=SC2086
	[ -z "$missing" ] || kmake -k -j1 $missing >>"$log" 2>&1 || true
	while read -r o; do
		if [ -f "$o" ]; then "${cross}nm" "$o"; fi
	done <.lego-macro-objs | sed -n 's/.* __export_symbol_\(.*\)$/\1/p' |
	awk '{ printf "0x00000000\t%s\tvmlinux\tEXPORT_SYMBOL\t\n", $1 }' >>.lego-exports
	# The first entry of a name wins.
	awk -F'\t' '!seen[$2]++' .lego-exports | sort -t"$(printf '\t')" -k2,2 >Module.symvers
)
n=$(wc -l <"$tree/Module.symvers")
[ "$n" -gt 10000 ] || { echo "build-cross-tree: only $n exported symbols found, the scan is broken" >&3; exit 1; }
printf 'KARCH=%s\nCROSS=%s\n' "$karch" "$cross" >"$entry/env"
echo "build-cross-tree: $arch tree ready ($n exported symbols) in $(( $(date +%s) - start )) s" >&3
touch "$entry/.done"
echo "$tree"
