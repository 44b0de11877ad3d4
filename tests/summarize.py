#!/usr/bin/env python3
"""Count the results of a `make check` run.

KUnit: every `<suite>.ktap` in RESULTS/kunit is parsed with the kernel's own
`tools/testing/kunit/kunit.py parse --json`, and every test case counted.
Guest tests: RESULTS/guest.xml (pytest's JUnit XML).

Usage: tests/summarize.py RESULTS KERNEL_TREE
Prints one line per source and writes "KUNIT_PASSED ..." style totals to
RESULTS/totals; exit 1 if the results are missing or unreadable.
"""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET


def kunit_cases(node):
    """Yield (name, status) of every leaf test case in kunit.py's JSON."""
    for case in node.get('test_cases', []):
        yield case['name'], case['status']
    for sub in node.get('sub_groups', []):
        yield from kunit_cases(sub)


def count_kunit(results, tree):
    passed = failed = skipped = 0
    kdir = os.path.abspath(os.path.join(results, 'kunit'))
    files = sorted(f for f in os.listdir(kdir) if f.endswith('.ktap')) if os.path.isdir(kdir) else []
    kunit_py = os.path.join(tree, 'tools/testing/kunit/kunit.py')
    for f in files:
        path = os.path.join(kdir, f)
        proc = subprocess.run([sys.executable, kunit_py, 'parse', '--json', path],
                              capture_output=True, text=True)
        text = proc.stdout
        start = text.find('{')
        if start < 0:
            print(f'kunit: {f}: kunit.py parse gave no JSON', file=sys.stderr)
            print(proc.stdout, proc.stderr, file=sys.stderr)
            failed += 1
            continue
        data = json.loads(text[start:])
        cases = list(kunit_cases(data))
        if not cases:
            print(f'kunit: {f}: no test case parsed', file=sys.stderr)
            failed += 1
        for name, status in cases:
            if status == 'PASS':
                passed += 1
            elif status == 'SKIP':
                skipped += 1
            else:
                failed += 1
                print(f'kunit: FAILED {f[:-5]}.{name}: {status}')
    bad = os.path.join(kdir, 'failed-modules')
    if os.path.exists(bad):
        with open(bad) as fh:
            for line in fh:
                print(f'kunit: FAILED module {line.strip()}')
                failed += 1
    return passed, failed, skipped, len(files)


def count_guest(results):
    path = os.path.join(results, 'guest.xml')
    if not os.path.exists(path):
        print('guest: no pytest results (guest.xml missing)', file=sys.stderr)
        return 0, 1, 0
    root = ET.parse(path).getroot()
    passed = failed = skipped = 0
    for case in root.iter('testcase'):
        kinds = {child.tag for child in case}
        name = f"{case.get('classname')}.{case.get('name')}"
        if 'failure' in kinds or 'error' in kinds:
            failed += 1
            print(f'guest: FAILED {name}')
        elif 'skipped' in kinds:
            skipped += 1
        else:
            passed += 1
    return passed, failed, skipped


def main():
    results, tree = sys.argv[1], sys.argv[2]
    kp, kf, ks, nsuites = count_kunit(results, tree)
    gp, gf, gs = count_guest(results)
    print(f'kunit: {nsuites} suites, {kp} passed, {kf} failed, {ks} skipped')
    print(f'guest: {gp} passed, {gf} failed, {gs} skipped')
    with open(os.path.join(results, 'totals'), 'w') as fh:
        fh.write(f'{kp + gp} {kf + gf} {ks + gs}\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
