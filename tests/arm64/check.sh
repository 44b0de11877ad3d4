#!/usr/bin/env bash
# `make check-arm64`: the KUnit suites and the guest tests on an arm64 test
# kernel, under qemu-system-aarch64 -machine virt -cpu max (TCG).
#
#   tests/arm64/check.sh
#
#  1. installs what it needs (tests/install-deps.sh), builds (or takes from
#     the cache) the arm64 test kernel
#     (tests/kernel/build-kernel.sh --arch arm64: test.config + arm64.config),
#  2. builds (or takes from the cache) the arm64 root (tests/arm64/mkrootfs.sh),
#  3. cross-builds the modules (W=1), the tools and the uapi check,
#  4. boots the arm64 VM (tests/vm-run --arch arm64): every KUnit suite, then
#     the guest tests,
#  5. scans the guest console for splats,
#  6. prints every skipped test with its reason (a skip that
#     tests/expected-skips does not list fails the run), the ten slowest
#     tests, the time of each phase and one line "N passed, N failed, N skipped".
#
# Left out on arm64: tests/guest/test_packaging.py and test_deb.py, whose
# modules are built by dkms on the host for the x86 test kernel
# (tests/packaging/dkms-prepare.sh, deb-prepare.sh; a dkms build inside the
# emulated guest is far too slow).
#
# Slow (every instruction is emulated), so not part of .ci/run. KVER=6.12
# is the kernel series; VM runs take the lock /work/exp/vm-arm64.lock when
# that directory exists (LEGO_ARM64_LOCK overrides it).
set -uo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"

kver=${KVER:-6.12}
build=${LEGO_BUILD_DIR:-$top/.build}
results=$build/results-arm64
console=$build/console-arm64.log
lock=${LEGO_ARM64_LOCK:-}
[ -n "$lock" ] || [ ! -d /work/exp ] || lock=/work/exp/vm-arm64.lock
# shellcheck source=tests/lib/phases.sh
. "$top/tests/lib/phases.sh"
PHASE_TITLE="Phase times (arm64)"
PHASE_FOOTER="Skipped on arm64: tests/guest/test_packaging.py, test_deb.py (their dkms build is done on the host for x86)"

# A phase whose stdout (a path) is not wanted; "==> name" still shows.
quiet() { "$@" >/dev/null; }

phase "install dependencies" tests/install-deps.sh || summary
# The Python of the tests: tests/install-deps.sh's venv (tests/lib/venv.sh).
# shellcheck source=tests/lib/venv.sh
. "$top/tests/lib/venv.sh"
lego_venv_activate "$top"
phase "arm64 test kernel $kver" quiet nice -n 15 tests/kernel/build-kernel.sh --arch arm64 "$kver" || summary
tree=$(tests/kernel/build-kernel.sh --tree-only --arch arm64 "$kver")
phase "arm64 root file system" quiet tests/arm64/mkrootfs.sh || summary
phase "modules, tools for arm64 (W=1)" env ARCH=arm64 CROSS_COMPILE=aarch64-linux-gnu- \
	tests/build-modules.sh "$tree" "$build/modules-arm64-$kver" || summary

rm -rf "$results"
mkdir -p "$results"
vm=(tests/vm-run --arch arm64 --kver "$kver" --timeout "${LEGO_ARM64_TIMEOUT:-7200}" --log "$console"
	--share "$results" -- tests/guest/run-suite.sh "$results"
	--ignore=tests/guest/test_packaging.py --ignore=tests/guest/test_deb.py tests/guest)
[ -z "$lock" ] || vm=(flock "$lock" "${vm[@]}")
PHASE_NOCOUNT=1 LEGO_VM_NO_BUILD=1 phase "arm64 VM: KUnit and guest tests" "${vm[@]}"
vm_rc=$?
phase "console splat scan" tests/scan-console.py "$console"

vm_totals "$results" "$tree" "$vm_rc"
