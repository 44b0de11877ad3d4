#!/usr/bin/env bash
# Build the modules against one kernel tree in a build directory of their own,
# with W=1 (and sparse with --sparse), and fail on any compiler or sparse
# warning.
#   tests/build-modules.sh [--sparse] KDIR OUTDIR
# ARCH and CROSS_COMPILE in the environment cross-compile the modules, the
# uapi check and the tools (tests/cross-build.sh); the 32-bit NXT client is
# built only for an x86_64 host's own guest (no ARCH).
set -euo pipefail
sparse=
if [ "${1:-}" = --sparse ]; then
	sparse="C=2"
	shift
fi
kdir=$1
out=$2
top=$(cd "$(dirname "$0")/.." && pwd)
cc=${CROSS_COMPILE:-}gcc

mkdir -p "$out"
rsync -a --delete --exclude '*.o' --exclude '*.ko' --exclude '.*.cmd' --exclude '*.mod*' \
	--exclude 'modules.order' --exclude 'Module.symvers' \
	"$top/Kbuild" "$top/Makefile" "$top/drivers" "$top/include" "$out/"
mkdir -p "$out/tests" && rsync -a --delete "$top/tests/kmod" "$out/tests/"
log=$out/build.log
cross=()
[ -z "${ARCH:-}" ] || cross+=(ARCH="$ARCH")
[ -z "${CROSS_COMPILE:-}" ] || cross+=(CROSS_COMPILE="$CROSS_COMPILE")
# A kernel built with gcov (the test kernel: tests/kernel/test.config) gets
# instrumented drivers, whose coverage the guest suite collects
# (tests/coverage.py); other trees get the modules as users build them.
cov=()
! grep -qs '^CONFIG_GCOV_KERNEL=y' "$kdir/.config" || cov=(LEGO_COVERAGE=1)
if ! make -C "$out" KDIR="$kdir" "${cross[@]}" "${cov[@]}" $sparse modules >"$log" 2>&1; then
	cat "$log" >&2
	echo "build-modules: build against $kdir failed" >&2
	exit 1
fi
# Compiler warnings say "warning:"; sparse says "warning:" or "error:".
if grep -E '(warning|error):' "$log" >&2; then
	echo "build-modules: warnings building against $kdir (log: $log)" >&2
	exit 1
fi
# The guest tests' check of the uapi header, compiled here: a compiler in
# the emulated guest is slow.
"$cc" -Wall -Wextra -Werror -I "$top/include/uapi" -o "$out/uapi-check" "$top/tests/guest/nxt_uapi_check.c"
# The 32-bit client of the NXT ioctls (tests/guest/test_nxt_compat.py), for
# the x86 guest only: static, for i386 (gcc-12-multilib, libc6-dev-i386).
# gcc -m32 does not search the multiarch directory, whose asm/ headers (the
# same for i386 and x86_64) the i386 libc headers include: -idirafter adds
# it after the i386 ones (Debian's gcc-multilib would add an asm symlink, but
# it removes the ARM cross compilers).
rm -f "$out/nxt-compat-client"
if [ -z "${ARCH:-}" ] && [ "$(uname -m)" = x86_64 ]; then
	if ! gcc -m32 -static -O2 -Wall -Wextra -Werror -idirafter "/usr/include/$(gcc -print-multiarch)" \
		-I "$top/include/uapi" -o "$out/nxt-compat-client" "$top/tests/guest/nxt_compat_client.c"; then
		echo "build-modules: the 32-bit NXT client did not build (gcc-12-multilib and libc6-dev-i386: tests/install-deps.sh)" >&2
		exit 1
	fi
fi
# The userspace tools, for the guest tests: $LEGO_BUILD/tools/, warnings
# as errors (WERROR=1).
mkdir -p "$out/tools"
if ! make -s -C "$top/tools" O="$out/tools" CC="$cc" AR="${CROSS_COMPILE:-}ar" WERROR=1 >"$out/tools.log" 2>&1 || grep -E '(warning|error):' "$out/tools.log" >&2; then
	cat "$out/tools.log" >&2
	echo "build-modules: the userspace tools did not build cleanly" >&2
	exit 1
fi
# The C examples, as a user builds them (examples/Makefile), for the guest's
# tests/guest/test_examples.py: $LEGO_BUILD/examples/, warnings as errors.
# For the host's own guest only (iio-capture links the host's libiio).
rm -rf "$out/examples"
if [ -z "${ARCH:-}" ] &&
	! make -s -C "$top/examples" O="$out/examples" CFLAGS='-O2 -Wall -Wextra -Werror' >"$out/examples.log" 2>&1; then
	cat "$out/examples.log" >&2
	echo "build-modules: the examples did not build cleanly" >&2
	exit 1
fi
n=$(find "$out" -name '*.ko' | wc -l)
# A kernel newer than the machine's sparse (7.3's headers use
# __typeof_unqual__, which Debian 12's sparse 0.6.4 does not know) skips it
# with a note, not an error: say so rather than "sparse clean". The other
# trees make check builds against (6.12, the 6.1 headers, the cross
# builds) still run it.
checked=${sparse:+ (sparse clean)}
if [ -n "$sparse" ] && grep -q 'is not available or not up to date' "$log"; then
	checked=" (sparse not run: this kernel refuses $(sparse --version 2>/dev/null | head -n 1))"
fi
echo "build-modules: $n modules built against $kdir${ARCH:+ for $ARCH}$checked${cov:+ (with gcov)}" >&2
