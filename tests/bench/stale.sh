#!/usr/bin/env bash
# tests/bench/stale.sh [RESULTS_MD]: print a notice when
# tests/bench/results.md was measured on other driver code than HEAD's: its
# "Driver code: tree" line (tests/bench/report.py), or the tree of drivers/
# at its "Commit" if it has none, against
# `git rev-parse HEAD:drivers`. make check prints it under its phase times.
# Prints nothing when they match; never fails.
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top" || exit 0
res=${1:-tests/bench/results.md}
now=$(git rev-parse -q --verify HEAD:drivers 2>/dev/null) || exit 0
[ -f "$res" ] || { echo "Notice: no $res (make bench writes it)"; exit 0; }
measured=$(sed -n 's/^Driver code: tree `\([^`]*\)`.*/\1/p' "$res" | head -n 1)
commit=$(sed -n 's/^Commit `\([0-9a-f]*\).*/\1/p' "$res" | head -n 1)
if [ -z "$measured" ] || [ "$measured" = unknown ]; then
	measured=
	[ -z "$commit" ] || measured=$(git rev-parse -q --verify "$commit:drivers" 2>/dev/null)
fi
if [ -z "$measured" ]; then
	echo "Notice: $res does not say which driver code it was measured on (make bench)"
	exit 0
fi
[ "$measured" = "$now" ] && exit 0
since=
if [ -n "$commit" ] && git cat-file -e "$commit^{commit}" 2>/dev/null; then
	since="; $(git rev-list --count "$commit..HEAD" -- drivers) commits to drivers/ since $commit"
fi
shown=${measured:0:12}
[ "${measured%+changes}" = "$measured" ] || shown+=" with uncommitted changes"
echo "Notice: $res was measured on other driver code than HEAD's" \
	"(drivers/ tree $shown, HEAD's ${now:0:12}$since): make bench measures it again"
exit 0
