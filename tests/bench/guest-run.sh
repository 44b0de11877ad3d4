#!/usr/bin/env bash
# Run in the test VM by tests/bench/run.sh: each guest benchmark in turn,
# writing its JSON into OUTDIR. Usage: tests/bench/guest-run.sh OUTDIR [--quick]
set -uo pipefail
out=$1
shift
cd "$(dirname "$0")/../.."
rc=0
for b in ev3_bench ev3_profile nxt_bench nxt_bt_bench; do
	echo "==> $b"
	t0=$SECONDS
	python3 "tests/bench/guest/$b.py" --out "$out" "$@" || { echo "bench: $b failed"; rc=1; }
	echo "==> $b took $((SECONDS - t0)) s"
done
exit $rc
