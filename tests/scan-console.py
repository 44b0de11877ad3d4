#!/usr/bin/env python3
"""Find kernel splats in a guest console log.

Only kernel lines (those with the printk timestamp) are looked at, so test
output that happens to say "WARNING" does not count; kmemleak reports, which
come from reading debugfs, are matched on their own text.

Usage: tests/scan-console.py [--kcsan-ours] CONSOLE.LOG
(exit 1 if any splat is found)

--kcsan-ours: for the KCSAN kernel. KCSAN reports data races anywhere in the
kernel; a report (from "BUG: KCSAN:" to its closing line of "=") counts
only if one of its lines names our code (a frame in a lego_* module, or an
ev3_uart_/nxt_ function). The others are listed as foreign, and ignored.
"""
import re
import sys

KERNEL_LINE = re.compile(r'^\[\s*\d+\.\d+\]\s?(.*)$')
SPLATS = [
    re.compile(p) for p in (
        r'\bBUG: ',
        r'\bWARNING: ',
        r'\bOops\b',
        r'general protection fault',
        r'Kernel panic',
        r'KASAN: ',
        r'UBSAN: ',
        r'possible circular locking dependency',
        r'possible recursive locking',
        r'inconsistent lock state',
        r'blocked for more than',
        r'sleeping function called from invalid context',
        r'suspected memory leak',
        r'ODEBUG: ',
        r'\bstack-protector\b',
        r'Call Trace:',
    )
]
KMEMLEAK = re.compile(r'^unreferenced object 0x')
KCSAN_START = re.compile(r'BUG: KCSAN: ')
KCSAN_END = re.compile(r'^={20,}$')
OURS = re.compile(r'\[lego_\w+\]|\b(ev3_uart|ev3_iio|nxt)_\w+')


def scan(lines, kcsan_ours=False):
    """Splats as (line number, line); with kcsan_ours, also the foreign
    KCSAN reports' first lines, as a second list."""
    found, foreign = [], []
    report = None           # lines of the KCSAN report being read
    for n, raw in enumerate(lines, 1):
        line = raw.rstrip('\r\n').replace('\r', '')
        m = KERNEL_LINE.match(line)
        text = m.group(1) if m else None
        if report is not None:
            if text is not None and KCSAN_END.match(text.strip()):
                ours = any(OURS.search(t) for _, t in report)
                (found if ours else foreign).append(report[0])
                report = None
            elif text is not None:
                report.append((n, text))
            continue
        if kcsan_ours and text is not None and KCSAN_START.search(text):
            report = [(n, line)]
        elif text is not None and any(p.search(text) for p in SPLATS):
            found.append((n, line))
        elif KMEMLEAK.match(line):
            found.append((n, line))
    if report is not None:          # cut short: judge what there is
        ours = any(OURS.search(t) for _, t in report)
        (found if ours else foreign).append(report[0])
    return found, foreign


def main():
    args = sys.argv[1:]
    kcsan_ours = '--kcsan-ours' in args
    args = [a for a in args if a != '--kcsan-ours']
    with open(args[0], errors='replace') as f:
        found, foreign = scan(f, kcsan_ours)
    for n, line in foreign[:20]:
        print(f'foreign KCSAN report (ignored): line {n}: {line}')
    for n, line in found[:40]:
        print(f'splat: line {n}: {line}')
    if len(found) > 40:
        print(f'splat: ... and {len(found) - 40} more lines')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main())
