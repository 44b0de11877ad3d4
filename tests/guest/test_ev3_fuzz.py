"""Whole-driver fuzzing of the EV3 discipline, bounded for `make check`.

A few hundred generated and mutated handshakes (tests/emulator/ev3_gen.py),
each played by an emulated sensor on a pty (and some on a null-modem line)
through attach, registration, every sysfs and IIO attribute, a buffered
capture, mode switches, a WRITE and a detach (tests/guest/ev3_fuzz.py).
The first seed is random and printed (LEGO_EV3FUZZ_SEED sets it,
LEGO_EV3FUZZ_CASES the number of cases, LEGO_EV3FUZZ_KNOWN=include|only
lets the generator hit the known driver bugs); every failure prints its
seed and the command that replays it.
"""
import os
import random
import sys

sys.path.insert(0, os.path.dirname(__file__))
import ev3_fuzz  # noqa: E402

CASES = int(os.environ.get('LEGO_EV3FUZZ_CASES', '200'))
KNOWN = os.environ.get('LEGO_EV3FUZZ_KNOWN', ev3_fuzz.DEFAULT_KNOWN)


def first_seed():
    s = os.environ.get('LEGO_EV3FUZZ_SEED')
    return int(s) if s else random.SystemRandom().randrange(1 << 40)


def test_generated_handshakes(ev3_module, record_testsuite_property):
    seed = first_seed()
    print('\nev3fuzz: %d cases from seed %d (LEGO_EV3FUZZ_SEED=%d to run them again), '
          'known bugs: %s' % (CASES, seed, seed, KNOWN))
    ev3_fuzz.ensure_modules()
    plan = ev3_fuzz.plan_for(CASES, seed, pty_workers=2, nullmodem_lines=[0],
                             nullmodem_share=0.03)
    res = ev3_fuzz.run_many(plan, KNOWN)
    info = res['info']
    print('ev3fuzz: %d cases, %d failed: %s' % (res['count'], len(res['failures']),
                                               ' '.join('%s=%d' % kv for kv in sorted(info.items()))))
    record_testsuite_property('ev3fuzz_cases', res['count'])
    record_testsuite_property('ev3fuzz_seed', seed)
    assert not res['failures'], '\n\n'.join(res['failures'][:10])
    assert res['count'] == CASES
    # The run must reach every stage, or it proves nothing.
    assert info.get('registered', 0) > CASES // 3
    assert info.get('refused', 0) > 0
    assert info.get('captured_scans', 0) > 0
    assert info.get('mode_switches', 0) > 0
    assert info.get('writes', 0) > CASES // 3
    lost = sum(v for k, v in info.items() if k.startswith('sensor_lost'))
    assert lost <= info.get('registered', 0) // 10, '%d sensors lost mid-case' % lost
