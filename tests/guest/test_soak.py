"""The short robustness soak (tests/soak/soak.py) as part of `make check`.

Each part runs with small parameters (a few dozen cycles, 45 s of random
streams) and must report no failure. The kmemleak check runs last and counts
only leaks whose backtrace names a lego_ module: the earlier guest tests run
in the same VM and kmemleak's report is cumulative, so anything else there is
not the soak's (run-suite.sh's final scan still reports every leak, and the
console scan fails the run on any). `make soak` runs the full soak.
"""
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'soak'))
import soak  # noqa: E402

PARAMS = dict(soak.SHORT, cycles=24, fuzz_seconds=45, race_seconds=20, unplugs=24,
              transactions=60)


@pytest.fixture(scope='module', autouse=True)
def modules():
    if os.environ.get('LEGO_IN_VM') == '1':
        soak.ensure_modules(pairs=4)


def run_part(number, record_testsuite_property):
    p = soak.run([number], PARAMS, kmemleak=False)[0]
    print('part %d (%s): %d done, %d failed in %.0f s %s'
          % (p.number, p.name, p.count, p.failures, p.seconds, p.info))
    record_testsuite_property('soak_part%d_count' % number, p.count)
    assert p.failures == 0, '\n'.join(p.messages)
    return p


def test_plug_unplug_cycles(ev3_module, record_testsuite_property):
    p = run_part(1, record_testsuite_property)
    assert p.count == PARAMS['cycles']


def test_random_and_mutated_streams(ev3_module, record_testsuite_property):
    p = run_part(2, record_testsuite_property)
    assert p.count > 50, 'too few streams sent: %d' % p.count
    assert p.info.get('good_sensor_after') == 1
    assert p.info.get('good_sensor_values', 0) > 0, 'the good sensor never caught up'


def test_attach_detach_races(ev3_module, record_testsuite_property):
    p = run_part(3, record_testsuite_property)
    assert p.count > 20
    assert p.info.get('mode_switches', 0) > 0
    assert p.info.get('sensor_reads', 0) > 0


def test_brick_unplugs_mid_transfer(record_testsuite_property):
    p = run_part(4, record_testsuite_property)
    assert p.count == PARAMS['unplugs']
    assert p.info.get('errno_ENODEV', 0) >= p.count


def test_eight_clients_one_brick(record_testsuite_property):
    p = run_part(5, record_testsuite_property)
    assert p.count == 8 * PARAMS['transactions']


def test_no_lego_leak():
    if not soak.kmemleak_available():
        pytest.skip('kmemleak is not in this kernel')
    leaks = soak.kmemleak_scan(lego_only=True)
    assert not leaks, '\n\n'.join(leaks)
