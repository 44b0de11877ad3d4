#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-2.0
#
# `make fuzz`: build the libFuzzer targets (tests/fuzz/fuzz_ev3.c,
# fuzz_nxt.c) from the driver sources, run the two cores' KUnit suites in
# userspace (ASan, UBSan), replay the committed seeds and regression
# inputs, then fuzz each target for a fixed time (both at once,
# one a core) and report its executions, exec/s, coverage and any crash or
# sanitizer report.
#
#   tests/fuzz/run.sh [--seconds N] [--short] [--target-execs N] [TARGET...]
#
#   --seconds N       fuzz each target N seconds (default: EV3 and NXT times
#                     that reach 10 million executions each with a margin,
#                     see Documentation/lego/fuzzing.rst)
#   --short           30 s each, no execution target (make check)
#   --target-execs N  executions each target must reach (default 10000000;
#                     0 for none); not checked with --short
#   TARGET            ev3, nxt (default both)
#
# The corpus each target grows is kept between runs in the cache,
# ~/.cache/lego-mindstorms-linux/fuzz-corpus-TARGET (LEGO_CACHE moves it;
# delete it to start again from the committed seeds alone).
#
# Exits 1 on a crash, sanitizer report or failed invariant (the input is
# kept in .build/fuzz/artifacts/), on fewer executions than the target, or
# on a build, KUnit or replay failure. Each target's log is
# .build/fuzz/TARGET.log.
set -uo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"

out=${LEGO_BUILD_DIR:-$top/.build}/fuzz
# shellcheck source=tests/kernel/lib.sh
. "$top/tests/kernel/lib.sh"
cache=$(kcache_dir)
seconds=
short=
target_execs=10000000
targets=()
# 10 million executions with a margin on one core of the development
# machine (ev3: about 13000/s with the core to itself, 7400/s when heavily
# loaded; nxt: 70000/s loaded): see Documentation/lego/fuzzing.rst.
declare -A default_seconds=([ev3]=1500 [nxt]=240)

usage() {
	sed -n '4,24p' "$0" | sed 's/^# \{0,1\}//'
	exit 2
}

while [ $# -gt 0 ]; do
	case $1 in
	--seconds) seconds=${2:?}; shift 2 ;;
	--short) short=1; shift ;;
	--target-execs) target_execs=${2:?}; shift 2 ;;
	ev3|nxt) targets+=("$1"); shift ;;
	-h|--help) usage ;;
	*) echo "run.sh: unknown argument: $1" >&2; usage ;;
	esac
done
[ ${#targets[@]} -gt 0 ] || targets=(ev3 nxt)
if [ -n "$short" ]; then
	seconds=${seconds:-30}
	target_execs=0
fi

command -v clang-14 >/dev/null || { echo "run.sh: clang-14 not found (tests/install-deps.sh)" >&2; exit 1; }
mkdir -p "$out/artifacts"
if ! make -s -C tests/fuzz O="$out" fuzz replay kunit; then
	echo "run.sh: build failed" >&2
	exit 1
fi

fail=0
# The cores' KUnit suites in userspace, under ASan and UBSan.
for t in "${targets[@]}"; do
	if ! "$out/kunit_$t" >"$out/kunit_$t.log" 2>&1; then
		grep -vE '^ok ' "$out/kunit_$t.log" >&2
		echo "run.sh: the KUnit suite failed in userspace (kunit_$t)" >&2
		fail=1
	else
		tail -n 1 "$out/kunit_$t.log"
	fi
done
# The committed seeds and regression inputs, through the replay builds.
for t in "${targets[@]}"; do
	dirs=(tests/fuzz/corpus/"$t")
	[ -d tests/fuzz/regressions/"$t" ] && dirs+=(tests/fuzz/regressions/"$t")
	if ! "$out/replay_$t" "${dirs[@]}"; then
		echo "run.sh: replay of the $t seeds failed" >&2
		fail=1
	fi
done

# Both targets at once, one a core (the machine this was written for has
# two); each alone with a single target argument.
declare -A pids secs_of
touch "$out/.run-start"
for t in "${targets[@]}"; do
	secs=${seconds:-${default_seconds[$t]}}
	secs_of[$t]=$secs
	corpus=$cache/fuzz-corpus-$t
	mkdir -p "$corpus" || exit 1
	echo "$t: corpus $corpus: $(find "$corpus" -type f | wc -l) inputs from earlier runs"
	dict=()
	[ -f tests/fuzz/"$t".dict ] && dict=(-dict=tests/fuzz/"$t".dict)
	"$out/fuzz_$t" -max_total_time="$secs" -print_final_stats=1 -seed=1 \
		-max_len=1024 -timeout=10 -rss_limit_mb=1024 "${dict[@]}" \
		-artifact_prefix="$out/artifacts/$t-" "$corpus" tests/fuzz/corpus/"$t" \
		>"$out/$t.log" 2>&1 &
	pids[$t]=$!
done

report=$out/summary.txt
printf '%-5s %8s %12s %10s %6s %7s %7s %s\n' target seconds executions exec/s cov ft corpus result | tee "$report"
for t in "${targets[@]}"; do
	wait "${pids[$t]}"
	rc=$?
	log=$out/$t.log
	execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
	rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
	cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
	ft=$(grep -o 'ft: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
	result=ok
	if [ $rc -ne 0 ] || grep -qE 'ERROR: (libFuzzer|AddressSanitizer|LeakSanitizer)|runtime error:|invariant failed|^WARNING at' "$log"; then
		result="CRASH (exit $rc)"
		fail=1
	elif [ "$target_execs" -gt 0 ] && [ "${execs:-0}" -lt "$target_execs" ]; then
		result="too few executions (target $target_execs)"
		fail=1
	fi
	printf '%-5s %8s %12s %10s %6s %7s %7s %s\n' "$t" "${secs_of[$t]}" "${execs:-?}" "${rate:-?}" \
		"${cov:-?}" "${ft:-?}" "$(find "$cache/fuzz-corpus-$t" -type f | wc -l)" "$result" | tee -a "$report"
	if [ "${result#CRASH}" != "$result" ]; then
		echo "--- $t: report (full log: $log)"
		grep -E -B2 -A25 'ERROR: |runtime error:|invariant failed|^WARNING at' "$log" | head -n 60
		find "$out/artifacts" -name "$t-*" -newer "$out/.run-start" | sed 's/^/input kept: /'
	fi
done
exit $fail
