# shellcheck shell=bash
# Timed phases and the closing "N passed, N failed, N skipped" line, shared
# by tests/check.sh and tests/arm64/check.sh (source this file).
#
#   phase NAME CMD...   runs CMD, records its time; a failure counts once
#                       unless PHASE_NOCOUNT is set (the VM phase, whose
#                       failures are counted from its results)
#   pytest_phase NAME XML PYTEST_ARGS...   a phase running pytest on the
#                       host, its results in the JUnit XML file XML (for
#                       summarize.py: RESULTS/host-NAME.xml); its failures
#                       are counted from XML, a run that failed with no
#                       failed test in XML counts once
#   summary [PASSED [FAILED [SKIPPED]]]   prints the phase times and exits 0 only
#                       if nothing failed; PHASE_TITLE names the table,
#                       PHASE_FOOTER is printed under it
#   beside_start LOG FUNC   runs FUNC (which calls phase) in the background
#                       at nice 19 and idle I/O priority, its output to LOG:
#                       the host's phases that the VM does not need run
#                       beside it, in the time the emulated guest leaves idle
#   beside_wait         waits for it, prints LOG and adds its phases, marked
#                       "(beside)", to the table and its failures to the count
#   vm_totals RESULTS TREE VM_RC   summarizes the results (tests/summarize.py:
#                       the VM's, the host's pytest phases', the skips, the
#                       slowest tests) and calls summary with their counts

phase_names=()
phase_times=()
phase_fail=0
phase_failed=()

phase() {
	local name=$1
	shift
	local t0=$SECONDS
	echo "==> $name"
	"$@"
	local rc=$?
	phase_names+=("$name")
	phase_times+=("$((SECONDS - t0))")
	if [ $rc -ne 0 ]; then
		echo "==> $name FAILED (exit $rc)"
		[ -n "${PHASE_NOCOUNT:-}" ] || {
			phase_fail=$((phase_fail + 1))
			phase_failed+=("phase: $name (exit $rc)")
		}
	fi
	return $rc
}

pytest_phase() {
	local name=$1 xml=$2 rc
	shift 2
	rm -f "$xml"
	PHASE_NOCOUNT=1 phase "$name" python3 -m pytest -q -p no:cacheprovider \
		-W error::pytest.PytestUnhandledThreadExceptionWarning --junitxml="$xml" "$@"
	rc=$?
	if [ $rc -ne 0 ] && ! grep -qs -e '<failure' -e '<error' "$xml"; then
		phase_fail=$((phase_fail + 1))
		phase_failed+=("phase: $name (exit $rc, no test failed)")
	fi
	return $rc
}

summary() {
	local passed=${1:-0} failed=${2:-0} skipped=${3:-0} i
	echo
	echo "${PHASE_TITLE:-Phase times}:"
	for i in "${!phase_names[@]}"; do
		printf '  %-34s %5s s\n' "${phase_names[$i]}" "${phase_times[$i]}"
	done
	printf '  %-34s %5s s\n' "total" "$SECONDS"
	[ -z "${PHASE_FOOTER:-}" ] || echo "$PHASE_FOOTER"
	# What failed, again at the end: CI keeps only the log's tail.
	if [ ${#phase_failed[@]} -gt 0 ] || [ -s "${PHASE_FAILURES:-/nonexistent}" ]; then
		echo "Failed:"
		for i in "${phase_failed[@]}"; do
			echo "  $i"
		done
		[ -z "${PHASE_FAILURES:-}" ] || sed 's/^/  /' "$PHASE_FAILURES" 2>/dev/null
	fi
	failed=$((failed + phase_fail))
	echo "$passed passed, $failed failed, $skipped skipped"
	[ "$failed" -eq 0 ]
	exit $?
}

beside_start() {
	beside_log=$1
	rm -f "$beside_log" "$beside_log.phases" "$beside_log.failed" "$beside_log.names"
	(
		renice -n 19 -p "$BASHPID" >/dev/null
		ionice -c 3 -p "$BASHPID" 2>/dev/null
		phase_names=()
		phase_times=()
		phase_fail=0
		"$2"
		for i in "${!phase_names[@]}"; do
			printf '%s (beside)\t%s\n' "${phase_names[$i]}" "${phase_times[$i]}"
		done > "$beside_log.phases"
		echo "$phase_fail" > "$beside_log.failed"
		for i in "${phase_failed[@]}"; do
			echo "$i"
		done > "$beside_log.names"
	) > "$beside_log" 2>&1 &
	beside_pid=$!
}

beside_wait() {
	local name t n
	wait "$beside_pid"
	echo "==> the phases beside the VM (log: $beside_log)"
	cat "$beside_log"
	if [ -f "$beside_log.phases" ]; then
		while IFS=$'\t' read -r name t; do
			phase_names+=("$name")
			phase_times+=("$t")
		done < "$beside_log.phases"
	fi
	read -r n < "$beside_log.failed" 2>/dev/null || {
		n=1
		phase_failed+=("phase: the phases beside the VM (no result)")
	}
	phase_fail=$((phase_fail + n))
	if [ -f "$beside_log.names" ]; then
		while IFS= read -r name; do
			phase_failed+=("$name (beside)")
		done < "$beside_log.names"
	fi
}

# Test failures in the VM are counted from its results; only a VM that
# failed with no failed test (a crash, a timeout) counts as one more failure.
# An unexpected skip counts as a failure (summarize.py).
vm_totals() {
	local results=$1 tree=$2 vm_rc=$3 passed failed skipped
	rm -f "$results/totals" "$results/failures"
	python3 tests/summarize.py "$results" "$tree"
	read -r passed failed skipped < "$results/totals" 2>/dev/null || { passed=0; failed=1; skipped=0; }
	if [ "$vm_rc" -ne 0 ] && [ "$failed" -eq 0 ]; then
		phase_fail=$((phase_fail + 1))
		phase_failed+=("VM exited $vm_rc with no failed test (crash or timeout: see the console log)")
	fi
	PHASE_FAILURES="$results/failures" summary "$passed" "$failed" "$skipped"
}
