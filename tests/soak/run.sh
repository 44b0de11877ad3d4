#!/usr/bin/env bash
# `make soak`: the robustness soak in the test VM (KASAN, UBSAN, lockdep,
# kmemleak), then a scan of the guest console for splats.
#
# Usage: tests/soak/run.sh [--short] [--no-kcsan] [SOAK.PY OPTIONS...]
#   --short     a few dozen cycles of each part, 60 s of streams, a few
#               hundred fuzz cases (about 15 min); without it the full soak
#               (hours: 10,000 EV3 cases and 10,000 NXT sequences among
#               the parts, see Documentation/lego/soak.rst)
#   --no-kcsan  skip the second pass on the KCSAN kernel
# Other options go to tests/soak/soak.py (e.g. --parts 1,4; see its --help).
#
# Two passes: the soak on the test kernel (KASAN, UBSAN, lockdep, kmemleak),
# then its short version on the KCSAN kernel (build-kernel.sh --variant
# kcsan: KCSAN, UBSAN, lockdep; built and cached on first use), whose
# console fails the run for any KCSAN report in our code
# (tests/scan-console.py --kcsan-ours). LEGO_KCSAN_ARGS replaces the
# options of the second pass (default: --short --no-kmemleak).
# Output: .build/soak/ (console.log, results.json, console-kcsan.log,
# results-kcsan.json); exit 0 only if every part passed, kmemleak found no
# leak and neither console has a splat.
set -uo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"
out=${LEGO_BUILD_DIR:-$top/.build}/soak
rm -rf "$out"
mkdir -p "$out"
console=$out/console.log
t0=$SECONDS
kcsan=1
args=()
for a in "$@"; do
	if [ "$a" = --no-kcsan ]; then kcsan=0; else args+=("$a"); fi
done
# The Python of the tests: tests/install-deps.sh's venv (tests/lib/venv.sh).
# shellcheck source=tests/lib/venv.sh
. "$top/tests/lib/venv.sh"
lego_venv_activate "$top"
# The full soak takes hours under TCG; leave room for a slow host.
tests/vm-run --timeout 21600 --log "$console" --share "$out" -- \
	python3 tests/soak/soak.py --json "$out/results.json" "${args[@]}"
rc=$?
vm_s=$((SECONDS - t0))
tests/scan-console.py "$console"
scan=$?
echo "soak: VM time ${vm_s} s (boot included); soak exit $rc, console scan exit $scan"
echo "soak: console in $console, results in $out/results.json"
krc=0
kscan=0
if [ $kcsan = 1 ]; then
	t1=$SECONDS
	read -r -a kargs <<< "${LEGO_KCSAN_ARGS:---short --no-kmemleak}"
	tests/vm-run --variant kcsan --timeout 5400 --log "$out/console-kcsan.log" \
		--share "$out" -- python3 tests/soak/soak.py \
		--json "$out/results-kcsan.json" "${kargs[@]}"
	krc=$?
	tests/scan-console.py --kcsan-ours "$out/console-kcsan.log"
	kscan=$?
	echo "soak: KCSAN pass: VM time $((SECONDS - t1)) s; soak exit $krc, console scan exit $kscan"
fi
if [ $rc -ne 0 ] || [ $scan -ne 0 ] || [ $krc -ne 0 ] || [ $kscan -ne 0 ]; then
	echo "soak: FAILED"
	exit 1
fi
echo "soak: passed"
