#!/usr/bin/env python3
"""Count the results of a `make check` run.

KUnit: every `<suite>.ktap` in RESULTS/kunit is parsed with the kernel's own
`tools/testing/kunit/kunit.py parse --json`, and every test case counted.
Guest tests: RESULTS/guest.xml (pytest's JUnit XML); the host's pytest
phases: RESULTS/host-*.xml, if any.

Every skipped test is listed with its reason. A skip must be expected: a
line of the expected-skips file (tests/expected-skips, unless
--expected-skips or LEGO_EXPECTED_SKIPS names another) whose test id pattern
(fnmatch: *, ?, [...]) matches the test's id and whose reason is part of
the skip's message. Any other skip is counted as a failure. Test ids: kunit.SUITE.CASE, and pytest's
CLASSNAME.NAME (tests.guest.test_vm.test_guest_runs_on_every_cpu_it_was_given).

Usage: tests/summarize.py [--expected-skips FILE] RESULTS KERNEL_TREE
Prints one line per source, each skip, the ten slowest tests and the guest
run's recorded properties (fuzzer seeds and counts); writes
"PASSED FAILED SKIPPED" to RESULTS/totals; exit 1 if anything failed or the
results are missing or unreadable.
"""
import argparse
import fnmatch
import glob
import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
# kunit_parser.py's TEST_RESULT_SKIP: "ok 3 name # SKIP reason"
KTAP_SKIP = re.compile(r'^\s*(ok|not ok) ([0-9]+) ?(:?- )?(.*) # SKIP ?(.*)$')


FAILURES = []


def fail(line, file=None):
    """Print LINE and keep it for RESULTS/failures."""
    FAILURES.append(line)
    print(line, file=file or sys.stdout)


def kunit_cases(node):
    """Yield (name, status) of every leaf test case in kunit.py's JSON."""
    for case in node.get('test_cases', []):
        yield case['name'], case['status']
    for sub in node.get('sub_groups', []):
        yield from kunit_cases(sub)


def ktap_skip_reasons(path):
    """{case name: reason} of the SKIP lines of a KTAP file (kunit.py's
    JSON has the status only)."""
    reasons = {}
    with open(path, errors='replace') as fh:
        for line in fh:
            m = KTAP_SKIP.match(line.rstrip('\n'))
            if m:
                reasons[m.group(4).strip()] = m.group(5).strip()
    return reasons


def count_kunit(results, tree, skips):
    passed = failed = 0
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
            fail(f'kunit: {f}: kunit.py parse gave no JSON', file=sys.stderr)
            print(proc.stdout, proc.stderr, file=sys.stderr)
            failed += 1
            continue
        data = json.loads(text[start:])
        cases = list(kunit_cases(data))
        if not cases:
            fail(f'kunit: {f}: no test case parsed', file=sys.stderr)
            failed += 1
        reasons = ktap_skip_reasons(path)
        for name, status in cases:
            if status == 'PASS':
                passed += 1
            elif status == 'SKIP':
                skips.append((f'kunit.{f[:-5]}.{name}', reasons.get(name, '')))
            else:
                failed += 1
                fail(f'kunit: FAILED {f[:-5]}.{name}: {status}')
    bad = os.path.join(kdir, 'failed-modules')
    if os.path.exists(bad):
        with open(bad) as fh:
            for line in fh:
                fail(f'kunit: FAILED module {line.strip()}')
                failed += 1
    return passed, failed, len(files)


def count_junit(label, path, skips, times, props):
    """Count a pytest JUnit XML file; skips get (id, reason), times
    (seconds, id)."""
    root = ET.parse(path).getroot()
    passed = failed = 0
    for prop in root.iter('property'):
        props.append((prop.get('name'), prop.get('value')))
    for case in root.iter('testcase'):
        children = {child.tag: child for child in case}
        name = f"{case.get('classname')}.{case.get('name')}"
        times.append((float(case.get('time') or 0), name))
        if 'failure' in children or 'error' in children:
            failed += 1
            fail(f'{label}: FAILED {name}')
        elif 'skipped' in children:
            skip = children['skipped']
            skips.append((name, skip.get('message') or skip.text or ''))
        else:
            passed += 1
    return passed, failed


def load_expected(path):
    """[(pattern, reason)] of the expected-skips file; a line without a
    reason is an error (ValueError)."""
    entries = []
    with open(path) as fh:
        for n, line in enumerate(fh, 1):
            line = line.strip()
            if not line or line.startswith('#'):
                continue
            fields = line.split(None, 1)
            if len(fields) < 2:
                raise ValueError(f'{path}:{n}: a test id pattern without its reason')
            entries.append((fields[0], fields[1].strip()))
    return entries


def expected(test_id, reason, entries):
    return any(fnmatch.fnmatchcase(test_id, pat) and want in reason for pat, want in entries)


def main(argv=None):
    ap = argparse.ArgumentParser(description='Count the results of a make check run.')
    ap.add_argument('--expected-skips', default=os.environ.get('LEGO_EXPECTED_SKIPS') or
                    os.path.join(HERE, 'expected-skips'))
    ap.add_argument('results')
    ap.add_argument('tree')
    args = ap.parse_args(argv)
    results = args.results
    skips, times, props = [], [], []
    FAILURES.clear()
    passed, failed, nsuites = count_kunit(results, args.tree, skips)
    nkunit = len(skips)
    print(f'kunit: {nsuites} suites, {passed} passed, {failed} failed, {nkunit} skipped')

    sources = [('guest', os.path.join(results, 'guest.xml'))]
    for path in sorted(glob.glob(os.path.join(results, 'host-*.xml'))):
        sources.append(('host ' + os.path.basename(path)[5:-4], path))
    for label, path in sources:
        if not os.path.exists(path):
            fail(f'{label}: no pytest results ({os.path.basename(path)} missing)', file=sys.stderr)
            failed += 1
            continue
        before = len(skips)
        try:
            p, f = count_junit(label, path, skips, times, props)
        except (OSError, ET.ParseError) as e:
            # Cut short: its pytest was killed, or the disk was full.
            fail(f'{label}: FAILED, {os.path.basename(path)} unreadable: {e}', file=sys.stderr)
            failed += 1
            continue
        print(f'{label}: {p} passed, {f} failed, {len(skips) - before} skipped')
        passed += p
        failed += f

    try:
        entries = load_expected(args.expected_skips)
    except (OSError, ValueError) as e:
        fail(f'expected skips: {e}', file=sys.stderr)
        entries = []
        failed += 1
    skipped = unexpected = 0
    name = os.path.relpath(args.expected_skips)
    for test_id, reason in skips:
        if expected(test_id, reason, entries):
            skipped += 1
            print(f'skipped (expected): {test_id}: {reason}')
        else:
            unexpected += 1
            fail(f'FAILED, skipped and not in {name}: {test_id}: {reason or "(no reason given)"}')
    failed += unexpected

    if times:
        print('Slowest tests:')
        for t, test_id in sorted(times, reverse=True)[:10]:
            print(f'  {t:7.1f} s  {test_id}')
    if props:
        print('Recorded by the tests: ' + ', '.join(f'{k}={v}' for k, v in props))

    with open(os.path.join(results, 'totals'), 'w') as fh:
        fh.write(f'{passed} {failed} {skipped}\n')
    # Printed again after the phase times (tests/lib/phases.sh): CI shows
    # only the end of the log.
    with open(os.path.join(results, 'failures'), 'w') as fh:
        fh.writelines(line + '\n' for line in FAILURES)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
