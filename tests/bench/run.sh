#!/usr/bin/env bash
# `make bench`: measure the drivers against their physical limits and their
# peers, and write the figures, each beside its reference, to the results file.
#
#   tests/bench/run.sh [--quick] [--debug-kernel] [--results FILE]
#
#   --quick          short runs (for trying the benchmarks out; the results file
#                    then says so)
#   --debug-kernel   run on the test kernel (KASAN, UBSAN, lockdep, kmemleak)
#                    instead of the benchmark kernel
#   --results FILE   where to write the results (default tests/bench/results.md)
#
# Steps: the protocol-core cost on the host (callgrind: deterministic), then one
# VM running the EV3 and the NXT benchmarks (tests/bench/guest-run.sh) on the
# benchmark kernel: the test kernel without its debug checks
# (tests/kernel/bench.config; built once and cached like the test kernel).
# Each benchmark writes a JSON file of figures into one directory
# (.build/bench/<time>/); tests/bench/report.py turns them into the results
# file and prints them. Timing figures depend on the machine: run it on a quiet
# one. A missed target is reported, not an error: the exit status is non-zero
# only when a benchmark could not run.
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"

quick=
variant=(--variant bench)
kernel="benchmark kernel (tests/kernel/test.config + bench.config: no KASAN, UBSAN, lockdep or kmemleak)"
results=$top/tests/bench/results.md
while [ $# -gt 0 ]; do
	case "$1" in
	--quick) quick=--quick; shift ;;
	--debug-kernel)
		variant=()
		kernel="test kernel (tests/kernel/test.config: KASAN, UBSAN, lockdep, kmemleak)"
		shift ;;
	--results) results=$2; shift 2 ;;
	-h|--help) sed -n '2,/^set -e/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
	*) echo "bench: unknown option $1 (try --help)" >&2; exit 2 ;;
	esac
done

out=${LEGO_BUILD_DIR:-$top/.build}/bench/$(date -u +%Y%m%dT%H%M%SZ)
mkdir -p "$out"
fail=0
# What the figures come from, noted before anything runs (report.py).
git describe --always --dirty > "$out/commit" 2>/dev/null || true
# The tree of drivers/ (tests/bench/stale.sh compares it with HEAD's).
if drivers=$(git rev-parse -q --verify HEAD:drivers); then
	[ -z "$(git status --porcelain -- drivers)" ] || drivers+=+changes
	echo "$drivers" > "$out/drivers"
fi
echo "$kernel" > "$out/kernel"

tests/install-deps.sh >/dev/null
# The Python of the tests: tests/install-deps.sh's venv (tests/lib/venv.sh).
# shellcheck source=tests/lib/venv.sh
. "$top/tests/lib/venv.sh"
lego_venv_activate "$top"
# The guest runs the host's binaries: the EV3 sensor streamer, the NXT client.
make -s -C tests/bench/ev3
make -s -C tests/bench/nxt
echo "==> protocol cores on the host (callgrind)"
tests/bench/proto/run.sh "$out" $quick || { echo "bench: the protocol-core benchmark failed" >&2; fail=1; }

echo "==> the test VM: EV3 and NXT benchmarks"
# One guest CPU, as the figures in results.md were measured (and as the EV3
# brick has): the sensors' emulators then compete with the driver for it.
# LEGO_VM_SMP=2 measures on two.
export LEGO_VM_SMP=${LEGO_VM_SMP:-1}
if ! tests/vm-run "${variant[@]}" --timeout 2400 --log "$out/console.log" --share "$out" -- \
	tests/bench/guest-run.sh "$out" $quick; then
	echo "bench: the VM benchmarks failed (console: $out/console.log)" >&2
	fail=1
fi
tests/scan-console.py "$out/console.log" || fail=1

python3 tests/bench/report.py --out "$results" $quick "$out" || fail=1
echo "bench: figures in $out, results file $results"
exit $fail
