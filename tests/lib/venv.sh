# shellcheck shell=bash
# The Python virtual environment of the tests: the PyPI packages of
# tests/requirements.txt, which Debian's python3 will not take from pip
# (PEP 668: "externally-managed-environment"). tests/install-deps.sh makes
# it; every script that runs the Python tests sources this file and calls
# lego_venv_activate, so that `python3` is the venv's (the x86 test VM runs
# the host's python3 over 9p: tests/vm-run passes the venv on).
#
# The venv is made from Debian's /usr/bin/python3 with
# --system-site-packages: Debian's python3-* packages (python3-ply and
# python3-git for checkpatch, python3-usb ...) stay visible, the PyPI ones
# come first. It lives in the cache, one per content of requirements.txt:
#   ${LEGO_CACHE:-~/.cache/lego-mindstorms-linux}/venv/<hash>
# and is complete when <hash>/.done exists. LEGO_VENV names another one.

# lego_venv_dir TOP: print the venv's directory for the checkout TOP.
lego_venv_dir() {
	if [ -n "${LEGO_VENV:-}" ]; then
		echo "$LEGO_VENV"
		return
	fi
	local cache=${LEGO_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/lego-mindstorms-linux} key
	# The recipe (venv options, base python) and the requirements.
	key=$( { echo "venv 1 --system-site-packages /usr/bin/python3"; cat "$1/tests/requirements.txt"; } |
		sha256sum | cut -c1-16)
	echo "$cache/venv/$key"
}

# lego_venv_activate TOP: put the venv's bin/ first in PATH if the venv is
# complete; without it (install-deps.sh never ran) PATH stays as it is.
lego_venv_activate() {
	local v
	v=$(lego_venv_dir "$1")
	[ -f "$v/.done" ] && [ -x "$v/bin/python3" ] || return 0
	case ":$PATH:" in
	*":$v/bin:"*) ;;
	*) PATH=$v/bin:$PATH ;;
	esac
	export PATH VIRTUAL_ENV=$v
}
