# shellcheck shell=bash
# Timed phases and the closing "N passed, N failed" line, shared by
# tests/check.sh and tests/arm64/check.sh (source this file).
#
#   phase NAME CMD...   runs CMD, records its time; a failure counts once
#                       unless PHASE_NOCOUNT is set (the VM phase, whose
#                       failures are counted from its results)
#   summary [PASSED [FAILED]]   prints the phase times and exits 0 only
#                       if nothing failed; PHASE_TITLE names the table,
#                       PHASE_FOOTER is printed under it
#   vm_totals RESULTS TREE VM_RC   summarizes the VM's results and calls
#                       summary with its counts

phase_names=()
phase_times=()
phase_fail=0

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
		[ -n "${PHASE_NOCOUNT:-}" ] || phase_fail=$((phase_fail + 1))
	fi
	return $rc
}

summary() {
	local passed=${1:-0} failed=${2:-0} i
	echo
	echo "${PHASE_TITLE:-Phase times}:"
	for i in "${!phase_names[@]}"; do
		printf '  %-34s %5s s\n' "${phase_names[$i]}" "${phase_times[$i]}"
	done
	printf '  %-34s %5s s\n' "total" "$SECONDS"
	[ -z "${PHASE_FOOTER:-}" ] || echo "$PHASE_FOOTER"
	failed=$((failed + phase_fail))
	echo "$passed passed, $failed failed"
	[ "$failed" -eq 0 ]
	exit $?
}

# Test failures in the VM are counted from its results; only a VM that
# failed with no failed test (a crash, a timeout) counts as one more failure.
vm_totals() {
	local results=$1 tree=$2 vm_rc=$3 passed failed
	python3 tests/summarize.py "$results" "$tree" || phase_fail=$((phase_fail + 1))
	read -r passed failed _ < "$results/totals" 2>/dev/null || { passed=0; failed=1; }
	[ "$vm_rc" -ne 0 ] && [ "$failed" -eq 0 ] && phase_fail=$((phase_fail + 1))
	summary "$passed" "$failed"
}
