#!/usr/bin/env bash
# For tests/packaging/test_deb.py and tests/guest/test_deb.py: a private
# Debian root (tests/packaging/debroot.py) in which the built
# lego-mindstorms-dkms package is installed with dpkg, so that DKMS compiles
# the modules for the test kernel here on the host (a DKMS build in the
# emulated guest takes over ten minutes, here seconds), saved as OUT_TAR
# (the host test unpacks it, installs the other packages and purges them
# all); then with the other packages installed too, left unpacked in
# OUT_TAR without .tar, where the guest test chroots.
#
#   tests/packaging/deb-prepare.sh KDIR DEB_DIR OUT_TAR
#
# DEB_DIR holds the packages of `make deb`. Runs in a private mount
# namespace: the host's directories are untouched.
set -euo pipefail
if [ $# -ne 3 ]; then
	echo "usage: $0 KDIR DEB_DIR OUT_TAR" >&2
	exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
[ "$(id -u)" = 0 ] || { echo "deb-prepare: needs root (a mount namespace, dpkg)" >&2; exit 1; }
mkdir -p "$(dirname "$3")"
rm -f "$3"
kver=$(unshare -m --propagation private /usr/bin/python3 "$here/debroot.py" prepare "$1" "$2" "$3")
echo "deb-prepare: lego-mindstorms-dkms installed, DKMS built for $kver: $3" >&2
