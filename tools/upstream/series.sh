#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-2.0
#
# `make upstream-series`: the drivers as a patch series against the kernel
# source of Debian's linux-source-SERIES package (default 6.12; 6.1 too,
# `make upstream-series UPSTREAM_SERIES=6.1`), written with
# git format-patch --cover-letter into .build/upstream/SERIES/.
#
#   tools/upstream/series.sh [SERIES]
#
# The kernel source is committed once as the base of a scratch repository,
# .build/upstream/linux-SERIES (tagged with the package's version: it is
# unpacked again only when the package changes, into a bare repository in
# the kernel cache that each checkout's scratch repository borrows from,
# up_base in tools/upstream/lib.sh). The series is built on the
# branch lego-SERIES from this checkout's files, copied at generation time:
# there is no second copy of any source. What differs in-tree is either a
# file of this repository that the out-of-tree build does not read
# (drivers/lego/*/Kconfig, .kunitconfig, the Makefile that the out-of-tree
# Kbuild includes, tools/upstream/MAINTAINERS, the userspace API page
# tools/upstream/doc/lego.rst, the commit messages in tools/upstream/msg/)
# or a mechanical rule:
#
# - files move to their mainline places (tools/upstream/places.py), and
#   every path a file names is mapped to its place;
# - the documentation pages (the drivers' and the trace events' pages of
#   Documentation/lego) drop what is about this repository's package, between
#   ".. out-of-tree-begin" and ".. out-of-tree-end", and take the blocks of
#   their ".. in-tree" comments (tools/upstream/intree.py);
# - C sources and headers go through tools/upstream/intree.py, which drops
#   drivers/lego/lego_compat.h's shims for what they mean in the target tree
#   (its LEGO_HAVE_* flags come from the top-level Kbuild's own probes, run
#   by kbuild on a configured tree of the same source: up_have in
#   tools/upstream/lib.sh) and runs unifdef -DN_LEGOEV3 -DN_LEGONXT;
# - hooks into existing kernel files, each inserted at a fixed or sorted
#   place and checked: N_LEGOEV3 and N_LEGONXT in include/uapi/linux/tty.h
#   (the next free numbers, NR_LDISCS raised), the ioctl magic numbers in
#   Documentation/userspace-api/ioctl/ioctl-number.rst, the Kconfig
#   "source" lines and Makefile lines of drivers/iio/common and
#   drivers/usb/misc, the pages in the index.rst of Documentation/iio,
#   usb, trace and userspace-api, the MAINTAINERS entries (each patch adds
#   the F: lines of the files it adds).
#
# Commits carry the author and Signed-off-by of this checkout's HEAD, and
# HEAD's commit date, so the same checkout gives the same patches.
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
here=$top/tools/upstream
series=${1:-newest}
prog=upstream-series
# shellcheck source=tools/upstream/lib.sh
. "$here/lib.sh"

command -v unifdef >/dev/null || { echo "$prog: unifdef missing (tests/install-deps.sh installs it)" >&2; exit 1; }
up_base
tag=$(up_base_tag)
tree=$up_repo
have=$(up_have) || { echo "$prog: no configured $series tree to probe" >&2; exit 1; }
date=$(git -C "$top" log -1 --format=%cI HEAD)
export GIT_AUTHOR_DATE=$date GIT_COMMITTER_DATE=$date

# The mainline place of each directory of this repository.
EV3=$("$here/places.py" drivers/lego/ev3)
NXT=$("$here/places.py" drivers/lego/nxt)

# The line discipline's number in the tree (piece_ldisc).
ldisc=

up_git checkout -q -f -B "$up_branch" "$tag"
up_git clean -q -fdx

die() { echo "$prog: $*" >&2; exit 1; }

# put SRC DST: copy a file of this checkout into the tree: C, headers,
# documentation pages and ABI files through intree.py (which also maps the
# paths they name to their places); an ABI file's Contact: becomes the
# mailing list of its MAINTAINERS entry (the out-of-tree package names its
# own address).
put() {
	local list
	mkdir -p "$(dirname "$tree/$2")"
	case "$1" in
	*.c | *.h | *.rst) "$here/intree.py" --have "$have" --ldisc "$ldisc" "$top/$1" "$tree/$2" ;;
	Documentation/ABI/*)
		list=$(awk -v f="F:\t$2" '/^L:/ { l = $2 } $0 == f { print l; exit }' "$here/MAINTAINERS")
		[ -n "$list" ] || die "$2: not in tools/upstream/MAINTAINERS"
		"$here/intree.py" "$top/$1" "$tree/$2"
		sed -i "s/^Contact:.*/Contact:\t$list/" "$tree/$2"
		;;
	*) cp "$top/$1" "$tree/$2" ;;
	esac
}

# put_dir SRCDIR DSTDIR FILE...: put several files of one directory.
put_dir() {
	local src=$1 dst=$2 f
	shift 2
	for f in "$@"; do put "$src/$f" "$dst/$f"; done
}

# insert_sorted FILE REGEX LINE: among the lines matching REGEX, insert LINE
# before the first that sorts after it (after the last if none does).
insert_sorted() {
	local file=$tree/$1
	grep -qxF -- "$3" "$file" && return 0
	grep -qE -- "$2" "$file" || die "$1: no line matches $2"
	LC_ALL=C awk -v re="$2" -v new="$3" '
	!done && $0 ~ re && $0 > new { print new; done = 1 }
	{ print }
	$0 ~ re { last = NR }
	' "$file" >"$file.new"
	if ! grep -qxF -- "$3" "$file.new"; then
		# None sorted after it: after the last matching line.
		LC_ALL=C awk -v re="$2" -v new="$3" '
		{ lines[NR] = $0; if ($0 ~ re) last = NR }
		END { for (i = 1; i <= NR; i++) { print lines[i]; if (i == last) print new } }
		' "$file" >"$file.new"
	fi
	mv "$file.new" "$file"
}

# insert_before FILE ANCHOR TEXT: insert TEXT (lines) before the line ANCHOR.
insert_before() {
	local file=$tree/$1
	grep -qxF -- "$2" "$file" || die "$1: no line \"$2\""
	awk -v anchor="$2" -v text="$3" '
	$0 == anchor && !done { print text; done = 1 }
	{ print }' "$file" >"$file.new"
	mv "$file.new" "$file"
}

# toctree_append FILE MEMBER ENTRY: add ENTRY to FILE's toctree that lists
# MEMBER, after its last entry (where a tree has one toctree or several).
toctree_append() {
	local file=$tree/$1
	grep -qxF -- "   $2" "$file" || die "$1: no toctree entry $2"
	awk -v member="   $2" -v new="   $3" '
	$0 == member { in_toc = 1 }
	in_toc && !/^   [^ :]/ { print new; in_toc = 0 }
	{ print }
	END { if (in_toc) print new }' "$file" >"$file.new"
	mv "$file.new" "$file"
}

# maintainers: MAINTAINERS as in the base plus our entries, with only the
# F: lines of paths the tree has by now (an entry with none is left out),
# before the first entry that sorts after them.
maintainers() {
	local entries
	entries=$(awk -v tree="$tree" -v author="$up_name <$up_email>" '
	function flush() { if (nf) printf "%s%s", (n++ ? "\n" : ""), buf; buf = ""; nf = 0 }
	/^$/ { flush(); next }
	/^F:/ { p = $0; sub(/^F:[ \t]*/, "", p); if (system("test -e \"" tree "/" p "\"")) next; nf++ }
	{ gsub(/@AUTHOR@/, author); buf = buf $0 "\n" }
	END { flush() }' "$here/MAINTAINERS")
	up_git show "$tag:MAINTAINERS" >"$tree/MAINTAINERS"
	[ -n "$entries" ] || return 0
	# Our titles sort between "LEGO MINDSTORMS EV3" and "LEGO USB Tower driver".
	insert_before MAINTAINERS "LEGO USB Tower driver" "$entries
"
}

# commit MSG: commit everything with tools/upstream/msg/MSG, signed off.
# @EV3_CASES@ and @NXT_CASES@ in a message are the KUnit suites' case counts.
commit() {
	local ev3 nxt
	maintainers
	# -f: Debian's .gitignore ignores everything at the top level.
	up_git add -A -f .
	ev3=$(up_kunit_cases "$top"/drivers/lego/ev3/*_test.c)
	nxt=$(up_kunit_cases "$top"/drivers/lego/nxt/*_test.c)
	sed -e "s/@EV3_CASES@/$ev3/g" -e "s/@NXT_CASES@/$nxt/g" "$here/msg/$1" |
		up_git commit -q -s --no-verify -F -
}

# 1. The line discipline number: the next free one.
piece_ldisc() {
	local f=include/uapi/linux/tty.h nr
	nr=$(sed -n 's/^#define NR_LDISCS[[:space:]]*\([0-9]*\).*/\1/p' "$tree/$f")
	[ -n "$nr" ] || die "$f: no NR_LDISCS"
	awk -v nr="$nr" '
	/^#define N_[A-Z0-9_]+[ \t]/ { last = NR }
	{ lines[NR] = $0 }
	END {
		for (i = 1; i <= NR; i++) {
			if (lines[i] ~ /^#define NR_LDISCS/)
				lines[i] = "#define NR_LDISCS\t" nr + 2
			print lines[i]
			if (i == last) {
				printf "#define N_LEGOEV3\t%d\t/* LEGO MINDSTORMS EV3 UART sensors */\n", nr
				printf "#define N_LEGONXT\t%d\t/* LEGO MINDSTORMS NXT on Bluetooth */\n", nr + 1
			}
		}
	}' "$tree/$f" >"$tree/$f.new"
	mv "$tree/$f.new" "$tree/$f"
	grep -q "^#define N_LEGOEV3" "$tree/$f" || die "$f: N_LEGOEV3 not added"
	grep -q "^#define N_LEGONXT" "$tree/$f" || die "$f: N_LEGONXT not added"
	ldisc=$nr
	commit 1-tty.txt
}

# 2. The uapi headers and their ioctl magic numbers.
piece_uapi() {
	local f=Documentation/userspace-api/ioctl/ioctl-number.rst
	put include/uapi/linux/lego_ev3_uart.h include/uapi/linux/lego_ev3_uart.h
	put include/uapi/linux/lego_nxt.h include/uapi/linux/lego_nxt.h
	grep -q '^0xE[34] ' "$tree/$f" && die "$f: 0xE3 or 0xE4 is taken"
	insert_sorted "$f" '^0x[0-9A-F][0-9A-F] ' \
		'0xE3  01-02  uapi/linux/lego_ev3_uart.h                                LEGO MINDSTORMS EV3 UART sensors'
	insert_sorted "$f" '^0x[0-9A-F][0-9A-F] ' \
		'0xE4  00-23  uapi/linux/lego_nxt.h                                     LEGO MINDSTORMS NXT bricks'
	commit 2-uapi.txt
}

# 3. The EV3 protocol core and its KUnit suite (built from 4 on).
piece_ev3_proto() {
	put_dir drivers/lego/ev3 "$EV3" ev3_uart_proto.h ev3_uart_proto.c ev3_uart_chan.h \
		ev3_uart_chan.c ev3_uart_proto_test.c
	commit 3-ev3-proto.txt
}

# 4. The sensor core, the line discipline and IIO; Kconfig and Makefile
# without the lego-sensor class (5), the ABI of the IIO channels.
piece_ev3_ldisc() {
	put_dir drivers/lego/ev3 "$EV3" ev3_uart_core.h ev3_uart_core.c ev3_uart_views.h \
		ev3_uart_ldisc.c ev3_uart_iio.c ev3_uart_leds.c ev3_uart_trace.h ev3_uart_trace.c Kconfig \
		Makefile .kunitconfig
	# The class's option and object come with the class.
	awk '/^config LEGO_EV3_UART_CLASS$/ { skip = 1; next }
	     skip && /^config / { skip = 0 }
	     !skip' "$tree/$EV3/Kconfig" >"$tree/$EV3/Kconfig.new"
	mv "$tree/$EV3/Kconfig.new" "$tree/$EV3/Kconfig"
	sed -i '/ev3_uart_class\.o/d' "$tree/$EV3/Makefile"
	! grep -q -e LEGO_EV3_UART_CLASS -e ev3_uart_class "$tree/$EV3/Kconfig" "$tree/$EV3/Makefile" ||
		die "$EV3: the class is left in Kconfig or Makefile"
	put_dir Documentation/ABI/testing Documentation/ABI/testing sysfs-bus-iio-lego-ev3-uart \
		sysfs-class-led-lego-ev3-uart
	insert_sorted drivers/iio/common/Kconfig '^source "drivers/iio/common/' \
		"source \"$EV3/Kconfig\""
	insert_sorted drivers/iio/common/Makefile '^obj-y \+= ' 'obj-y += lego_ev3_uart/'
	commit 4-ev3-ldisc.txt
}

# 5. The lego-sensor class of ev3dev, its option, its ABI.
piece_ev3_class() {
	put_dir drivers/lego/ev3 "$EV3" ev3_uart_class.c Kconfig Makefile
	put_dir Documentation/ABI/testing Documentation/ABI/testing sysfs-class-lego-sensor
	commit 5-ev3-class.txt
}

# 6. The NXT telegram core, the transaction engine and their KUnit suites
# (built from 7 on).
piece_nxt_proto() {
	put_dir drivers/lego/nxt "$NXT" nxt_proto.h nxt_proto.c nxt_proto_test.c \
		nxt_core.h nxt_core.c nxt_core_test.c
	commit 6-nxt-proto.txt
}

# 7. The core module and the USB driver; Kconfig and Makefile without the
# serial transport (8), the ABI they add.
piece_nxt_usb() {
	put_dir drivers/lego/nxt "$NXT" nxt_views.h nxt_main.c nxt_usb.c nxt_cdev.c \
		nxt_sysfs.c nxt_usb_trace.h nxt_usb_trace.c Kconfig Makefile .kunitconfig
	kconfig_drop LEGO_NXT_SERIAL
	kconfig_drop LEGO_NXT_I2C
	sed -i -e '/LEGO_NXT_SERIAL/d' -e '/lego_nxt_serial/d' -e '/LEGO_NXT_I2C/d' \
		"$tree/$NXT/Makefile"
	! grep -q -e LEGO_NXT_SERIAL -e nxt_serial -e LEGO_NXT_I2C -e nxt_i2c \
		"$tree/$NXT/Kconfig" "$tree/$NXT/Makefile" ||
		die "$NXT: the serial transport or the I2C adapters are left in Kconfig or Makefile"
	put Documentation/ABI/testing/sysfs-class-lego-nxt \
		Documentation/ABI/testing/sysfs-class-lego-nxt
	# The adapters' entry comes with them (9).
	awk '/^What:/ { skip = $2 ~ /\/i2c-/ } !skip' \
		"$tree/Documentation/ABI/testing/sysfs-class-lego-nxt" \
		>"$tree/Documentation/ABI/testing/sysfs-class-lego-nxt.new"
	mv "$tree/Documentation/ABI/testing/sysfs-class-lego-nxt.new" \
		"$tree/Documentation/ABI/testing/sysfs-class-lego-nxt"
	sed -i -e '${/^$/d}' "$tree/Documentation/ABI/testing/sysfs-class-lego-nxt"
	# Beside the LEGO USB tower's entries.
	insert_before drivers/usb/misc/Kconfig "config USB_LCD" "source \"$NXT/Kconfig\"
"
	# shellcheck disable=SC2016 # make's $(CONFIG_...), not the shell's
	grep -q '^obj-$(CONFIG_USB_LEGOTOWER)' "$tree/drivers/usb/misc/Makefile" ||
		die "drivers/usb/misc/Makefile: no USB_LEGOTOWER line"
	# shellcheck disable=SC2016
	sed -i '/^obj-$(CONFIG_USB_LEGOTOWER)/a obj-$(CONFIG_LEGO_NXT)\t\t+= lego_nxt/' \
		"$tree/drivers/usb/misc/Makefile"
	commit 7-nxt-usb.txt
}

# 8. The serial (Bluetooth) transport: a line discipline, with its page
# (the pages of the drivers themselves come in 9).
piece_nxt_serial() {
	local dst
	put_dir drivers/lego/nxt "$NXT" nxt_serial.c Kconfig Makefile
	kconfig_drop LEGO_NXT_I2C
	sed -i -e '/LEGO_NXT_I2C/d' "$tree/$NXT/Makefile"
	dst=$("$here/places.py" Documentation/lego/nxt-bluetooth.rst)
	put Documentation/lego/nxt-bluetooth.rst "$dst"
	index_add "$dst"
	commit 8-nxt-serial.txt
}

# 9. The sensor ports as I2C adapters, their option, ABI entry and page.
piece_nxt_i2c() {
	local dst
	put_dir drivers/lego/nxt "$NXT" nxt_i2c.c Kconfig Makefile
	put Documentation/ABI/testing/sysfs-class-lego-nxt \
		Documentation/ABI/testing/sysfs-class-lego-nxt
	dst=$("$here/places.py" Documentation/lego/nxt-i2c.rst)
	put Documentation/lego/nxt-i2c.rst "$dst"
	index_add "$dst"
	commit 9-nxt-i2c.txt
}

# kconfig_drop OPTION: the entry of OPTION out of the NXT Kconfig.
kconfig_drop() {
	awk -v opt="config $1" '$0 == opt { skip = 1; next }
	     skip && /^config / { skip = 0 }
	     !skip' "$tree/$NXT/Kconfig" >"$tree/$NXT/Kconfig.new"
	mv "$tree/$NXT/Kconfig.new" "$tree/$NXT/Kconfig"
}

# 10. The documentation: each driver's page in its subsystem's guide, the
# trace events' page, and the userspace API guide's page with the uapi
# headers' kernel-doc. Each page goes into its directory's index, sorted
# among the pages there.
piece_docs() {
	local src dst
	for src in Documentation/lego/ev3-uart.rst Documentation/lego/nxt-usb.rst \
		Documentation/lego/tracing.rst; do
		dst=$("$here/places.py" "$src")
		put "$src" "$dst"
		index_add "$dst"
	done
	put tools/upstream/doc/lego.rst Documentation/userspace-api/lego.rst
	# Last in the toctree of media/index ("Devices and I/O" since 6.8).
	toctree_append Documentation/userspace-api/index.rst media/index lego
	commit 10-docs.txt
}

# index_add PAGE: PAGE's entry in the toctree of its directory's index.rst,
# indented as the entries there are, before the first entry that sorts
# after it in the toctree of the pages of its kind: drivers' pages in
# Documentation/iio and usb (in iio's toctree of drivers where it has one),
# events-* pages in Documentation/trace.
index_add() {
	local page=$1 index entry re after=
	index=$(dirname "$page")/index.rst
	entry=$(basename "$page" .rst)
	case "$index" in
	Documentation/iio/*) re='^   [a-z0-9][a-z0-9_-]*$'; after='Industrial I/O Kernel Drivers' ;;
	Documentation/usb/*) re='^    [a-z0-9][a-z0-9_-]*$' ;;
	Documentation/trace/*) re='^   events(-[a-z0-9]+)?$' ;;
	*) die "$page: no rule for its index" ;;
	esac
	# The same indentation as the entries.
	insert_sorted "$index" "$re" "$(grep -m1 -E "$re" "$tree/$index" | sed 's/[^ ].*//')$entry"
	# (6.1's index has one toctree, drivers and framework together.)
	if [ -n "$after" ] && grep -qxF "$after" "$tree/$index"; then
		awk -v a="$after" -v e="$entry" '$0 == a { seen = 1 } seen && $1 == e { ok = 1 } END { exit !ok }' \
			"$tree/$index" || die "$index: $entry is not after \"$after\""
	fi
}

piece_ldisc
piece_uapi
piece_ev3_proto
piece_ev3_ldisc
piece_ev3_class
piece_nxt_proto
piece_nxt_usb
piece_nxt_serial
piece_nxt_i2c
piece_docs

# Nothing of this checkout's drivers or their ABI may be left out of the series.
for f in "$top"/Documentation/ABI/testing/*lego*; do
	[ -e "$tree/Documentation/ABI/testing/$(basename "$f")" ] || die "$f is in no patch"
done
# (The files git tracks: not what a build left there.)
for f in $(git -C "$top" ls-files drivers/lego/ev3 drivers/lego/nxt); do
	b=$(basename "$f")
	[ "$b" = Kbuild ] && continue
	case "$f" in */ev3/*) d=$EV3 ;; *) d=$NXT ;; esac
	[ -e "$tree/$d/$b" ] || die "$f is in no patch"
done

# The cover letter: subject and body from tools/upstream/cover-letter.txt.
up_git config "branch.$up_branch.description" "$(cat "$here/cover-letter.txt")"
rm -rf "$up_patches"
up_git format-patch -q --cover-letter --cover-from-description=subject \
	--base="$tag" -o "$up_patches" "$tag..$up_branch" >/dev/null
n=$(find "$up_patches" -name '0*.patch' ! -name '0000-*' | wc -l)
echo "$prog: $n patches and a cover letter against linux-source-$series $(up_pkgver) in $up_patches" >&2
