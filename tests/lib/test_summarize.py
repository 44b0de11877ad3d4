"""tests/summarize.py and tests/lib/phases.sh (host side, no VM): the
closing line counts passed, failed and skipped tests, lists every skip with
its reason, and a skip that the expected-skips file does not list (with its
reason) fails the run, as it would if LEGO_IN_VM were lost and every guest
test skipped.

  python3 -m pytest -v tests/lib/test_summarize.py
"""
import os
import subprocess
import sys
from xml.sax.saxutils import quoteattr

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SUMMARIZE = os.path.join(TOP, 'tests/summarize.py')
NOT_IN_VM = 'guest tests run inside the test VM (tests/vm-run)'


def junit(path, cases, props=()):
    """Write a pytest-style JUnit XML file: cases are (classname, name,
    time, outcome, message), outcome one of pass, fail, skip."""
    body = []
    for classname, name, time, outcome, message in cases:
        inner = {'pass': '',
                 'fail': '<failure message=%s>trace</failure>' % quoteattr(message),
                 'skip': '<skipped type="pytest.skip" message=%s>x</skipped>' % quoteattr(message),
                 }[outcome]
        body.append('<testcase classname=%s name=%s time="%.3f">%s</testcase>'
                    % (quoteattr(classname), quoteattr(name), time, inner))
    prop = ''.join('<property name=%s value=%s />' % (quoteattr(k), quoteattr(v)) for k, v in props)
    path.write_text('<?xml version="1.0" encoding="utf-8"?><testsuites><testsuite name="pytest">'
                    '<properties>%s</properties>%s</testsuite></testsuites>' % (prop, ''.join(body)))


def guest_results(tmp_path, skip_message=NOT_IN_VM):
    res = tmp_path / 'results'
    res.mkdir()
    junit(res / 'guest.xml', [
        ('tests.guest.test_a', 'test_one', 1.5, 'pass', ''),
        ('tests.guest.test_a', 'test_two[x]', 12.25, 'pass', ''),
        ('tests.guest.test_b', 'test_three', 0.5, 'skip', skip_message),
    ], props=[('nxt_fuzz_seed', '0x1234')])
    return res


def expected_file(tmp_path, *lines):
    f = tmp_path / 'expected-skips'
    f.write_text('# a comment\n\n' + ''.join(line + '\n' for line in lines))
    return f


def summarize(res, expected, tree='/nonexistent'):
    r = subprocess.run([sys.executable, SUMMARIZE, '--expected-skips', str(expected), str(res), tree],
                       capture_output=True, text=True, cwd=TOP)
    with open(res / 'totals') as f:
        totals = tuple(int(n) for n in f.read().split())
    return r.returncode, r.stdout + r.stderr, totals


def test_an_unexpected_skip_fails(tmp_path):
    res = guest_results(tmp_path)
    rc, out, totals = summarize(res, expected_file(tmp_path))
    assert rc == 1, out
    assert totals == (2, 1, 0), out
    assert 'FAILED, skipped and not in' in out
    assert 'tests.guest.test_b.test_three: ' + NOT_IN_VM in out


def test_only_expected_skips_pass(tmp_path):
    res = guest_results(tmp_path)
    rc, out, totals = summarize(res, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'))
    assert rc == 0, out
    assert totals == (2, 0, 1), out
    assert 'skipped (expected): tests.guest.test_b.test_three: ' + NOT_IN_VM in out


def test_an_expected_test_skipped_for_another_reason_fails(tmp_path):
    res = guest_results(tmp_path, skip_message='udevadm not installed')
    rc, out, totals = summarize(res, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'))
    assert rc == 1 and totals == (2, 1, 0), out
    assert 'udevadm not installed' in out


def test_an_entry_needs_a_reason(tmp_path):
    res = guest_results(tmp_path)
    rc, out, totals = summarize(res, expected_file(tmp_path, 'tests.guest.test_b.*'))
    assert rc == 1, out
    assert 'without its reason' in out


def test_host_phases_are_counted_and_their_skips_checked(tmp_path):
    res = guest_results(tmp_path)
    junit(res / 'host-packaging.xml', [
        ('tests.packaging.test_udev_rules', 'test_udevadm_verify', 0.2, 'skip', 'udevadm 252 has no verify'),
        ('tests.packaging.test_install', 'test_make_install', 30.0, 'pass', ''),
        ('tests.packaging.test_install', 'test_dkms', 3.0, 'fail', 'boom'),
    ])
    exp = expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM')
    rc, out, totals = summarize(res, exp)
    assert rc == 1 and totals == (3, 2, 1), out
    assert 'host packaging: 1 passed, 1 failed, 1 skipped' in out
    assert 'host packaging: FAILED tests.packaging.test_install.test_dkms' in out
    assert 'not in' in out and 'test_udevadm_verify: udevadm 252 has no verify' in out


def test_slowest_tests_and_properties_are_printed(tmp_path):
    res = guest_results(tmp_path)
    junit(res / 'host-emulator.xml', [('tests.emulator.test_e', 'test_slow', 40.0, 'pass', '')])
    rc, out, _ = summarize(res, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'))
    assert rc == 0, out
    slow = out.split('Slowest tests:\n', 1)[1].splitlines()
    assert slow[0].split() == ['40.0', 's', 'tests.emulator.test_e.test_slow']
    assert slow[1].split() == ['12.2', 's', 'tests.guest.test_a.test_two[x]']
    assert 'nxt_fuzz_seed=0x1234' in out


def test_missing_guest_results_fail(tmp_path):
    res = tmp_path / 'results'
    res.mkdir()
    rc, out, totals = summarize(res, expected_file(tmp_path))
    assert rc == 1 and totals == (0, 1, 0), out
    assert 'guest.xml missing' in out


def kernel_tree():
    tree = os.environ.get('LEGO_KERNEL_TREE')
    if not tree:
        r = subprocess.run([os.path.join(TOP, 'tests/kernel/build-kernel.sh'), '--tree-only', 'newest'],
                           capture_output=True, text=True)
        tree = r.stdout.strip()
    assert tree and os.path.exists(os.path.join(tree, 'tools/testing/kunit/kunit.py')), \
        'no kernel tree with kunit.py: build the test kernel or set LEGO_KERNEL_TREE'
    return tree


KTAP = '''KTAP version 1
1..1
    KTAP version 1
    # Subtest: lego_demo
    1..3
    ok 1 demo_passes
    ok 2 demo_skips # SKIP needs a brick
    not ok 3 demo_fails
# lego_demo: pass:1 fail:1 skip:1 total:3
# Totals: pass:1 fail:1 skip:1 total:3
not ok 1 lego_demo
'''


def test_kunit_skips_are_listed_with_their_reason(tmp_path):
    res = guest_results(tmp_path)
    (res / 'kunit').mkdir()
    (res / 'kunit/lego_demo.ktap').write_text(KTAP)
    tree = kernel_tree()
    exp = expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM')
    rc, out, totals = summarize(res, exp, tree)
    assert rc == 1 and totals == (3, 2, 1), out
    assert 'kunit: 1 suites, 1 passed, 1 failed, 1 skipped' in out
    assert 'kunit: FAILED lego_demo.demo_fails' in out
    assert 'not in' in out and 'kunit.lego_demo.demo_skips: needs a brick' in out
    exp = expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM',
                        'kunit.lego_demo.demo_skips needs a brick')
    rc, out, totals = summarize(res, exp, tree)
    assert totals == (3, 1, 2), out


def closing(res, expected, vm_rc=0):
    """phases.sh's vm_totals as check.sh calls it: its last line and exit."""
    script = '. tests/lib/phases.sh; phase "a phase" true; vm_totals "$1" /nonexistent "$2"'
    env = dict(os.environ, LEGO_EXPECTED_SKIPS=str(expected))
    env.pop('PHASE_NOCOUNT', None)
    r = subprocess.run(['bash', '-c', script, 'x', str(res), str(vm_rc)], capture_output=True,
                       text=True, cwd=TOP, env=env)
    return r.returncode, r.stdout.splitlines()[-1], r.stdout + r.stderr


@pytest.mark.parametrize('vm_rc', [0, 1])
def test_closing_line_fails_on_an_unexpected_skip(tmp_path, vm_rc):
    res = guest_results(tmp_path)
    rc, last, out = closing(res, expected_file(tmp_path), vm_rc)
    assert (rc, last) == (1, '2 passed, 1 failed, 0 skipped'), out


def test_closing_line_passes_with_expected_skips(tmp_path):
    res = guest_results(tmp_path)
    rc, last, out = closing(res, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'))
    assert (rc, last) == (0, '2 passed, 0 failed, 1 skipped'), out
    rc, last, out = closing(res, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'), 1)
    assert (rc, last) == (1, '2 passed, 1 failed, 1 skipped'), out


def test_failures_are_listed_again_before_the_closing_line(tmp_path):
    """CI keeps the log's tail: the failed tests and phases are named there,
    after the phase times, not only where they happened."""
    res = tmp_path / 'results'
    res.mkdir()
    junit(res / 'guest.xml', [
        ('tests.guest.test_a', 'test_one', 1.0, 'pass', ''),
        ('tests.guest.test_c', 'test_breaks', 2.0, 'fail', 'boom'),
    ])
    script = ('. tests/lib/phases.sh; phase "a phase" true; phase "a broken phase" false; '
              'vm_totals "$1" /nonexistent 1')
    # make check runs this under its own phase, whose PHASE_NOCOUNT (a
    # pytest phase counts its failures from its results) would else hide
    # the broken phase here.
    env = dict(os.environ, LEGO_EXPECTED_SKIPS=str(expected_file(tmp_path)))
    env.pop('PHASE_NOCOUNT', None)
    r = subprocess.run(['bash', '-c', script, 'x', str(res)], capture_output=True, text=True,
                       cwd=TOP, env=env)
    lines = r.stdout.splitlines()
    assert r.returncode == 1 and lines[-1] == '1 passed, 2 failed, 0 skipped', r.stdout
    tail = lines[lines.index('Failed:'):-1]
    assert tail == ['Failed:', '  phase: a broken phase (exit 1)',
                    '  guest: FAILED tests.guest.test_c.test_breaks'], r.stdout
    assert lines.index('Failed:') > max(i for i, line in enumerate(lines) if 'total' in line)
    (tmp_path / 'ok').mkdir()
    res2 = guest_results(tmp_path / 'ok')
    rc, last, out = closing(res2, expected_file(tmp_path, 'tests.guest.test_b.* inside the test VM'))
    assert rc == 0 and 'Failed:' not in out, out


def test_the_expected_skips_file_reads():
    """tests/expected-skips itself: every entry has its reason."""
    sys.path.insert(0, os.path.join(TOP, 'tests'))
    try:
        import summarize as s
    finally:
        sys.path.pop(0)
    for pattern, reason in s.load_expected(os.path.join(TOP, 'tests/expected-skips')):
        assert reason, pattern
