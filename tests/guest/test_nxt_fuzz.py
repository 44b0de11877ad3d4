"""The whole-driver NXT fuzzer (tests/soak/nxt_fuzz.py) in `make check`.

A few hundred random sequences of open/write/read/poll/ioctl/close from
three processes against honest and hostile emulated bricks, with USB
resets and unplugs (about two minutes in the TCG guest). The run seed is
random and printed (LEGO_NXT_FUZZ_SEED sets it), and every failure prints it
with the command that replays the failed epoch. `make soak` runs thousands
(part 8 of tests/soak/soak.py).

The other tests show that the fuzzer's checks can fail: a brick whose
replies the fuzzer did not see sent, a wrong errno expectation, a call
that hangs, a brick that answers with its previous reply to the same
opcode (which the driver cannot tell), a reply of the wrong length or
opcode, an ioctl number that the driver answers where it must fail with
ENOTTY; and that the unknown numbers the fuzzer tries include every typed
ioctl of earlier releases, each with a buffer as large as its number says.
"""
import errno
import os
import random
import subprocess
import sys
import time

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'soak'))
import nxt_fuzz  # noqa: E402

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SEQUENCES = int(os.environ.get('LEGO_NXT_FUZZ_SEQUENCES', '300'))


def run_seed():
    s = os.environ.get('LEGO_NXT_FUZZ_SEED')
    return int(s, 0) if s else random.SystemRandom().randrange(1 << 32)


def test_fuzz_sequences(record_testsuite_property):
    seed = run_seed()
    print('\nnxt_fuzz: %d sequences from seed %#x (LEGO_NXT_FUZZ_SEED=%#x to run them again)'
          % (SEQUENCES, seed, seed))
    record_testsuite_property('nxt_fuzz_seed', '%#x' % seed)
    fz = nxt_fuzz.run(SEQUENCES, seed, workers=3, per_epoch=30)
    s = fz.summary()
    print(s)
    record_testsuite_property('nxt_fuzz_sequences', fz.sequences)
    record_testsuite_property('nxt_fuzz_calls', fz.calls)
    assert not fz.failures, 'seed %#x (replay: %s):\n%s' % (
        seed, fz.replay_command(fz.failed_epochs[0]), '\n'.join(fz.failures))
    assert fz.sequences >= SEQUENCES
    # The run did what it is for: hostile replies, unplugs, checked replies.
    assert sum(n for a, n in s['brick_actions'].items() if a != 'ok') > 20
    assert s['info'].get('replies_checked', 0) > 50
    # The epochs whose plan says so had the firmware's 1 ms tick
    # (nxt_fuzz.TICK_SHARE of them).
    epochs = sum(n for k, n in s['info'].items() if k.startswith('profile_'))
    ticked = sum(1 for k in range(epochs)
                 if nxt_fuzz.epoch_plan(nxt_fuzz.derive(seed, 'epoch', k), 1)['tick'])
    assert s['info'].get('tick_epochs', 0) == ticked, s['info']
    assert fz.calls > 5 * SEQUENCES


def one_epoch(seed, tamper=None, sequences=12, **kw):
    fz = nxt_fuzz.Fuzzer(seed, workers=2, per_epoch=sequences, log=lambda m: None, **kw)
    fz.tamper = tamper
    try:
        fz.run_epoch(seed, sequences)
    finally:
        fz.close()
    return fz


def honest_plan(seed, sequences):
    """Whether the epoch's plan is an honest brick with no mid-epoch unplug."""
    p = nxt_fuzz.epoch_plan(seed, sequences)
    return p['profile'] == 'honest' and p['unplug_after'] is None and not p['resets']


def honest_seed(sequences=12):
    """An epoch seed whose plan is an honest brick with no mid-epoch unplug."""
    for s in range(1000):
        if honest_plan(s, sequences):
            return s
    raise AssertionError('no such seed')


def test_the_unknown_numbers_tried():
    """gen_retired(): numbers of the magic that the driver does not know,
    every retired typed one among them, never with a buffer smaller than
    the number's size field."""
    known = {nxt_fuzz.nxt.ioctl_number(n) for n in ('TRANSACT', 'SET_TIMEOUT', 'GET_TIMEOUT')}
    # Two of the typed numbers as the old header made them.
    assert nxt_fuzz.nxt.iowr(0x10 + 0x00, nxt_fuzz.RETIRED_TYPED[0x00]) == 0xc018e410
    assert nxt_fuzz.nxt.iowr(0x10 + 0x13, nxt_fuzz.RETIRED_TYPED[0x13]) == 0xc040e423
    seen = set()
    for seed in range(3000):
        num, arg = nxt_fuzz.gen_retired(random.Random(seed))
        assert num not in known and (num >> 8) & 0xff == nxt_fuzz.nxt.MAGIC, hex(num)
        assert num & 0xff in nxt_fuzz.RETIRED_NR or num & 0xff < 3, hex(num)
        assert len(arg) >= nxt_fuzz.ioc_size(num), (hex(num), len(arg))
        seen.add(num)
    typed = {nxt_fuzz.nxt.iowr(0x10 + op, size) for op, size in nxt_fuzz.RETIRED_TYPED.items()}
    assert typed <= seen, sorted(hex(n) for n in typed - seen)
    assert len(seen - typed) > 500


def test_a_known_number_among_the_unknown_is_caught(monkeypatch):
    # Stand in for a driver that still answered a retired number: the
    # action for unknown numbers is handed GET_TIMEOUT's, which the driver
    # answers (0, and the timeout written to the buffer).
    num = nxt_fuzz.nxt.ioctl_number('GET_TIMEOUT')
    monkeypatch.setattr(nxt_fuzz, 'gen_retired', lambda rng: (num, bytes(4)))
    seed = next(s for s in range(1000) if honest_plan(s, 12) and any(
        op[0] == 'retired' and op[1] == 0
        for i in range(12) for op in nxt_fuzz.gen_sequence(nxt_fuzz.derive(s, 'seq', i))))
    fz = one_epoch(seed)
    assert any('must be ENOTTY' in m for m in fz.failures), fz.failures
    assert any('changed its buffer' in m for m in fz.failures), fz.failures


def test_a_reply_the_brick_did_not_send_is_caught():
    # The brick forgets what it sent: every reply a client got is "unknown".
    def forget(brick):
        brick._record = lambda data: None
    fz = one_epoch(honest_seed(), tamper=forget)
    assert any('never sent' in m for m in fz.failures), fz.failures


def test_a_stale_reply_is_caught():
    # A brick that answers each command with its previous reply to the same
    # opcode: right type, opcode and length, sent by the brick, so the
    # driver cannot tell; only the exact pairing of an honest epoch can.
    def stale(brick):
        last = {}
        act = brick.act

        def stale_act(action, packet, reply):
            if action == 'ok' and reply is not None:
                key = (packet[0], packet[1])
                reply, last[key] = last.get(key, reply), reply
            act(action, packet, reply)
        brick.act = stale_act
    fz = one_epoch(honest_seed(40), tamper=stale, sequences=40)
    assert any('did not send in answer' in m for m in fz.failures), fz.failures


def test_a_wrong_errno_expectation_is_caught(monkeypatch):
    # Pretend the documentation said ENODATA is not what read() gives with
    # nothing asked: the (correct) driver now fails the check.
    orig = nxt_fuzz.Sequence.allowed

    def strict(self, i, op, what, err, extra, nonblock=False):
        return orig(self, i, op, what, err, tuple(e for e in extra if e != errno.ENODATA),
                    nonblock)
    monkeypatch.setattr(nxt_fuzz.Sequence, 'allowed', strict)
    fz = one_epoch(honest_seed(20), sequences=20)
    assert any('ENODATA' in m for m in fz.failures), fz.failures


def test_a_hang_is_caught(monkeypatch):
    # A "system call" that never returns: the worker is reported (with its
    # kernel stacks) and killed, and the epoch goes on.
    monkeypatch.setattr(nxt_fuzz.Sequence, 'op_sleep',
                        lambda self, i, op: time.sleep(3600))
    k = next(k for k in range(1000) if any(
        op[0] == 'sleep' for op in nxt_fuzz.gen_sequence(nxt_fuzz.derive(k, 'seq', 0))))
    fz = nxt_fuzz.Fuzzer(k, workers=1, per_epoch=1, hang_s=3, log=lambda m: None)
    try:
        fz.run_epoch(k, 1)
    finally:
        fz.close()
    assert any('hung' in m and 'kernel stacks' in m for m in fz.failures), fz.failures


@pytest.mark.parametrize('lie', ['length', 'opcode'])
def test_a_lying_driver_is_caught(lie):
    # Stand in for a driver bug: the check of what the client got must catch
    # a reply of the wrong length or opcode (the driver itself refuses them,
    # so the fuzzer's reply check is exercised directly here).
    tg = b'\x00\x0b'
    good = b'\x02\x0b\x00\x8f\x1e'
    bad = good + b'\0' if lie == 'length' else b'\x02\x0c\x00\x8f\x1e'
    assert nxt_fuzz.check_reply(tg, good) is None
    assert nxt_fuzz.check_reply(tg, bad)


@pytest.mark.parametrize('mode,count', [('short', 60), ('stall', 30)])
def test_write_does_not_report_the_replys_error(mode, count):
    """Found by the fuzzer: write() failed with the reply's EPROTO (a short
    reply) or EPIPE (an IN stall) when the reply was judged before the
    writer woke, although the brick had taken the telegram. write()
    succeeds now, and the error is read()'s (tests/soak/nxt_write_reply_error.py,
    which exits 1 for any such write)."""
    r = subprocess.run([sys.executable, os.path.join(TOP, 'tests/soak/nxt_write_reply_error.py'),
                        mode, str(count)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert 'write() ' in r.stdout
