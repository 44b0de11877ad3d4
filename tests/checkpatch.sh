#!/usr/bin/env bash
# checkpatch.pl --strict over every kernel source file of the project.
# Uses the checkpatch.pl of the cached test kernel tree (the newest, else
# 6.12), else 6.12's from its source package; CHECKPATCH= names another.
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
cd "$top"

cp=${CHECKPATCH:-}
if [ -z "$cp" ]; then
	tree=$(tests/kernel/build-kernel.sh --tree-only newest 2>/dev/null ||
		tests/kernel/build-kernel.sh --tree-only 6.12 2>/dev/null || true)
	[ -n "$tree" ] && [ -x "$tree/scripts/checkpatch.pl" ] && cp=$tree/scripts/checkpatch.pl
fi
if [ -z "$cp" ]; then
	d=${LEGO_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/lego-mindstorms-linux}/checkpatch
	if [ ! -x "$d/scripts/checkpatch.pl" ]; then
		mkdir -p "$d"
		tar -xf /usr/src/linux-source-6.12.tar.xz -C "$d" --strip-components=1 \
			linux-source-6.12/scripts/checkpatch.pl linux-source-6.12/scripts/spelling.txt \
			linux-source-6.12/scripts/const_structs.checkpatch
	fi
	cp=$d/scripts/checkpatch.pl
fi

compat=drivers/lego/lego_compat.h
mapfile -t files < <(git ls-files -co --exclude-standard -- 'drivers/*.[ch]' 'include/*.h' 'tools/*.[ch]' 'tests/kmod/*.[ch]' |
	grep -vxF "$compat" | grep -v '^tools/liblegonxt/' | sort)
[ ${#files[@]} -gt 0 ] || { echo "checkpatch: no files"; exit 1; }
"$cp" --strict --no-tree --quiet --show-types -f "${files[@]}" || {
	echo "checkpatch: not clean" >&2
	exit 1
}
# The shims of lego_compat.h re-create, for older kernels, macros of newer
# ones in the shape the kernel gives them (iio_for_each_active_channel()
# names its device twice, as the kernel's does), and name the older
# kernels' types (a bin_attribute that is not const). Never part of the
# in-tree series (tools/upstream/intree.py drops it).
"$cp" --strict --no-tree --quiet --show-types --ignore MACRO_ARG_REUSE,CONST_STRUCT -f "$compat" || {
	echo "checkpatch: $compat not clean" >&2
	exit 1
}
# The test programs (fuzz targets, benchmarks, the uapi check) and
# liblegonxt, whose header applications include, are userspace: C99 types,
# a volatile sig_atomic_t and libFuzzer's LLVMFuzzerTestOneInput are right
# there. tests/fuzz/shim/ is left out: it re-implements kernel macros for
# userspace, in the shape they have.
mapfile -t progs < <(git ls-files -co --exclude-standard -- 'tests/*.[ch]' 'tools/liblegonxt/*.[ch]' |
	grep -v -e '^tests/kmod/' -e '^tests/fuzz/shim/' | sort)
"$cp" --strict --no-tree --quiet --show-types --ignore PREFER_KERNEL_TYPES,VOLATILE,CAMELCASE \
	-f "${progs[@]}" || {
	echo "checkpatch: test programs not clean" >&2
	exit 1
}
echo "checkpatch: $(( ${#files[@]} + 1 )) files and ${#progs[@]} test programs clean"
