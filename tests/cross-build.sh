#!/usr/bin/env bash
# Cross-compile the modules (with the KUnit suites and tests/kmod), the uapi
# check and the userspace tools for arm64 and armhf, with W=1, sparse (C=2)
# and -Werror for the tools, against kernel trees prepared from Debian's
# linux-source-6.12 (tests/kernel/build-cross-tree.sh, cached). Any compiler
# or sparse warning, and any symbol the kernel does not export (modpost),
# fails the run.
#
#   tests/cross-build.sh [OUTDIR] [ARCH...]   OUTDIR: .build (default); ARCH: arm64 armhf
#
# Each architecture builds from scratch into OUTDIR/cross-ARCH.
set -uo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$top/.build}
shift || true
arches=("$@")
[ ${#arches[@]} -gt 0 ] || arches=(arm64 armhf)

fail=0
for arch in "${arches[@]}"; do
	t0=$SECONDS
	if ! tree=$("$top/tests/kernel/build-cross-tree.sh" "$arch"); then
		echo "cross-build: no $arch kernel tree" >&2
		fail=1
		continue
	fi
	# shellcheck source=/dev/null
	. "$(dirname "$tree")/env"
	# From scratch: an object left from an earlier run would not be
	# recompiled, and its warnings not shown again.
	rm -rf "$out/cross-$arch"
	if ARCH=$KARCH CROSS_COMPILE=$CROSS "$top/tests/build-modules.sh" --sparse "$tree" "$out/cross-$arch"; then
		echo "cross-build: $arch clean in $((SECONDS - t0)) s" >&2
	else
		echo "cross-build: $arch FAILED" >&2
		fail=1
	fi
done
exit $fail
