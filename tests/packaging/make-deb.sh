#!/usr/bin/env bash
# `make deb`: the Debian packages of debian/, built with dpkg-buildpackage
# from a copy of the tree (the build leaves objects and debian/ output
# beside the sources), into OUTDIR (default .build/deb); with --lintian (make
# deb DEB_LINTIAN=1, as make check does), lintian on them: a warning fails.
#
#   tests/packaging/make-deb.sh [--lintian] [OUTDIR]
#
# Needs dpkg-dev, debhelper, dh-dkms, dh-python, pybuild-plugin-pyproject
# and python3-all, and lintian for --lintian (tests/install-deps.sh installs
# them). A user's `make deb` does not need lintian: it is the project's
# check, not the build's.
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
lint=0
if [ "${1:-}" = --lintian ]; then
	lint=1
	shift
fi
out=$(mkdir -p "${1:-$top/.build/deb}" && cd "${1:-$top/.build/deb}" && pwd)
ver=$(sed -n 's/^PACKAGE_VERSION="\(.*\)"/\1/p' "$top/dkms.conf")
chver=$(sed -n '1s/^[^ ]* (\([^)]*\)).*/\1/p' "$top/debian/changelog")
if [ "$ver" != "$chver" ]; then
	echo "make-deb: dkms.conf has version $ver, debian/changelog $chver" >&2
	exit 1
fi
tools=(dpkg-buildpackage dh dh_dkms)
[ "$lint" = 0 ] || tools+=(lintian)
for t in "${tools[@]}"; do
	command -v "$t" >/dev/null || { echo "make-deb: $t is missing (tests/install-deps.sh)" >&2; exit 1; }
done

work=$(mktemp -d "${TMPDIR:-/tmp}/lego-deb.XXXXXX")
trap 'rm -rf "$work"' EXIT
src=$work/lego-mindstorms-$ver
mkdir "$src"
# The tree without build output, VCS data or caches.
tar -C "$top" -cf - --exclude=./.git --exclude=./.build --exclude='*.o' --exclude='*.ko' \
	--exclude='.*.cmd' --exclude='*.mod' --exclude='*.mod.c' --exclude='modules.order' \
	--exclude='Module.symvers' --exclude='__pycache__' --exclude='.pytest_cache' \
	--exclude='*.egg-info' . | tar -C "$src" -xf -

echo "make-deb: dpkg-buildpackage -us -uc -b in $src" >&2
# The system's python3 and tools (pybuild builds for Debian's python3, not
# for one of a virtual environment or pyenv earlier in PATH).
if ! (cd "$src" && PATH=/usr/sbin:/usr/bin:/sbin:/bin dpkg-buildpackage -us -uc -b) \
		>"$work/build.log" 2>&1; then
	cat "$work/build.log" >&2
	echo "make-deb: dpkg-buildpackage failed" >&2
	exit 1
fi
rm -f "$out"/*.deb "$out"/*.changes "$out"/*.buildinfo
cp "$work"/*.deb "$work"/*.changes "$work"/*.buildinfo "$out"/
cp "$work/build.log" "$out/build.log"

if [ "$lint" = 0 ]; then
	ls -1 "$out"/*.deb
	exit 0
fi
# lintian: errors and warnings fail the check; each override in debian/
# says why.
echo "make-deb: lintian" >&2
if ! lintian --fail-on error,warning --info "$out"/*.changes >"$out/lintian.log" 2>&1; then
	cat "$out/lintian.log" >&2
	echo "make-deb: lintian found errors or warnings (log: $out/lintian.log)" >&2
	exit 1
fi
cat "$out/lintian.log" >&2
ls -1 "$out"/*.deb
