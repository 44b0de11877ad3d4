#!/usr/bin/env python3
"""The drivers' layering, read from what was compiled and written.

  tests/layering/check.py BUILD_DIR [--driver ev3|nxt]... [--report] [--src DIR]

For each driver (drivers/lego/ev3, drivers/lego/nxt), the objects of its
module in BUILD_DIR (tests/build-modules.sh's output): object A uses object
B when A refers to a global symbol B defines (nm). A circle among them (A
uses B and B, directly or not, uses A) fails, as does a function of the
drivers' C sources longer than MAX_LINES lines from its opening brace to its
closing one (kernel style: both alone at the start of a line), a view (the
sysfs class, IIO, the char device, sysfs attributes) that uses its
transport's object or includes its transport's header, and a source file
that reads a field of a structure another file owns (the EV3 parser's:
the port asks ev3_uart_proto.h's questions instead). KUnit test objects
are left out. --driver checks only the drivers named (all by default).
--report prints the graph and the long functions and exits 0. --src
reads the sources from DIR/drivers/lego rather than this checkout's
(tests/layering/test_check.py plants faults in a copy).
"""
import argparse
import glob
import os
import re
import subprocess
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
MAX_LINES = 60
DRIVERS = {
    # The discipline's structure is private to ev3_uart_ldisc.c: it has no
    # header a view could include.
    'ev3': {'views': ['ev3_uart_class.c', 'ev3_uart_iio.c', 'ev3_uart_leds.c'], 'transport': ['ev3_uart_ldisc.h'],
            'transport_objs': ['ev3_uart_ldisc.o'],
            # (owner, a use of a field, what): struct ev3_uart_parser's
            # fields are read through its accessors outside its own file.
            'private': [('ev3_uart_proto.c', r'\bparser\s*(?:\.|->)\s*(\w+)', 'the parser')]},
    'nxt': {'views': ['nxt_cdev.c', 'nxt_sysfs.c', 'nxt_i2c.c'], 'transport': ['nxt_usb.h'],
            'transport_objs': ['nxt_usb.o', 'nxt_serial.o']},
}


def symbols(obj):
    """(defined globals, undefined) of one object."""
    out = subprocess.run(['nm', obj], capture_output=True, text=True, check=True).stdout
    defined, undefined = set(), set()
    for line in out.splitlines():
        f = line.split()
        if len(f) == 2 and f[0] == 'U':
            undefined.add(f[1])
        elif len(f) == 3 and f[1] in 'TDBRGSVW':
            defined.add(f[2])
    return defined, undefined


def uses(objs):
    """{object: set of objects whose symbols it uses}."""
    syms = {o: symbols(o) for o in objs}
    owner = {}
    for o, (d, _) in syms.items():
        for s in d:
            owner[s] = o
    return {o: {owner[s] for s in u if s in owner and owner[s] != o} for o, (_, u) in syms.items()}


def circles(graph):
    """The strongly connected components of more than one node (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


FUNC = re.compile(r'^(?:[A-Za-z_][\w\s\*]*?)\b(\w+)\s*\(')


def long_functions(path, limit=MAX_LINES):
    """[(name, lines)] of the functions in a C file longer than limit lines
    from '{' to '}' (each alone at the start of a line)."""
    lines = open(path).read().splitlines()
    found, name, start = [], None, None
    for i, line in enumerate(lines):
        if start is None:
            m = FUNC.match(line)
            if m and not line.startswith(('static const', 'struct', '#')):
                name = m.group(1)
            if line == '{' and name:
                start = i
        elif line == '}':
            n = i - start + 1
            if n > limit:
                found.append((name, n))
            name, start = None, None
    return found


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('build')
    ap.add_argument('--driver', action='append', choices=sorted(DRIVERS))
    ap.add_argument('--report', action='store_true')
    ap.add_argument('--src', default=TOP)
    args = ap.parse_args(argv)
    bad = []
    for drv in args.driver or sorted(DRIVERS):
        conf = DRIVERS[drv]
        src = os.path.join(args.src, 'drivers/lego', drv)
        objs = [o for o in glob.glob(os.path.join(args.build, 'drivers/lego', drv, '*.o'))
                if not re.search(r'(_test|\.mod|lego_\w+)\.o$', o)]
        if not objs:
            print('layering: no objects of %s in %s' % (drv, args.build), file=sys.stderr)
            return 2
        graph = uses(objs)
        name = {o: os.path.basename(o) for o in objs}
        if args.report:
            for o in sorted(graph):
                print('%s: %s uses %s' % (drv, name[o], ' '.join(sorted(name[x] for x in graph[o]))
                                          or '-'))
        for c in circles(graph):
            bad.append('%s: a circle: %s' % (drv, ' <-> '.join(name[o] for o in c)))
        for o in sorted(graph):
            if name[o].replace('.o', '.c') in conf['views']:
                for t in sorted(graph[o]):
                    if name[t] in conf['transport_objs']:
                        bad.append('%s: the view %s uses its transport %s' % (drv, name[o],
                                                                            name[t]))
        for c in sorted(glob.glob(os.path.join(src, '*.c'))):
            if c.endswith('_test.c'):
                continue
            for fn, n in long_functions(c):
                bad.append('%s: %s() is %d lines (at most %d)' % (os.path.basename(c), fn, n,
                                                                   MAX_LINES))
        for owner, pattern, what in conf.get('private', []):
            for c in sorted(glob.glob(os.path.join(src, '*.c'))):
                base = os.path.basename(c)
                if base == owner or base.endswith('_test.c'):
                    continue
                fields = sorted(set(re.findall(pattern, open(c).read())))
                if fields:
                    bad.append('%s: reads %s\'s fields %s (only %s may)'
                               % (base, what, ', '.join(fields), owner))
        for v in conf['views']:
            if not os.path.exists(os.path.join(src, v)):
                continue        # a view this tree has not (the tests' small trees)
            text = open(os.path.join(src, v)).read()
            for h in conf['transport']:
                if re.search(r'#include\s+"%s"' % re.escape(h), text):
                    bad.append('%s: the view includes the transport\'s %s' % (v, h))
    for b in bad:
        print('layering: %s' % b)
    print('layering: %d problem(s)' % len(bad))
    return 0 if args.report or not bad else 1


if __name__ == '__main__':
    sys.exit(main())
