#!/usr/bin/env python3
"""Find kernel splats in a guest console log.

Only kernel lines (those with the printk timestamp) are looked at, so test
output that happens to say "WARNING" does not count; kmemleak reports, which
come from reading debugfs, are matched on their own text.

Usage: tests/scan-console.py CONSOLE.LOG   (exit 1 if any splat is found)
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


def scan(lines):
    found = []
    for n, raw in enumerate(lines, 1):
        line = raw.rstrip('\r\n').replace('\r', '')
        m = KERNEL_LINE.match(line)
        text = m.group(1) if m else None
        if text is not None and any(p.search(text) for p in SPLATS):
            found.append((n, line))
        elif KMEMLEAK.match(line):
            found.append((n, line))
    return found


def main():
    with open(sys.argv[1], errors='replace') as f:
        found = scan(f)
    for n, line in found[:40]:
        print(f'splat: line {n}: {line}')
    if len(found) > 40:
        print(f'splat: ... and {len(found) - 40} more lines')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main())
