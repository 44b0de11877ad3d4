#!/usr/bin/env bash
# tests/install-deps.sh on a new Debian 12 machine: a clean bookworm root
# (debootstrap, minbase), in which install-deps.sh installs what it lists
# (the Debian packages with apt, the PyPI ones of tests/requirements.txt in
# its virtual environment), then the venv's python3 is checked (the versions
# requirements.txt names, the imports the tests make) and coccicheck's
# semantic patches with scripts run: spatch compiles
# OCaml scripts with the OCaml compiler (without it, it stops with "No
# OCaml compiler found") and loads libpython3.11.so for Python ones.
#
#   tests/packaging/clean-root.sh [--force]
#
# A pass is recorded in $LEGO_CACHE/clean-root-<key>.pass, where <key>
# hashes install-deps.sh, tests/lib/venv.sh, check-requirements.py,
# tests/requirements.txt, the semantic patches and the recipe number: the
# (slow: a few minutes) check runs again when one of them changes, or with
# --force. The root is made in a scratch directory and removed afterwards
# (LEGO_CLEAN_ROOT_KEEP=1 keeps it, and prints where).
#
# What is not a new machine's: the root reaches the package mirror as the
# host does, through the host's apt settings for it (/etc/apt/apt.conf.d
# lines about Release files' dates: mirrors here serve a snapshot whose
# Release files are past their Valid-Until), and PyPI as the host's pip
# reaches it: through the proxies of the environment (http_proxy,
# https_proxy, no_proxy), the index of PIP_INDEX_URL, and trusting the CA
# bundle the host's pip trusts (PIP_CERT, or "cert =" of a pip.conf: a
# TLS-inspecting proxy's CA). Nothing else of the host's pip settings (no
# PIP_FIND_LINKS: the wheels come from the index).
#
# Environment: LEGO_DEBIAN_MIRROR (default http://deb.debian.org/debian),
# LEGO_DEBIAN_SECURITY_MIRROR (default http://deb.debian.org/debian-security).
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
# shellcheck source=tests/kernel/lib.sh
. "$top/tests/kernel/lib.sh"
cache=$(kcache_dir)
mirror=${LEGO_DEBIAN_MIRROR:-http://deb.debian.org/debian}
force=0
[ "${1:-}" = --force ] && force=1
prog=clean-root

# The semantic patches with OCaml or Python scripts, from the newest
# kernel's tree.
ktree=$("$top/tests/kernel/build-kernel.sh" --tree-only newest 2>/dev/null) ||
	{ echo "$prog: no newest test kernel tree (tests/kernel/build-kernel.sh newest)" >&2; exit 1; }
# Those with a report mode, which make coccicheck MODE=report runs (it skips
# the others, as here).
mapfile -t cocci < <(grep -l -E '^@ *(script|initialize|finalize) *: *(ocaml|python)' -r "$ktree/scripts/coccinelle" |
	xargs grep -l -E '^virtual\b.*\breport\b' | sort)
[ ${#cocci[@]} -gt 0 ] || { echo "$prog: no semantic patch with scripts in $ktree" >&2; exit 1; }

recipe=3
deps_files=("$top/tests/install-deps.sh" "$top/tests/requirements.txt" "$top/tests/lib/venv.sh"
	"$top/tests/lib/check-requirements.py")
key=$( { echo "recipe $recipe"; cat "${deps_files[@]}" "${cocci[@]}"; } |
	sha256sum | cut -c1-16)
pass=$cache/clean-root-$key.pass
if [ "$force" = 0 ] && [ -f "$pass" ]; then
	echo "$prog: passed before for these inputs ($(cat "$pass"))"
	exit 0
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/lego-clean-root.XXXXXX")
if [ -n "${LEGO_CLEAN_ROOT_KEEP:-}" ]; then
	trap 'echo "$prog: kept $work" >&2' EXIT
else
	trap 'rm -rf "$work"' EXIT
fi
root=$work/root
t0=$SECONDS
echo "$prog: debootstrap bookworm (minbase) into $root" >&2
debootstrap --variant=minbase bookworm "$root" "$mirror" >"$work/debootstrap.log" 2>&1 ||
	{ tail -n 20 "$work/debootstrap.log" >&2; exit 1; }
cp /etc/resolv.conf "$root/etc/resolv.conf"
# The suites a Debian 12 installation has (debootstrap sets bookworm alone):
# linux-source-6.12 comes with bookworm's updates.
printf 'deb %s %s main\n' "$mirror" bookworm "$mirror" bookworm-updates \
	"${LEGO_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}" bookworm-security \
	>"$root/etc/apt/sources.list"
grep -h -E '^Acquire::Check-(Valid-Until|Date)' /etc/apt/apt.conf.d/* 2>/dev/null |
	sort -u >"$root/etc/apt/apt.conf.d/99mirror-snapshot" || true

# The host's pip trust and proxies (see the top).
pip_env=()
cert=${PIP_CERT:-}
if [ -z "$cert" ]; then
	cert=$(sed -n 's/^[[:space:]]*cert[[:space:]]*=[[:space:]]*//p' \
		"$HOME/.config/pip/pip.conf" "$HOME/.pip/pip.conf" /etc/pip.conf 2>/dev/null | head -n 1)
fi
if [ -n "$cert" ] && [ -f "$cert" ]; then
	cp "$cert" "$root/etc/lego-host-pip-ca.crt"
	pip_env+=(PIP_CERT=/etc/lego-host-pip-ca.crt)
fi
for v in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY PIP_INDEX_URL; do
	[ -z "${!v:-}" ] || pip_env+=("$v=${!v}")
done

mkdir -p "$root/lego/tests/lib" "$root/lego/cocci" "$root/lego/src"
cp "$top/tests/install-deps.sh" "$top/tests/requirements.txt" "$root/lego/tests/"
cp "$top/tests/lib/venv.sh" "$top/tests/lib/check-requirements.py" "$root/lego/tests/lib/"
cp "${cocci[@]}" "$root/lego/cocci/"
cp "$top"/drivers/lego/ev3/*.c "$top"/drivers/lego/nxt/*.c "$root/lego/src/"

# In a private mount namespace: /proc, /sys and /dev for apt and dpkg.
unshare -m --propagation private bash -s "$root" "${pip_env[@]}" >"$work/run.log" 2>&1 <<'EOF' || { tail -n 40 "$work/run.log" >&2; exit 1; }
set -eu
root=$1
shift
pip_env=("$@")
for d in proc sys dev; do mount --rbind "/$d" "$root/$d"; done
in_root() {
	chroot "$root" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root "${pip_env[@]}" "$@"
}
in_root bash /lego/tests/install-deps.sh
echo "installed: $(in_root dpkg-query -W -f '${Package}\n' | wc -l) packages"
# A second run has nothing to do and checks the versions again.
in_root bash /lego/tests/install-deps.sh
# The venv that install-deps.sh made, as the test scripts find it.
venv=$(in_root bash -c '. /lego/tests/lib/venv.sh; lego_venv_activate /lego; echo "$VIRTUAL_ENV"')
[ -n "$venv" ] || { echo "venv: not made (or not complete)"; exit 1; }
py=$venv/bin/python3
in_root "$py" /lego/tests/lib/check-requirements.py /lego/tests/requirements.txt
# Each name in requirements.txt at its installed version, from the venv.
in_root "$py" -c 'import importlib.metadata as md, re, sys
for l in open(sys.argv[1]):
    l = l.split("#")[0].strip()
    if l:
        n = re.split("[<>=!~ ]", l)[0]
        print("venv: %s %s" % (n, md.version(n)))' /lego/tests/requirements.txt
# The third-party imports of the tests and tools.
in_root "$py" -c 'import pytest, ev3dev2.sensor.lego, nxt.locator, nxt.brick, usb.core; print("venv: imports ok")'
for c in "$root"/lego/cocci/*.cocci; do
	n=$(basename "$c")
	# Report mode, as make coccicheck MODE=report runs them.
	if ! chroot "$root" spatch -D report --no-show-diff --very-quiet \
		--cocci-file "/lego/cocci/$n" --dir /lego/src >"$root/lego/$n.out" 2>&1; then
		echo "spatch $n failed:"
		cat "$root/lego/$n.out"
		exit 1
	fi
	if grep -q -e 'No OCaml compiler' -e 'find_library' "$root/lego/$n.out"; then
		cat "$root/lego/$n.out"
		exit 1
	fi
	echo "spatch $n: ok"
done
EOF
grep -E '^(installed|venv|spatch)' "$work/run.log" >&2
echo "$(date -u +%FT%TZ) in $((SECONDS - t0)) s" >"$pass"
echo "$prog: install-deps.sh (apt and the venv's PyPI packages) and coccicheck's semantic patches with scripts (${#cocci[@]}) passed in a clean Debian 12 root in $((SECONDS - t0)) s"
