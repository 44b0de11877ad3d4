#!/bin/sh
# Runs inside the test VM (through tests/vm-run) for `make check`:
#   1. loads every KUnit module and saves each suite's KTAP results,
#   2. runs the guest integration tests with pytest,
#   3. saves the gcov data of the modules (gcov_persist keeps what modules
#      unloaded since had counted) for tests/coverage.py,
#   4. asks kmemleak for a scan.
# Usage: tests/guest/run-suite.sh OUTDIR [PYTEST ARGS...]
out=$1
shift
mkdir -p "$out/kunit"
rc=0

suites() {
	ls /sys/kernel/debug/kunit 2>/dev/null | sort
}

# kmemleak scans on its own a minute after boot and every ten minutes
# after, for tens of seconds under emulation: a test running then saw the
# discipline's keep-alives 15 ms late on average (median period 114.8 ms
# at 673 s of uptime, twice in a row; the same test passed at 963 s).
# Leaks are found by the scans the tests ask for and the two at the end.
if [ -w /sys/kernel/debug/kmemleak ]; then
	echo scan=off > /sys/kernel/debug/kmemleak
fi

echo "=== KUnit"
kos=$(find "$LEGO_BUILD" -name '*_test.ko' | sort)
if [ -z "$kos" ]; then
	echo "run-suite: no KUnit module was built"
	echo "no KUnit module in $LEGO_BUILD" >> "$out/kunit/failed-modules"
	rc=1
fi
for ko in $kos; do
	before=$(suites)
	if ! insmod "$ko"; then
		echo "run-suite: insmod $ko failed"
		echo "$ko" >> "$out/kunit/failed-modules"
		rc=1
		continue
	fi
	added=$(suites | grep -vxF "$before")
	if [ -z "$added" ]; then
		echo "run-suite: $ko registered no KUnit suite"
		echo "$ko" >> "$out/kunit/failed-modules"
		rc=1
	fi
	for s in $added; do
		cat "/sys/kernel/debug/kunit/$s/results" > "$out/kunit/$s.ktap"
	done
	rmmod "$ko" || rc=1
done

echo "=== guest tests"
# No pytest plugin is installed for the guest tests: without the search for
# plugins among every installed distribution's metadata (hundreds of small
# files over 9p), pytest starts ten seconds sooner under emulation.
# An exception that ends an emulator's thread fails the test it came in.
PYTEST_DISABLE_PLUGIN_AUTOLOAD=1 python3 -m pytest -p no:cacheprovider --color=no -v \
	-W error::pytest.PytestUnhandledThreadExceptionWarning \
	--junitxml="$out/guest.xml" "$@" || rc=1

echo "=== coverage"
# The kernel's gcov (CONFIG_GCOV_KERNEL) has a .gcda file for each object
# of the modules, under the object's build path; copied as they are, at
# their path below LEGO_BUILD, into OUTDIR/gcov (and that path into
# OUTDIR/gcov/BUILD).
gcov=/sys/kernel/debug/gcov$LEGO_BUILD
rm -rf "$out/gcov"
if [ -d "$gcov" ]; then
	mkdir -p "$out/gcov"
	n=0
	for f in $(cd "$gcov" && find . -name '*.gcda'); do
		mkdir -p "$out/gcov/${f%/*}"
		cat "$gcov/$f" > "$out/gcov/$f" || rc=1
		n=$((n + 1))
	done
	echo "$LEGO_BUILD" > "$out/gcov/BUILD"
	echo "run-suite: gcov data of $n objects saved in $out/gcov"
fi

echo "=== kmemleak"
if [ -w /sys/kernel/debug/kmemleak ]; then
	# Two scans: kmemleak reports an object only once it has been seen
	# unreferenced in more than one scan.
	echo scan > /sys/kernel/debug/kmemleak
	sleep 6
	echo scan > /sys/kernel/debug/kmemleak
	cat /sys/kernel/debug/kmemleak
fi
exit $rc
