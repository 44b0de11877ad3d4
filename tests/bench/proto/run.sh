#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-2.0
#
# Benchmark figure 4, protocol-core cost: instructions per received byte of
# the EV3 parser (drivers/lego/ev3/ev3_uart_proto.c) and of the NXT reply
# decoder (drivers/lego/nxt/nxt_proto.c), built in userspace with -O2 and no
# sanitizers (as tests/fuzz builds them, with tests/fuzz/shim), over recorded
# streams (make-streams.py), counted with callgrind: deterministic for a
# given compiler and source.
#
#   tests/bench/proto/run.sh OUTDIR [--quick]
#
# Writes OUTDIR/proto.json (the results interface of tests/bench/report.py)
# and keeps the streams, binaries and callgrind files in OUTDIR/proto/.
# --quick: streams a tenth as long. Exits non-zero only on an error (a
# missing tool, a failed build, a stream the parser did not read as
# recorded), never on a figure.
set -euo pipefail
top=$(cd "$(dirname "$0")/../../.." && pwd)

usage() {
	sed -n '4,17p' "$0" | sed 's/^# \{0,1\}//'
	exit 2
}
outdir=
quick=
for a in "$@"; do
	case $a in
	--quick) quick=--quick ;;
	-h|--help) usage ;;
	-*) echo "proto/run.sh: unknown option $a" >&2; usage ;;
	*) outdir=$a ;;
	esac
done
[ -n "$outdir" ] || usage
for tool in valgrind python3 "${CC:=gcc}"; do
	command -v "$tool" >/dev/null || { echo "proto/run.sh: $tool not found (tests/install-deps.sh)" >&2; exit 1; }
done
mkdir -p "$outdir"
outdir=$(cd "$outdir" && pwd)
work=$outdir/proto
mkdir -p "$work"

# The kernel's -O2 and its char and aliasing rules, as for the modules.
# DWARF 4: valgrind 3.19 cannot read clang-14's DWARF 5.
cflags=(-O2 -gdwarf-4 -std=gnu11 -D_GNU_SOURCE -funsigned-char -fno-strict-aliasing -DLEGO_HAVE_LINUX_UNALIGNED
	-Wall -Wextra -Werror -Wno-unused-parameter -Wno-sign-compare
	-I"$top/tests/fuzz/shim" -I"$top/tests/fuzz" -I"$top/include/uapi" -I"$top/drivers/lego")
"$CC" "${cflags[@]}" -I"$top/drivers/lego/ev3" "$top/tests/bench/proto/bench_ev3.c" \
	"$top/drivers/lego/ev3/ev3_uart_proto.c" -o "$work/bench_ev3"
"$CC" "${cflags[@]}" -I"$top/drivers/lego/nxt" "$top/tests/bench/proto/bench_nxt.c" \
	"$top/drivers/lego/nxt/nxt_proto.c" -o "$work/bench_nxt"
python3 "$top/tests/bench/proto/make-streams.py" "$work" $quick

# callgrind counts only inside the entry points the drivers call per
# received batch or reply (and what they call), not the harness.
callgrind() {
	local name=$1
	shift
	local ir
	valgrind --tool=callgrind --callgrind-out-file="$work/callgrind.$name" \
		"$@" >"$work/$name.out" 2>"$work/$name.valgrind" || {
		echo "proto/run.sh: callgrind failed, see $work/$name.valgrind" >&2
		return 1
	}
	ir=$(sed -n 's/^summary: *//p' "$work/callgrind.$name")
	[ -n "$ir" ] && [ "$ir" -gt 0 ] || {
		echo "proto/run.sh: callgrind counted nothing for $name ($work/$name.valgrind)" >&2
		return 1
	}
	echo "$ir"
}
ev3_ir=$(callgrind ev3 --toggle-collect=ev3_uart_parser_feed \
	"$work/bench_ev3" "$work/ev3.stream" "$work/ev3.unplug")
nxt_ir=$(callgrind nxt --toggle-collect=nxt_reply_check --toggle-collect=nxt_command_decode \
	--toggle-collect=nxt_decode_versions --toggle-collect=nxt_decode_device_info \
	"$work/bench_nxt" "$work/nxt.records")

python3 - "$outdir/proto.json" "$work" "$ev3_ir" "$nxt_ir" "$("$CC" --version | head -n 1)" \
	"$(uname -m)" <<'PYEOF'
import json
import sys

out, work, ev3_ir, nxt_ir, cc, arch = sys.argv[1:]
ev3_ir, nxt_ir = int(ev3_ir), int(nxt_ir)


def counts(name):
    w = open('%s/%s.out' % (work, name)).read().split()
    return {w[i]: int(w[i + 1]) for i in range(0, len(w) - 1, 2)}


e = counts('ev3')
n = counts('nxt')
unplugs = len(open(work + '/ev3.unplug').read().split())
# The stream is read as recorded, or the figure means nothing.
if e['handshakes'] != unplugs or e['errors'] != unplugs - 1 or e['data'] == 0:
    sys.exit('proto/run.sh: the EV3 stream was not parsed as recorded: %s' % e)
if n['bad'] or n['accepted'] != n['replies']:
    sys.exit('proto/run.sh: NXT replies rejected: %s' % n)

# Budgets: the EV3 brick (300 MHz ARM9) receiving at the protocol's top
# speed, 460800 baud 8N1 = 46080 bytes/s, at one instruction per cycle.
budget_ev3 = 300e6 / 46080
ev3_per_byte = ev3_ir / e['bytes']
nxt_per_byte = nxt_ir / n['bytes']
nxt_per_reply = nxt_ir / n['replies']
# The NXT answers one command at a time, at most about 1000 a second over
# USB; the same 300 MHz core then has 300000 instructions per reply.
budget_nxt = 300e6 / 1000
res = {
    'section': 'Protocol-core cost (callgrind, userspace build of the driver sources)',
    'figures': [
        {'name': 'EV3 parser: instructions per received byte',
         'value': round(ev3_per_byte, 1), 'unit': 'instructions/byte',
         'reference': 'byte budget of the EV3 brick (300 MHz ARM9, 1 instruction/cycle) '
                      'at 460800 baud, the protocol\'s top speed',
         'reference_value': round(budget_ev3),
         'target': None, 'met': None,
         'detail': '%d instructions in ev3_uart_parser_feed() over %d bytes: %d handshakes '
                   '(colour, ultrasonic, gyro, infrared, FatcatLab humidity), %d DATA '
                   'messages, %d sensor losses; %.2f%% of the byte budget (%.2f%% at the '
                   'LEGO sensors\' 57600 baud)'
                   % (ev3_ir, e['bytes'], e['handshakes'], e['data'], e['errors'],
                      100 * ev3_per_byte / budget_ev3, 100 * ev3_per_byte / (300e6 / 5760))},
        {'name': 'NXT reply decoder: instructions per received byte',
         'value': round(nxt_per_byte, 1), 'unit': 'instructions/byte',
         'reference': 'deterministic count, lower is better', 'reference_value': None,
         'target': None, 'met': None,
         'detail': '%d instructions in nxt_reply_check() and the decoders over %d replies '
                   '(%d bytes): a polling loop of GetInputValues, GetOutputState, '
                   'SetOutputState, LSWrite/LSGetStatus/LSRead, MessageRead, battery, '
                   'keep-alive and sysfs GetVersions/GetDeviceInfo'
                   % (nxt_ir, n['replies'], n['bytes'])},
        {'name': 'NXT reply decoder: instructions per reply',
         'value': round(nxt_per_reply, 1), 'unit': 'instructions/reply',
         'reference': 'budget per reply of a 300 MHz core at the brick\'s ~1000 replies/s',
         'reference_value': round(budget_nxt),
         'target': None, 'met': None,
         'detail': '%.3f%% of that budget' % (100 * nxt_per_reply / budget_nxt)},
    ],
    'notes': [
        'callgrind instruction counts of %s code (%s, -O2, the kernel\'s -funsigned-char '
        '-fno-strict-aliasing), counted only inside the driver entry points '
        '(--toggle-collect), so the harness costs nothing; the same source and compiler '
        'give the same counts on any machine.' % (arch, cc),
        'Streams from tests/bench/proto/make-streams.py (the emulators\' sensor and '
        'firmware models), received in 16-byte batches with a keep-alive tick per 100 ms '
        'of bytes.',
    ],
}
with open(out, 'w') as f:
    json.dump(res, f, indent=1)
    f.write('\n')
for fig in res['figures']:
    print('%-52s %10s %-22s (reference: %s)' % (fig['name'], fig['value'], fig['unit'],
                                               fig['reference_value']))
PYEOF
