#!/usr/bin/env bash
# Install everything `make check` needs on a fresh Debian 12 machine: the
# kernel sources, QEMU, sparse, the kernel build dependencies (apt), and the
# Python packages the tests use (tests/requirements.txt, pip, in a virtual
# environment in the cache: tests/lib/venv.sh). Checks the versions
# requirements.txt names. Does nothing (and needs no network) when all is
# there.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)

debs=(
	linux-source-6.12 linux-source-6.1 linux-headers-amd64
	qemu-system-x86 sparse build-essential bc bison flex libelf-dev libssl-dev
	cpio busybox-static kmod util-linux rsync python3 perl libiio-utils
	dkms udev
)
# The virtual environment of the PyPI packages (python3 -m venv, with pip)
debs+=(python3-venv)
# libusb for pyusb: nxt-python's usb backend in tests/guest/test_nxt_python.py
debs+=(libusb-1.0-0)
# systemd-analyze (tests/packaging/test_systemd_unit.py's unit check),
# systemd-udevd (the guest runs the host's root) and systemd-sysusers
# (tests/packaging/test_udev_rules.py)
debs+=(systemd)
# tests/cross-build.sh: the arm64 and armhf cross compilers (with their libc
# for the userspace tools)
debs+=(gcc-aarch64-linux-gnu gcc-arm-linux-gnueabihf libc6-dev-arm64-cross libc6-dev-armhf-cross)
# make check-arm64 (tests/arm64/check.sh): the arm64 VM, the cross compiler,
# and debootstrap for its root file system.
debs+=(qemu-system-arm debootstrap qemu-user-static file)
# tests/guest/nxt_compat_client.c, the 32-bit client of the NXT ioctls, built
# static with gcc -m32 by tests/build-modules.sh (not gcc-multilib, which
# would remove the arm64 and armhf cross compilers above)
debs+=(gcc-12-multilib libc6-dev-i386)
# libusb headers and pkg-config for the NXT benchmark's C client (tests/bench/nxt)
debs+=(libusb-1.0-0-dev pkg-config)
# examples/iio-capture.c (built and run by tests/guest/test_examples.py)
debs+=(libiio-dev)
# i2cdetect, i2cget, i2cdump on the NXT's sensor ports (tests/guest/test_nxt_i2c.py)
# and libiio's network daemon (tests/guest/test_ev3_iiod.py)
debs+=(i2c-tools iiod)
# tests/fuzz (libFuzzer, ASan, UBSan) and tests/bench/proto (callgrind)
debs+=(clang-14 libclang-rt-14-dev valgrind)
# make upstream-series and upstream-check (tools/upstream, tests/upstream):
# unifdef for the in-tree sources, coccinelle for coccicheck (with the OCaml
# compiler, ocaml-nox: semantic patches with OCaml scripts, such as
# api/check_bq27xxx_data.cocci and null/badzero.cocci, are compiled by
# spatch, which stops with "No OCaml compiler found" without it; and
# libpython3-dev, whose unversioned libpython3.11.so spatch loads for the
# semantic patches with Python scripts, such as null/badzero.cocci:
# "Py.find_library: unable to find the Python library" without it), python3-ply
# and python3-git for checkpatch's SPDX check, Sphinx for the kernel's
# documentation build
debs+=(unifdef coccinelle ocaml-nox libpython3-dev python3-ply python3-git python3-sphinx python3-sphinx-rtd-theme python3-yaml)
# tests/guest/test_nxt_bluetooth.py: two virtual Bluetooth controllers
# (btvirt, of bluez-test-tools, on the kernel's /dev/vhci) and hciconfig
# (bluez) to bring them up
debs+=(bluez bluez-test-tools)
# make deb (tests/packaging/make-deb.sh) and its lintian run
debs+=(dpkg-dev debhelper dh-dkms dh-python pybuild-plugin-pyproject python3-all
	python3-setuptools fakeroot lintian)

missing=()
for p in "${debs[@]}"; do
	dpkg-query -W -f '${Status}\n' "$p" 2>/dev/null | grep -q '^install ok installed' || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
	echo "install-deps: apt-get install ${missing[*]}"
	sudo=; [ "$(id -u)" = 0 ] || sudo=sudo
	export DEBIAN_FRONTEND=noninteractive
	$sudo apt-get update -qq
	$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The PyPI packages of tests/requirements.txt, in a virtual environment
# (tests/lib/venv.sh): Debian's python3 refuses `pip install` (PEP 668).
# LEGO_DEPS_NO_PIP=1 leaves them out.
[ -z "${LEGO_DEPS_NO_PIP:-}" ] || exit 0

top=$(dirname "$here")
# shellcheck source=tests/lib/venv.sh
. "$here/lib/venv.sh"
venv=$(lego_venv_dir "$top")
mkdir -p "$(dirname "$venv")"
# One maker at a time (make check and make demo may start together).
exec 9>"$venv.lock"
flock 9
if [ ! -f "$venv/.done" ]; then
	echo "install-deps: python3 -m venv $venv; pip install -r tests/requirements.txt"
	rm -rf "$venv"
	/usr/bin/python3 -m venv --system-site-packages "$venv"
	"$venv/bin/python3" -m pip install -q --disable-pip-version-check -r "$here/requirements.txt"
	touch "$venv/.done"
fi
# The versions requirements.txt names, every time (no network needed).
"$venv/bin/python3" "$here/lib/check-requirements.py" "$here/requirements.txt" || {
	echo "install-deps: the venv $venv does not match tests/requirements.txt (remove it to remake it)" >&2
	exit 1
}
