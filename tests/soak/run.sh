#!/usr/bin/env bash
# `make soak`: the robustness soak in the test VM (KASAN, UBSAN, lockdep,
# kmemleak), then a scan of the guest console for splats.
#
# Usage: tests/soak/run.sh [--short] [SOAK.PY OPTIONS...]
#   --short   a few dozen cycles of each part, 60 s of streams (< 5 min);
#             without it the full soak (about 75 minutes of VM time)
# Other options go to tests/soak/soak.py (e.g. --parts 1,4; see its --help).
# Output: .build/soak/ (console.log, results.json); exit 0 only if every part
# passed, kmemleak found no leak and the console has no splat.
set -uo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"
out=${LEGO_BUILD_DIR:-$top/.build}/soak
rm -rf "$out"
mkdir -p "$out"
console=$out/console.log
t0=$SECONDS
# The full soak takes about 75 minutes under TCG; leave room for a slow host.
tests/vm-run --timeout 9000 --log "$console" --share "$out" -- \
	python3 tests/soak/soak.py --json "$out/results.json" "$@"
rc=$?
vm_s=$((SECONDS - t0))
tests/scan-console.py "$console"
scan=$?
echo "soak: VM time ${vm_s} s (boot included); soak exit $rc, console scan exit $scan"
echo "soak: console in $console, results in $out/results.json"
if [ $rc -ne 0 ] || [ $scan -ne 0 ]; then
	echo "soak: FAILED"
	exit 1
fi
echo "soak: passed"
