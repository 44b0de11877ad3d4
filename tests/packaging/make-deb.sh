#!/usr/bin/env bash
# `make deb`: the Debian packages of debian/, built with dpkg-buildpackage
# from a copy of the tree (the build leaves objects and debian/ output
# beside the sources), into OUTDIR (default .build/deb), then lintian on them.
#
#   tests/packaging/make-deb.sh [OUTDIR]
#
# Needs dpkg-dev, debhelper, dh-dkms, dh-python, pybuild-plugin-pyproject,
# python3-all and lintian (tests/install-deps.sh installs them).
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
out=$(mkdir -p "${1:-$top/.build/deb}" && cd "${1:-$top/.build/deb}" && pwd)
ver=$(sed -n 's/^PACKAGE_VERSION="\(.*\)"/\1/p' "$top/dkms.conf")
chver=$(sed -n '1s/^[^ ]* (\([^)]*\)).*/\1/p' "$top/debian/changelog")
if [ "$ver" != "$chver" ]; then
	echo "make-deb: dkms.conf has version $ver, debian/changelog $chver" >&2
	exit 1
fi
for t in dpkg-buildpackage dh dh_dkms lintian; do
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

# lintian: errors and warnings fail the build; each override in debian/
# says why.
echo "make-deb: lintian" >&2
if ! lintian --fail-on error,warning --info "$out"/*.changes >"$out/lintian.log" 2>&1; then
	cat "$out/lintian.log" >&2
	echo "make-deb: lintian found errors or warnings (log: $out/lintian.log)" >&2
	exit 1
fi
cat "$out/lintian.log" >&2
ls -1 "$out"/*.deb
