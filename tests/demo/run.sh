#!/usr/bin/env bash
# `make demo`: build what is missing, boot the test VM with four emulated EV3
# sensors and an emulated NXT brick, and show what a user would see
# (tests/demo/demo.py runs in the guest). Exits non-zero if any step fails or
# the guest kernel logged a splat.
#
# The guest's own kernel messages are kept out of the way: they go to
# .build/demo-console.log, and the demo prints the drivers' lines itself.
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
cd "$top"
build=${LEGO_BUILD_DIR:-$top/.build}
log=$build/demo-console.log
mkdir -p "$build"

t0=$SECONDS
echo "==> [1/4] packages (Debian and PyPI; nothing to do when all are there)"
tests/install-deps.sh
# The Python of the tests: tests/install-deps.sh's venv (tests/lib/venv.sh).
# shellcheck source=tests/lib/venv.sh
. "$top/tests/lib/venv.sh"
lego_venv_activate "$top"
# The newest kernel source Debian serves (KVER= picks another series).
read -r kver _ < <(tests/kernel/fetch-source.sh "${KVER:-newest}")
echo "==> [2/4] the $kver test kernel (cached; the first build takes 5-20 minutes on 2 cores: a dot a minute)"
tree=$(tests/kernel/build-kernel.sh "$kver")
echo "    $tree"
echo "==> [3/4] the modules and tools against it"
tests/build-modules.sh "$tree" "$build/modules-$kver"
echo "==> [4/4] booting the test VM (QEMU, no KVM: about a minute) and running the demo"
set +e
LEGO_VM_NO_BUILD=1 tests/vm-run --kver "$kver" --timeout 900 --log "$log" -- \
	python3 tests/demo/demo.py |
	sed -u -e 's/\r$//; s/\x1b\[[0-9;?]*[a-zA-Z]//g; s/\x1bc//g' |
	grep -a --line-buffered -v -E '^\[ *[0-9]+\.[0-9]+\]|^(SeaBIOS|Booting from)'
rc=${PIPESTATUS[0]}
set -e
if ! tests/scan-console.py "$log" >/dev/null; then
	tests/scan-console.py "$log" || true
	echo "make demo: the guest kernel logged a splat (console: $log)" >&2
	rc=1
fi
echo "make demo: $((SECONDS - t0)) s; guest console in $log"
exit "$rc"
