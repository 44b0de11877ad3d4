#!/usr/bin/env bash
# `make check`: the project's one test command.
#
#  1. installs what it needs (Debian packages, and PyPI packages in a
#     virtual environment whose python3 runs the tests: tests/lib/venv.sh),
#  2. builds (or takes from the cache) the test kernel of the newest
#     linux-source-X.Y that Debian serves (tests/kernel/fetch-source.sh),
#  3. builds the modules against it with W=1 and sparse, against a prepared
#     6.12 tree and the 6.1 headers, then cross-compiles them and the tools
#     for arm64 and armhf (tests/cross-build.sh),
#  4. runs checkpatch --strict, a short fuzzing run of the protocol cores
#     (tests/fuzz/run.sh --short), the packaging tests of tests/packaging,
#     the emulators' and the harness's own tests (tests/emulator, tests/lib),
#     the in-tree series' rules (tests/upstream/test_intree.py) and the
#     series' quick checks (tests/upstream/check.sh without its builds), and
#     dkms (on the host) for the guest's packaging test, `make deb` (with
#     lintian) and the packages installed in a Debian root (on the host)
#     for tests/packaging/test_deb.py and the guest's tests/guest/test_deb.py,
#  5. boots the test VM: every KUnit suite, then the guest tests; the
#     phases of 3 and 4 that the VM does not need (all but the modules for
#     the test kernel, the fuzzers, dkms and the packages) run beside it at
#     nice 19, their output printed when the VM is done,
#  6. scans the guest console for splats, and checks which of the drivers'
#     functions the tests reached (tests/coverage.py, tests/coverage-allow.txt),
#  7. prints every skipped test with its reason (a skip that
#     tests/expected-skips does not list fails the run), the ten slowest
#     tests, whether tests/bench/results.md was measured on other driver
#     code than HEAD's, the time of each phase and one line
#     "N passed, N failed, N skipped" (KUnit, guest and host pytest tests).
#
# KVER is the test kernel's series: newest (default), or 6.12, 6.1, any X.Y
# Debian serves; every phase runs against it. LEGO_CACHE moves the kernel
# cache.
set -uo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
cd "$top" || exit 1

kver=${KVER:-newest}
build=${LEGO_BUILD_DIR:-$top/.build}
results=$build/results
console=$build/console.log
# shellcheck source=tests/lib/phases.sh
. "$top/tests/lib/phases.sh"
# shellcheck source=tests/kernel/lib.sh
. "$top/tests/kernel/lib.sh"          # kcache_dir
# KUnit's and the guest's results (the VM writes them), the host's pytest
# phases' JUnit XML (host-*.xml): tests/summarize.py counts them all.
rm -rf "$results"
mkdir -p "$results"

# A full disk fails a run late and obscurely (a JUnit file cut short, a
# patch that does not apply): below what a run writes into $build (2.1 GB,
# most of it the upstream series' kernel worktree), say so before anything.
need_mb=3072
free_mb=$(df -Pm "$build" | awk 'NR == 2 { print $4 }')
echo "make check: ${free_mb} MB free for $build (a run writes about 2.1 GB there;" \
	"a cold kernel cache, $(kcache_dir), takes about 9 GB more)"
if [ "${free_mb:-0}" -lt "$need_mb" ]; then
	echo "make check: FAILED, less than $need_mb MB free for $build" >&2
	exit 1
fi

# The steps of tests/upstream/check.sh that take no kernel build.
upstream_quick=(series am checkpatch kernel-doc refs abi headers coccicheck htmldocs lego-docs)

newest_61_headers() {
	ls -d /usr/src/linux-headers-6.1.*-amd64 2>/dev/null | sort -V | tail -n 1
}

# modules_other SERIES: the modules against a prepared x86 tree of SERIES,
# a series the VM does not boot.
modules_other() {
	local t
	t=$(tests/kernel/build-cross-tree.sh x86 "$1") || return 1
	tests/build-modules.sh --sparse "$t" "$build/modules-$1-tree"
}

phase "install dependencies" tests/install-deps.sh || summary
# The Python of the tests: tests/install-deps.sh's venv (tests/lib/venv.sh).
# shellcheck source=tests/lib/venv.sh
. "$top/tests/lib/venv.sh"
lego_venv_activate "$top"
phase "kernel source: $kver" tests/kernel/fetch-source.sh "$kver" || summary
read -r kver _ < <(tests/kernel/fetch-source.sh "$kver")
phase "test kernel $kver" tests/kernel/build-kernel.sh "$kver" >/dev/null || summary
tree=$(tests/kernel/build-kernel.sh --tree-only "$kver")
phase "modules for $kver (W=1, sparse)" tests/build-modules.sh --sparse "$tree" "$build/modules-$kver" || summary
# The EV3 driver without its lego-sensor class (LEGO_EV3_CLASS=n, the
# in-tree series' LEGO_EV3_UART_CLASS=n): it builds, links, and still
# keeps its layering; tests/guest/test_ev3_no_class.py runs it.
modules_no_class() {
	local out="$build/modules-$kver-no-class"
	rm -rf "$out"
	LEGO_EV3_CLASS=n tests/build-modules.sh --sparse "$tree" "$out" || return
	if [ -e "$out/drivers/lego/ev3/ev3_uart_class.o" ]; then
		echo "modules_no_class: ev3_uart_class.o was built" >&2
		return 1
	fi
	tests/layering/check.py "$out" --driver ev3
}

# One-way layering, read from the objects of both drivers: no circle, no
# view using its transport, no function over 60 lines.
phase "layering: EV3 and NXT objects (nm)" tests/layering/check.py "$build/modules-$kver"
# Before the VM: tests/guest/test_ev3_no_class.py loads it.
phase "modules for $kver, no lego-sensor class (W=1, sparse)" modules_no_class
# The host's own phases, which the VM does not need: they run beside it
# (beside_start, at nice 19), in the time the emulated guest leaves idle
# waiting on its 2400-baud handshakes and its timers.
host_phases() {
	[ "$kver" = 6.12 ] || phase "modules, 6.12 tree (W=1, sparse)" modules_other 6.12
	h61=$(newest_61_headers)
	phase "modules, 6.1 headers (W=1, sparse)" tests/build-modules.sh --sparse "$h61" "$build/modules-6.1-headers"
	phase "cross: arm64, armhf (W=1, sparse)" tests/cross-build.sh "$build"
	phase "checkpatch --strict" env CHECKPATCH="$tree/scripts/checkpatch.pl" tests/checkpatch.sh
	# install-deps.sh (Debian packages) in a clean Debian 12 root, with
	# coccicheck's semantic patches that have scripts; cached per inputs.
	phase "install-deps in a clean Debian 12 root" tests/packaging/clean-root.sh
	LEGO_KERNEL_TREE="$tree" LEGO_DEB_ROOT="$build/deb-root-$kver.tar" \
		pytest_phase "make install, dkms-source, deb (host)" \
		"$results/host-packaging.xml" tests/packaging
	LEGO_KERNEL_TREE="$tree" pytest_phase "emulators, harness (host)" \
		"$results/host-emulator.xml" tests/emulator tests/lib tests/layering
	pytest_phase "upstream series: in-tree rules (host)" "$results/host-upstream.xml" tests/upstream
	# The in-tree series' quick checks (about 2 minutes cold, 1 warm); the
	# kernel builds and kunit.py runs are `make upstream-check`'s.
	phase "upstream series: git am, checkpatch, docs" env LEGO_UPSTREAM_OUT="$build/upstream" \
		tests/upstream/check.sh "$kver" "${upstream_quick[@]}"
}

# Before the VM: what it needs, and the fuzzers, whose runs are timed and
# would do less work at nice 19.
phase "fuzz (short, 2 x 30 s)" tests/fuzz/run.sh --short
# For tests/guest/test_packaging.py: a dkms build in the emulated guest is slow.
phase "dkms build for $kver (host)" tests/packaging/dkms-prepare.sh "$tree" "$build/dkms-$kver"
# For tests/packaging/test_deb.py and tests/guest/test_deb.py: the
# packages, installed in a private root (DKMS, dpkg: too slow in the guest).
phase "make deb, lintian" make -s deb DEB_OUT="$build/deb" DEB_LINTIAN=1
phase "deb: packages in a Debian root for $kver (host)" tests/packaging/deb-prepare.sh "$tree" \
	"$build/deb" "$build/deb-root-$kver.tar"

# The guest's python3 writes no bytecode (PYTHONDONTWRITEBYTECODE: its root
# is the host's, read-only), so every import compiled the tests' modules
# again under emulation. Compiled here (pytest's rewritten test modules by a
# collection), by the same interpreter, the guest reads them.
guest_bytecode() {
	env -u PYTHONDONTWRITEBYTECODE python3 -m compileall -q tests tools/python &&
		env -u PYTHONDONTWRITEBYTECODE python3 -m pytest --collect-only -q \
			-p no:cacheprovider tests/guest >/dev/null
}
phase "python bytecode for the guest" guest_bytecode

beside_start "$build/beside.log" host_phases

# The guest suite takes 26 to 29 minutes on a loaded 2-core host before the
# tests of issue 18 (nxtctl's command line, lego-sensors, examples, the
# Debian packages) added about ten: vm-run's default 1800 s is too short.
PHASE_NOCOUNT=1 LEGO_VM_NO_BUILD=1 phase "VM: KUnit and guest tests" \
	tests/vm-run --timeout 3600 --kver "$kver" --log "$console" --share "$results" -- \
	tests/guest/run-suite.sh "$results" tests/guest
vm_rc=$?
beside_wait
phase "console splat scan" tests/scan-console.py "$console"
# Which of the drivers' functions the suite reached (the test kernel has
# gcov: tests/coverage.py): one that no test reaches fails the run unless
# tests/coverage-allow.txt names it with the reason. The whole report is in
# .build/coverage.txt (`make coverage` prints it).
coverage_check() {
	python3 tests/coverage.py --check tests/coverage-allow.txt "$results/gcov" > "$build/coverage.txt"
	local rc=$?
	grep -E '^(total|coverage):' "$build/coverage.txt"
	return $rc
}
phase "coverage of drivers/lego" coverage_check

PHASE_FOOTER=$(tests/bench/stale.sh)
vm_totals "$results" "$tree" "$vm_rc"
