#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-2.0
#
# `make upstream-check`: the in-tree patch series (tools/upstream/series.sh),
# checked as a maintainer would check it. The first run builds four small
# kernel configurations and two KUnit kernels (about 20 minutes on two busy
# cores), later runs take a few minutes; `make check` runs the steps that
# build no kernel (tests/check.sh).
#
#   tests/upstream/check.sh [SERIES] [STEP...]
#   make upstream-check UPSTREAM_SERIES=SERIES UPSTREAM_STEPS="STEP..."
#
# SERIES: 6.12 (default) or 6.1. STEPS (default: all): series am checkpatch
# kernel-doc refs abi headers coccicheck htmldocs lego-docs build-x86_64-m
# build-x86_64-y build-arm64-m build-arm64-y bisect kunit kunit-arm64.
#
# 1. series: `make upstream-series` writes the series from this checkout;
# 2. am: the scratch repository's own worktree, reset to the base commit
#    and cleaned, takes the patches with git am; the result must be the
#    series' tree (the branch lego-SERIES). One worktree of the kernel
#    (1.8 GB for 7.3), not two: the steps below check that detached HEAD;
# 3. checkpatch: scripts/checkpatch.pl --strict on every patch: no error,
#    warning or check (nor any other output);
# 4. kernel-doc: scripts/kernel-doc -none -Wall on every C file and header
#    the series adds: no output;
#    refs: every path the series' added lines name exists in the tree;
# 5. abi: scripts/get_abi.pl validate: no line about our ABI files;
# 6. headers: make headers, then each uapi header the series adds compiled
#    alone in userspace with -Wall -Wextra -Werror;
#    coccicheck: make coccicheck MODE=report on both drivers' directories:
#    no report;
# 7. htmldocs: make SPHINXDIRS="userspace-api iio usb trace" htmldocs (the
#    series adds rows to ioctl-number.rst, a page with the uapi headers'
#    kernel-doc, the drivers' pages and the trace events' page): no warning
#    about them, and the pages say what they should, and nothing of this
#    repository's package;
#    lego-docs: this checkout's Documentation/lego (not part of the series)
#    through sphinx-build -W;
# 8. build-ARCH-MODE: allnoconfig plus tests/upstream/build.config and the
#    drivers and their KUnit suites as MODE (m or y), checked after
#    olddefconfig (IIO_BUFFER and IIO_KFIFO_BUF must be selected); vmlinux
#    built and linked, for m the modules too (modpost: undefined symbols,
#    section mismatches), then the drivers' directories again with W=1 and
#    sparse (C=1).
#    Any warning about our files fails. ARCH x86_64 natively, arm64 with
#    aarch64-linux-gnu-. Each configuration builds in
#    .build/upstream/build-SERIES-ARCH-MODE (O=), kept for the next run:
#    only what changed is rebuilt;
# 9. bisect: each commit of the series checked out in turn, and the
#    drivers' directories that have a Makefile by then built in with W=1
#    (build-x86_64-y's configuration): no patch breaks the build;
# 10. kunit: tools/testing/kunit/kunit.py run (UML) with both drivers'
#    .kunitconfig; both suites must run and every case their sources list
#    pass. kunit-arm64: the same on an arm64 kernel under QEMU (TCG). The
#    builds are kept in .build/upstream/kunit-SERIES-ARCH.
#
# Logs go to .build/upstream/check-SERIES.log/; the last line is
# "N passed, N failed" and the exit status is 1 if any step failed.
set -uo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
series=newest
if [ $# -gt 0 ] && [[ "$1" =~ ^([0-9]+\.[0-9]+|newest)$ ]]; then
	series=$1
	shift
fi
prog=upstream-check
# shellcheck source=tools/upstream/lib.sh
. "$top/tools/upstream/lib.sh"      # and tests/kernel/lib.sh

steps=("$@")
[ ${#steps[@]} -gt 0 ] || steps=(series am checkpatch kernel-doc refs abi headers coccicheck htmldocs lego-docs
	build-x86_64-m build-x86_64-y build-arm64-m build-arm64-y bisect kunit kunit-arm64)
work=$up_repo
logs=$up_out/check-$series.log
mkdir -p "$logs"
jobs=${LEGO_UPSTREAM_JOBS:-2}
# checkpatch's SPDX check runs scripts/spdxcheck.py with the first python3
# in PATH; it needs Debian's python3-ply and python3-git.
export PATH=/usr/bin:/bin:$PATH
passed=0
failed=0

# result STEP SECONDS STATUS: count and print one step's result.
result() {
	if [ "$3" = 0 ]; then
		passed=$((passed + 1))
		echo "$prog: PASS $1 ($2 s)"
	else
		failed=$((failed + 1))
		echo "$prog: FAIL $1 ($2 s; log: $logs/$1.log)"
	fi
}

want() {
	local s
	for s in "${steps[@]}"; do [ "$s" = "$1" ] && return 0; done
	return 1
}

# The series' patches, without the cover letter.
patches() {
	find "$up_patches" -name '[0-9][0-9][0-9][0-9]-*.patch' ! -name '0000-*' | sort
}

# Files the series adds, of the given patterns, in the applied tree.
added() {
	git -C "$work" diff --name-only --diff-filter=A "$(up_base_tag)" HEAD -- "$@"
}

step_series() {
	"$top/tools/upstream/series.sh" "$series"
}

step_am() {
	local tag p
	up_base || return 1
	tag=$(up_base_tag)
	# The second worktree that earlier versions of this script kept.
	if [ -d "$up_out/check-$series" ]; then
		rm -rf "$up_out/check-$series"
		up_git worktree prune
	fi
	git -C "$work" am --abort >/dev/null 2>&1
	mapfile -t p < <(patches)
	git -C "$work" checkout -q -f --detach "$tag" &&
		git -C "$work" clean -q -fdx &&
		git -C "$work" -c user.name="$up_name" -c user.email="$up_email" am -q "${p[@]}" ||
		return 1
	# The patches must give exactly the series' tree.
	git -C "$work" diff --quiet HEAD "$up_branch" || { echo "git am gave another tree than $up_branch"; return 1; }
	echo "$(patches | wc -l) patches applied to $tag"
}

step_checkpatch() {
	local p out bad=0
	for p in $(patches); do
		out=$(cd "$work" && scripts/checkpatch.pl --strict --quiet --show-types "$p" 2>&1)
		if [ -n "$out" ]; then
			echo "== $(basename "$p")"
			echo "$out"
			bad=1
		else
			echo "clean: $(basename "$p")"
		fi
	done
	return $bad
}

step_kernel_doc() {
	local out wall=(-Wall)
	mapfile -t files < <(added '*.c' '*.h')
	[ ${#files[@]} -gt 0 ] || { echo "no files"; return 1; }
	# -Wall adds the checks of return values and short descriptions; an
	# older kernel-doc (6.1's) has none of it, and runs its other checks.
	(cd "$work" && scripts/kernel-doc -none -Wall /dev/null >/dev/null 2>&1) ||
		{ wall=(); echo "this kernel-doc has no -Wall"; }
	out=$(cd "$work" && scripts/kernel-doc -none "${wall[@]}" "${files[@]}" 2>&1)
	echo "${#files[@]} files: ${files[*]}"
	[ -z "$out" ] || { echo "$out"; return 1; }
}

# get_abi COMMAND ARGS...: the tree's ABI tool on Documentation/ABI:
# scripts/get_abi.pl until 6.13, then get_abi.py (in scripts/, later in
# tools/docs/), whose --dir comes before the command.
get_abi() {
	local cmd=$1
	shift
	if [ -f scripts/get_abi.pl ]; then
		scripts/get_abi.pl "$cmd" --dir Documentation/ABI "$@"
	elif [ -f tools/docs/get_abi.py ]; then
		python3 tools/docs/get_abi.py --dir Documentation/ABI "$cmd" "$@"
	else
		python3 scripts/get_abi.py --dir Documentation/ABI "$cmd" "$@"
	fi
}

step_abi() {
	local out
	mapfile -t files < <(added 'Documentation/ABI/*')
	[ ${#files[@]} -gt 0 ] || { echo "no ABI files"; return 1; }
	out=$(cd "$work" && get_abi validate 2>&1) || { echo "$out"; return 1; }
	echo "${#files[@]} files: ${files[*]}"
	# It did read them.
	(cd "$work" && get_abi search '/sys/class/lego-sensor/sensor<N>/mode$') |
		grep 'sysfs-class-lego-sensor' >/dev/null || { echo "get_abi.pl does not find the lego-sensor class"; return 1; }
	# The tree's own ABI files have warnings of their own; ours have none.
	out=$(echo "$out" | grep -F -e lego -e LEGO)
	[ -z "$out" ] || { echo "$out"; return 1; }
}

# kmake ARCH MODE ARGS...: make in the build directory of ARCH and MODE.
kmake() {
	local arch=$1 mode=$2 cross=()
	shift 2
	[ "$arch" = arm64 ] && cross=(CROSS_COMPILE=aarch64-linux-gnu-)
	make -C "$work" O="$up_out/build-$series-$arch-$mode" ARCH="$arch" "${cross[@]}" "$@"
}

step_headers() {
	local h bad=0 usr=$up_out/build-$series-x86_64-m/usr/include
	kmake x86_64 m -s headers || return 1
	mapfile -t files < <(added 'include/uapi/*.h')
	[ ${#files[@]} -gt 0 ] || { echo "no uapi headers"; return 1; }
	for h in "${files[@]}"; do
		h=${h#include/uapi/}
		echo "#include <$h>" | gcc -Wall -Wextra -Werror -fsyntax-only -I "$usr" -x c - ||
			{ echo "$h does not compile alone"; bad=1; continue; }
		echo "compiles alone: $h"
	done
	return $bad
}

# step_build ARCH MODE
step_build() {
	local arch=$1 mode=$2 out frag log2 dirs sym d k targets c
	out=$up_out/build-$series-$arch-$mode
	frag=$out/lego.config
	dirs=(drivers/iio/common/lego_ev3_uart/ drivers/usb/misc/lego_nxt/)
	mkdir -p "$out"
	{
		cat "$top/tests/upstream/build.config"
		[ "$arch" = x86_64 ] && echo "CONFIG_64BIT=y"
		for sym in LEGO_EV3_UART LEGO_EV3_UART_KUNIT_TEST USB_LEGO_NXT LEGO_NXT_SERIAL \
			LEGO_NXT_KUNIT_TEST; do
			echo "CONFIG_$sym=$mode"
		done
		# Selected by LEGO_EV3_UART, not set by the fragment: Kconfig must
		# (IIO_BUFFER is a bool, IIO_KFIFO_BUF takes the driver's value).
		echo "CONFIG_IIO_BUFFER=y"
		echo "CONFIG_IIO_KFIFO_BUF=$mode"
	} >"$frag.new"
	# Configure again only when the fragment or the tree's Kconfig changed.
	if ! cmp -s "$frag.new" "$frag" || [ ! -f "$out/.config" ] ||
		[ -n "$(find "$work" -name 'Kconfig*' -newer "$out/.config" -print -quit)" ]; then
		grep -v 'IIO_BUFFER\|IIO_KFIFO_BUF' "$frag.new" >"$out/lego-request.config"
		kmake "$arch" "$mode" -s allnoconfig &&
			(cd "$out" && ARCH=$arch "$work/scripts/kconfig/merge_config.sh" -m -O "$out" \
				"$out/.config" "$out/lego-request.config" >/dev/null) &&
			kmake "$arch" "$mode" -s olddefconfig || return 1
		mv "$frag.new" "$frag"
	else
		rm -f "$frag.new"
	fi
	kconfig_verify "$out/.config" "" "$frag" || return 1
	log2=$(mktemp)
	# The whole kernel of this configuration, linked (the built-in
	# drivers), and for m the modules with modpost (undefined symbols,
	# section mismatches) against it; without W=1, which the tree's own
	# files are not clean with. No line about our files may be a warning.
	targets=(vmlinux)
	[ "$mode" = m ] && targets+=(modules)
	if ! kmake "$arch" "$mode" -j"$jobs" "${targets[@]}" >"$log2" 2>&1; then
		tail -n 60 "$log2"
		rm -f "$log2"
		return 1
	fi
	grep -E 'warning:|error:|WARNING:|ERROR:' "$log2" | grep -E 'lego|ev3_uart|nxt_' && { rm -f "$log2"; return 1; }
	grep -c '' "$log2" | sed 's/^/lines of the vmlinux build log: /'
	# Then our objects again, with W=1: any warning fails. Then once more
	# with sparse (C=1) too: by then only our objects are rebuilt (the
	# first pass rebuilt what W=1 changes in "prepare", e.g. arm64's vDSO,
	# which 6.1's sparse does not pass), and any warning fails.
	for c in "" 1; do
		find "$out/drivers/iio/common/lego_ev3_uart" "$out/drivers/usb/misc/lego_nxt" \
			-name '*.o' -delete 2>/dev/null
		kmake "$arch" "$mode" -j"$jobs" W=1 ${c:+C=$c} "${dirs[@]}" >"$log2" 2>&1 ||
			{ cat "$log2"; rm -f "$log2"; return 1; }
		[ -z "$c" ] || grep -c '^  CHECK ' "$log2" | sed 's/^/files checked by sparse: /'
		cat "$log2"
		if grep -E 'warning:|error:|WARNING:|ERROR:' "$log2"; then
			rm -f "$log2"
			return 1
		fi
	done
	rm -f "$log2"
	if [ "$mode" = m ]; then
		for k in lego_ev3_uart lego_ev3_uart_test lego_nxt lego_nxt_usb lego_nxt_serial \
			lego_nxt_test; do
			[ -n "$(find "$out/drivers" -name "$k.ko")" ] || { echo "$k.ko not built"; return 1; }
		done
	else
		for d in "${dirs[@]}"; do
			[ -s "$out/${d}built-in.a" ] || { echo "${d}built-in.a is empty"; return 1; }
		done
		# Linked in: the init functions of all four modules (the EV3
		# discipline, the NXT core, its USB and serial transports).
		for k in ev3_uart_init nxt_init nxt_usb_driver_init nxt_serial_init; do
			nm "$out/vmlinux" | grep " $k\$" >/dev/null || { echo "$k is not in vmlinux"; return 1; }
		done
	fi
}

# Every path the series' lines name (Documentation/..., drivers/...,
# tests/...) exists in the tree: a comment or an ABI entry must not point
# at a file that stays out of the tree. nxt-python's own tests/test_brick.py
# is another project's file.
step_refs() {
	local out
	out=$(git -C "$work" diff "$(up_base_tag)" HEAD | grep '^+[^+]' |
		grep -oP '(?<![\w/.<-])(Documentation|drivers|include|scripts|tests|tools)/[\w./-]*\w' |
		grep -vxF 'tests/test_brick.py' | sort -u |
		while read -r f; do [ -e "$work/$f" ] || echo "$f"; done)
	[ -z "$out" ] || { echo "paths named by the series that are not in the tree:"; echo "$out"; return 1; }
	echo "every path the series names is in the tree"
}

# This checkout's own pages (Documentation/lego, which stay out of the
# tree) through Sphinx with warnings as errors, as htmldocs would.
step_lego_docs() {
	local out=$up_out/lego-docs
	rm -rf "$out"
	sphinx-build -q -W --keep-going -C -D master_doc=index -D project="LEGO MINDSTORMS" \
		-b html "$top/Documentation/lego" "$out" || return 1
	echo "$(find "$out" -maxdepth 1 -name '*.html' | wc -l) pages in $out"
}

# Every patch builds (git bisect): at each commit of the series, the
# drivers' directories that have a Makefile by then, built in with W=1, in
# the configuration of build-x86_64-y (its .config, olddefconfig: the
# options of a driver not there yet drop out).
step_bisect() {
	local out=$up_out/build-$series-x86_64-bisect cfg=$up_out/build-$series-x86_64-y/.config
	local c d n=0 dirs log2 rc=0
	[ -f "$cfg" ] || { echo "no $cfg: run build-x86_64-y first"; return 1; }
	local tip
	tip=$(git -C "$work" rev-parse HEAD)
	mkdir -p "$out"
	log2=$(mktemp)
	for c in $(git -C "$work" rev-list --reverse "$(up_base_tag)..HEAD"); do
		n=$((n + 1))
		git -C "$work" checkout -q --detach "$c" || { rc=1; break; }
		dirs=()
		for d in drivers/iio/common/lego_ev3_uart drivers/usb/misc/lego_nxt; do
			[ -f "$work/$d/Makefile" ] && dirs+=("$d/")
		done
		if [ ${#dirs[@]} = 0 ]; then
			echo "patch $n: nothing of ours is built yet"
			continue
		fi
		cp "$cfg" "$out/.config"
		find "$out/drivers/iio/common/lego_ev3_uart" "$out/drivers/usb/misc/lego_nxt" \
			-name '*.o' -delete 2>/dev/null
		if ! make -C "$work" O="$out" -s olddefconfig >"$log2" 2>&1 ||
			! make -C "$work" O="$out" -j"$jobs" W=1 "${dirs[@]}" >>"$log2" 2>&1 ||
			grep -E 'warning:|error:' "$log2"; then
			cat "$log2"
			echo "patch $n ($(git -C "$work" log -1 --format=%s "$c")): FAILED"
			rc=1
			break
		fi
		for d in "${dirs[@]}"; do
			[ -n "$(find "$out/$d" -name '*.o' ! -name 'built-in*')" ] ||
				{ echo "patch $n: nothing was compiled in $d"; rc=1; }
		done
		[ "$rc" = 0 ] || break
		echo "patch $n: ${dirs[*]} built with W=1"
	done
	rm -f "$log2"
	# Back to the whole series.
	git -C "$work" checkout -q --detach "$tip" || rc=1
	return $rc
}

# Coccinelle's semantic patches of the tree (scripts/coccinelle, as the
# kernel test robot runs them) on both drivers' directories, in report mode:
# any report fails. In the source tree: with O=, coccicheck's M= would look
# for the sources in the build directory and find none.
step_coccicheck() {
	local d out bad=0
	command -v spatch >/dev/null || { echo "spatch missing (tests/install-deps.sh installs coccinelle)"; return 1; }
	for d in drivers/iio/common/lego_ev3_uart drivers/usb/misc/lego_nxt; do
		out=$(make -C "$work" coccicheck MODE=report M="$d" J="$jobs" DEBUG_FILE=/dev/null 2>&1) ||
			{ echo "$out"; return 1; }
		# spatch's own notes: the commands, "N files match", warnings
		# about the semantic patches themselves, and (newer trees) those
		# it skips as having no report mode.
		out=$(echo "$out" | grep -vE '^(/usr/bin/spatch|make|Please check|When using)|^$|files match$|^warning: line [0-9]+: |^warning: Skipping .* does not match mode')
		if [ -n "$out" ]; then
			echo "$d:"
			echo "$out"
			bad=1
		else
			echo "$d: no report"
		fi
	done
	return $bad
}

# step_kunit ARCH: both KUnit suites with kunit.py and the drivers'
# .kunitconfig, under UML (um) or QEMU (arm64, with Debian's
# aarch64-linux-gnu- and qemu-system-aarch64, no KVM needed).
step_kunit() {
	local arch=$1 out dirs=(drivers/iio/common/lego_ev3_uart drivers/usb/misc/lego_nxt) args=() d n
	for d in "${dirs[@]}"; do args+=(--kunitconfig="$d"); done
	[ "$arch" = um ] || args+=(--arch="$arch" --cross_compile=aarch64-linux-gnu- --timeout=900)
	out=$(cd "$work" && tools/testing/kunit/kunit.py run "${args[@]}" \
		--build_dir="$up_out/kunit-$series-$arch" --jobs="$jobs" 2>&1)
	rc=$?
	echo "$out"
	[ "$rc" = 0 ] || return 1
	# Every suite of the drivers' *_test.c ran, and every case passed: as
	# many as those sources list.
	local tests=("$top"/drivers/lego/*/*_test.c) suites
	suites=$(sed -n 's/^[[:space:]]*\.name[[:space:]]*=[[:space:]]*"\(lego_[a-z0-9_]*\)",$/\1/p' "${tests[@]}")
	[ -n "$suites" ] || { echo "no KUnit suite found in ${tests[*]}"; return 1; }
	for d in $suites; do
		echo "$out" | grep -E "^\[[0-9:]+\] =+ $d \(" >/dev/null || { echo "suite $d did not run"; return 1; }
	done
	n=$(up_kunit_cases "${tests[@]}")
	echo "$out" | grep -E "Testing complete\. Ran $n tests: passed: $n\$" ||
		{ echo "not all $n cases ran and passed"; return 1; }
}

# The documentation the series touches built by Sphinx: the directories of
# its pages (the drivers' pages in iio and usb, the trace events' page, the
# userspace API page and ioctl-number.rst).
step_htmldocs() {
	local log=$up_out/htmldocs-$series.log out w page
	kmake x86_64 m "SPHINXDIRS=userspace-api iio usb trace" htmldocs >"$log" 2>&1 ||
		{ tail -n 40 "$log"; return 1; }
	grep -c '' "$log" | sed 's/^/lines of the htmldocs log: /'
	# No warning about what the series changed: none naming our pages, and
	# none on a line it added to ioctl-number.rst (the tree's own lines
	# there may warn when only some directories are built: 7.3's links to
	# process/submitting-patches).
	if grep -E 'WARNING|ERROR' "$log" | grep -F lego; then
		return 1
	fi
	local ioctl=Documentation/userspace-api/ioctl/ioctl-number.rst a n l bad=0
	declare -A mine=()
	while read -r a n; do
		for ((l = a; l < a + ${n:-1}; l++)); do mine[$l]=1; done
	done < <(git -C "$work" diff -U0 "$(up_base_tag)" HEAD -- "$ioctl" |
		sed -n 's/^@@ .* +\([0-9]*\),\{0,1\}\([0-9]*\) @@.*/\1 \2/p')
	[ ${#mine[@]} -gt 0 ] || { echo "the series adds no line to $ioctl"; return 1; }
	while IFS= read -r w; do
		l=$(echo "$w" | sed -n "s|.*$ioctl:\([0-9]*\):.*|\1|p")
		if [ -n "$l" ] && [ -n "${mine[$l]:-}" ]; then echo "$w"; bad=1; fi
	done < <(grep -E "$ioctl:[0-9]+: (WARNING|ERROR)" "$log")
	[ "$bad" = 0 ] || return 1
	out=$up_out/build-$series-x86_64-m/Documentation/output
	grep -q 'LEGO MINDSTORMS' "$out/userspace-api/ioctl/ioctl-number.html" ||
		{ echo "ioctl-number.html does not list the LEGO drivers"; return 1; }
	# Each page, with what it must say: the uapi headers' kernel-doc, the
	# number the tree gives the line discipline, the channel table, the
	# status table, the events of both drivers.
	while read -r page w; do
		[ -f "$out/$page" ] || { echo "no $page"; return 1; }
		grep -qF -- "$w" "$out/$page" || { echo "$page has no \"$w\""; return 1; }
		echo "$page: \"$w\""
	done <<-EOF
		userspace-api/lego.html struct lego_ev3_port_label
		userspace-api/lego.html LEGO_EV3_SET_PORT_LABEL
		userspace-api/lego.html struct nxt_transaction
		userspace-api/lego.html NXT_IOC_TRANSACT
		iio/lego_ev3_uart.html ldattach $(sed -n 's/^#define N_LEGOEV3[[:space:]]*\([0-9]*\).*/\1/p' "$work/include/uapi/linux/tty.h")
		iio/lego_ev3_uart.html intensity_red
		usb/lego_nxt.html no active program
		trace/events-lego.html ev3_uart_handshake
		trace/events-lego.html nxt_usb_drain
	EOF
	# What stays out of the tree is not in it.
	if grep -lE 'udev/[0-9]+-lego|lego-sensors --trace|nxtctl|tests/emulator' \
		"$out/iio/lego_ev3_uart.html" "$out/usb/lego_nxt.html" "$out/trace/events-lego.html"; then
		echo "the pages above name this repository's package"
		return 1
	fi
}

for s in "${steps[@]}"; do
	case "$s" in
	series | am | checkpatch | kernel-doc | abi | headers | build-x86_64-[my] | build-arm64-[my] | bisect | kunit | kunit-arm64 | coccicheck | htmldocs | lego-docs | refs) ;;
	*) echo "$prog: unknown step $s" >&2; exit 2 ;;
	esac
done

start=$(date +%s)
for s in "${steps[@]}"; do
	t=$(date +%s)
	case "$s" in
	series) step_series >"$logs/$s.log" 2>&1 ;;
	am) step_am >"$logs/$s.log" 2>&1 ;;
	checkpatch) step_checkpatch >"$logs/$s.log" 2>&1 ;;
	kernel-doc) step_kernel_doc >"$logs/$s.log" 2>&1 ;;
	abi) step_abi >"$logs/$s.log" 2>&1 ;;
	headers) step_headers >"$logs/$s.log" 2>&1 ;;
	kunit) step_kunit um >"$logs/$s.log" 2>&1 ;;
	kunit-arm64) step_kunit arm64 >"$logs/$s.log" 2>&1 ;;
	coccicheck) step_coccicheck >"$logs/$s.log" 2>&1 ;;
	bisect) step_bisect >"$logs/$s.log" 2>&1 ;;
	lego-docs) step_lego_docs >"$logs/$s.log" 2>&1 ;;
	refs) step_refs >"$logs/$s.log" 2>&1 ;;
	htmldocs) step_htmldocs >"$logs/$s.log" 2>&1 ;;
	build-*-*)
		a=${s#build-}
		step_build "${a%-*}" "${a##*-}" >"$logs/$s.log" 2>&1
		;;
	esac
	rc=$?
	result "$s" "$(( $(date +%s) - t ))" "$rc"
	# Nothing can be checked without the series applied.
	if [ "$rc" != 0 ] && { [ "$s" = series ] || [ "$s" = am ]; }; then
		break
	fi
done
echo "$prog: $passed passed, $failed failed in $(( $(date +%s) - start )) s"
[ "$failed" = 0 ]
