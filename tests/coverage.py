#!/usr/bin/env python3
"""Which of the drivers' functions the test suite reached (gcov).

    tests/coverage.py [--all] [--check ALLOW] [--build BUILD] GCDA

GCDA is the directory where tests/guest/run-suite.sh saved the guest's
.gcda files, at their paths below BUILD, the modules' build directory
(tests/build-modules.sh's OUTDIR, built against a kernel with
CONFIG_GCOV_KERNEL: it holds a .gcno file beside each instrumented
object). BUILD defaults to the one GCDA/BUILD names (run-suite.sh writes
it). An object of BUILD with no .gcda was never loaded: all its
functions count as not reached.

Prints, for each source file of drivers/lego (and each header there
whose inline functions were emitted), how many of its functions were
called and how many of their basic blocks ran, and lists the functions no
test called (--all: every function, with its call count).

--check ALLOW fails (exit 1) on a function that no test reached and ALLOW
does not name, on an ALLOW line without a reason, on one that names no
function gcov knows (renamed or removed code), and when there is no gcov
data at all (a collection that broke must not pass as "all allowed").
An ALLOW line is "FUNCTION REASON...", or "FILE:FUNCTION REASON..." for a
static function whose name two files share; FILE is the path below BUILD.
A listed function that was reached is reported, not failed: some paths
(races, rare timings) are reached in some runs only.

A static inline function of a header is emitted in each object that calls
it; it counts as reached if any of them ran it.
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile

# Only our own code: the drivers and their headers (not the kernel's
# headers, whose inline functions gcov reports too), without the trace
# events' headers, whose functions TRACE_EVENT() generates (the trace_*()
# calls in the drivers are counted where they stand).
OURS = ('drivers/lego/', 'include/')
GENERATED = ('_trace.h',)


class Func:
    def __init__(self, path, name, line):
        self.path, self.name, self.line = path, name, line
        self.calls = 0
        self.blocks = 0
        self.blocks_run = 0

    @property
    def key(self):
        return f'{self.path}:{self.name}'


def gcov_tool():
    return os.environ.get('GCOV') or shutil.which('gcov') or 'gcov'


def gcov_json(gcno, gcda):
    """gcov's JSON report (format 1) of one object: its .gcno, with the
    .gcda when there is one (without, gcov counts nothing as run)."""
    with tempfile.TemporaryDirectory() as tmp:
        base = os.path.splitext(os.path.basename(gcno))[0]
        shutil.copy(gcno, os.path.join(tmp, base + '.gcno'))
        if gcda:
            shutil.copy(gcda, os.path.join(tmp, base + '.gcda'))
        out = subprocess.run([gcov_tool(), '--json-format', '--stdout', '-o', tmp,
                              os.path.join(tmp, base + '.gcno')],
                             cwd=tmp, capture_output=True, text=True)
        if out.returncode != 0 or not out.stdout.strip():
            raise RuntimeError(f'gcov failed on {gcno}: {out.stderr.strip()}')
        # One JSON document per line (one per data file given).
        return [json.loads(line) for line in out.stdout.splitlines() if line.strip()]


def ours(build, src, cwd):
    """The path of src below build if it is one of ours, else None."""
    path = os.path.realpath(os.path.join(cwd, src))
    rel = os.path.relpath(path, build)
    if rel.startswith('..') or not rel.startswith(OURS) or rel.endswith(GENERATED):
        return None
    return rel


def collect(build, gcda_dir):
    """{key: Func} for every function of our sources in build's objects,
    and the number of objects that had gcov data."""
    build = os.path.realpath(build)
    funcs = {}
    with_data = 0
    gcnos = sorted(glob.glob(os.path.join(build, 'drivers', 'lego', '**', '*.gcno'),
                             recursive=True))
    for gcno in gcnos:
        rel = os.path.relpath(gcno, build)
        gcda = os.path.join(gcda_dir, os.path.splitext(rel)[0] + '.gcda')
        if os.path.exists(gcda):
            with_data += 1
        else:
            gcda = None
        for doc in gcov_json(gcno, gcda):
            cwd = doc.get('current_working_directory', build)
            for f in doc['files']:
                path = ours(build, f['file'], cwd)
                if path is None:
                    continue
                for fn in f['functions']:
                    key = f'{path}:{fn["name"]}'
                    func = funcs.setdefault(key, Func(path, fn['name'], fn['start_line']))
                    func.calls += fn['execution_count']
                    func.blocks = max(func.blocks, fn['blocks'])
                    func.blocks_run = max(func.blocks_run, fn['blocks_executed'])
    return funcs, len(gcnos), with_data


def read_allow(path):
    """[(lineno, name or FILE:name, reason)] of an allow-list."""
    entries = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith('#'):
                continue
            name, _, reason = line.partition(' ')
            entries.append((n, name, reason.strip()))
    return entries


def report(funcs, show_all, out=None):
    out = out or sys.stdout
    files = {}
    for func in funcs.values():
        files.setdefault(func.path, []).append(func)
    tot_f = tot_r = tot_b = tot_br = 0
    for path in sorted(files):
        fl = sorted(files[path], key=lambda fn: fn.line)
        reached = sum(1 for fn in fl if fn.calls)
        blocks = sum(fn.blocks for fn in fl)
        run = sum(fn.blocks_run for fn in fl)
        tot_f += len(fl)
        tot_r += reached
        tot_b += blocks
        tot_br += run
        pct = 100.0 * run / blocks if blocks else 100.0
        print(f'{path}: {reached} of {len(fl)} functions reached, '
              f'blocks {run}/{blocks} ({pct:.1f} %)', file=out)
        for fn in fl:
            if show_all or not fn.calls:
                what = f'{fn.calls} calls, blocks {fn.blocks_run}/{fn.blocks}' if fn.calls \
                    else 'not reached'
                print(f'  {fn.name} (line {fn.line}): {what}', file=out)
    pct = 100.0 * tot_br / tot_b if tot_b else 100.0
    print(f'total: {tot_r} of {tot_f} functions reached, blocks {tot_br}/{tot_b} '
          f'({pct:.1f} %)', file=out)


def check(funcs, entries, allow_path, out=None):
    """The errors of --check, as lines."""
    out = out or sys.stdout
    errors = []
    by_name = {}
    for func in funcs.values():
        by_name.setdefault(func.name, []).append(func)
    allowed = set()
    for n, name, reason in entries:
        where = f'{allow_path}:{n}'
        if ':' in name:
            hits = [funcs[name]] if name in funcs else []
        else:
            hits = by_name.get(name, [])
        if not hits:
            errors.append(f'{where}: {name} is no function of the drivers (renamed or removed?)')
            continue
        if not reason:
            errors.append(f'{where}: {name} is listed without a reason')
        for func in hits:
            allowed.add(func.key)
            if func.calls:
                print(f'coverage: {func.key} is listed in {allow_path} but was reached '
                      f'({func.calls} calls)', file=out)
    for func in sorted(funcs.values(), key=lambda fn: (fn.path, fn.line)):
        if not func.calls and func.key not in allowed:
            errors.append(f'{func.path}:{func.line}: {func.name} is reached by no test: '
                          f'reach it, or name it in {allow_path} with the reason')
    return errors


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--all', action='store_true', help='list every function')
    ap.add_argument('--check', metavar='ALLOW', help='fail on unreached functions not in ALLOW')
    ap.add_argument('--build', help='the modules\' build directory (default: GCDA/BUILD)')
    ap.add_argument('gcda')
    args = ap.parse_args(argv)
    if not args.build:
        try:
            with open(os.path.join(args.gcda, 'BUILD')) as f:
                args.build = f.read().strip()
        except OSError:
            print(f'coverage: no gcov data in {args.gcda} (make check collects it)')
            return 1

    funcs, objects, with_data = collect(args.build, args.gcda)
    if not objects:
        print(f'coverage: no .gcno file under {args.build}/drivers/lego: '
              'the modules were not built with gcov (LEGO_COVERAGE=1, CONFIG_GCOV_KERNEL)')
        return 1
    report(funcs, args.all)
    print(f'coverage: {with_data} of {objects} objects had gcov data ({args.gcda})')
    if not args.check:
        return 0
    errors = check(funcs, read_allow(args.check), args.check)
    if not with_data:
        errors.append(f'no gcov data in {args.gcda}: the guest did not save it')
    for e in errors:
        print(f'coverage: {e}')
    if errors:
        print(f'coverage: {len(errors)} errors')
        return 1
    print(f'coverage: every function not reached is named in {args.check}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
