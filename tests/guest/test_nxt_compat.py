"""The NXT ioctls from a 32-bit program: lego_nxt_usb's compat_ioctl.

The driver hands 32-bit callers to its own ioctl handler through
compat_ptr_ioctl, which is right only while struct nxt_transaction of
include/uapi/linux/lego_nxt.h has the same layout on i386 as on x86_64
(and so NXT_IOC_TRANSACT the same number, whose size field is the
structure's size). tests/guest/nxt_compat_client.c, built static with
gcc -m32 by tests/build-modules.sh, prints its layout of the header, which
is compared here with nxtdev's x86_64 description; then it sends telegrams
of every reply size through NXT_IOC_TRANSACT on the emulated brick's
/dev/nxtN and checks each reply byte for byte (the brick's status byte is
data: a refusal is a successful call), checks the telegrams the driver
refuses, the timeouts, and ENOTTY for the typed ioctl numbers of earlier
releases and other unknown numbers; this test checks what the brick saw.

x86 only: the client is not built when cross-compiling (make check-arm64
skips this module, tests/expected-skips).
"""
import os
import re
import struct
import subprocess
import time

import pytest

import nxtdev as nxt
import nxt_brick

SERIAL = '0016530C0320'
# What the brick is set to answer; the client is told, and checks.
BATTERY_MV = 7321
SLEEP_MINUTES = 25
DISTANCE_CM = 37
SOUND_RAW = 321
TONE_HZ, TONE_MS = 1234, 30000      # the client's last PlayTone
IOCTLS = ['TRANSACT', 'SET_TIMEOUT', 'GET_TIMEOUT']
# What the client reports as passed: the three ioctls, the retired typed
# numbers and other unknown numbers of the magic.
CHECKED = sorted(IOCTLS + ['RETIRED', 'UNKNOWN'])

pytestmark = pytest.mark.skipif(os.uname().machine != 'x86_64',
                                reason='the 32-bit NXT client is built for x86_64 guests only')


def client():
    """The 32-bit client that tests/build-modules.sh built (missing: fail)."""
    path = os.path.join(os.environ.get('LEGO_BUILD', ''), 'nxt-compat-client')
    assert os.access(path, os.X_OK), \
        '%s is missing: tests/build-modules.sh builds it with gcc -m32 ' \
        '(gcc-12-multilib and libc6-dev-i386, tests/install-deps.sh)' % path
    with open(path, 'rb') as f:
        ident = f.read(20)
    # ELFCLASS32, little endian, e_machine EM_386.
    assert ident[:6] == b'\x7fELF\x01\x01' and struct.unpack_from('<H', ident, 18)[0] == 3, \
        '%s is not an i386 ELF program' % path
    return path


def transaction_layout():
    """Size and member offsets of struct nxt_transaction as nxtdev packs it
    on x86_64: each member filled with a byte of its own, then found."""
    fields = dict(telegram=b'\x11' * 64, reply=b'\x22' * 64, length=0x33333333,
                  reply_length=0x44444444)
    data = nxt.pack('transaction', **fields)
    assert nxt.unpack('transaction', data) == fields
    layout = {'transaction': len(data)}
    for name, mark in (('telegram', 0x11), ('reply', 0x22), ('length', 0x33),
                       ('reply_length', 0x44)):
        at = data.index(mark)
        size = 64 if name in ('telegram', 'reply') else 4
        assert data[at:at + size] == bytes([mark]) * size, name
        layout['transaction.' + name] = at
    return layout


def test_layout_is_the_same_for_i386():
    out = subprocess.run([client(), '--layout'], capture_output=True, text=True,
                         check=True, timeout=60).stdout
    c = dict(line.split() for line in out.splitlines())
    c = {k: int(v) for k, v in c.items()}
    assert c.pop('long') == 4, 'the client is not a 32-bit program'
    want = transaction_layout()
    want.update(NXT_TELEGRAM_MIN=2, NXT_TELEGRAM_MAX=64, NXT_IOC_MAGIC=nxt.MAGIC)
    for name in IOCTLS:
        want[name] = nxt.ioctl_number(name)
    assert set(c) == set(want), 'the client prints %s, nxtdev describes %s' % (
        sorted(c), sorted(want))
    wrong = ['%s: %d on i386, %d on x86_64' % (k, c[k], want[k]) for k in sorted(c)
             if c[k] != want[k]]
    assert not wrong, 'i386 and x86_64 differ: ' + ', '.join(wrong)


def reset_brick(fw):
    """The state nxt_compat_client.c expects: no program, the default
    sensors with their types unset, the IOMaps as they start, and the
    values it is told."""
    with fw.lock:
        fw.program = fw.program_next = None
        fw.battery_mv = BATTERY_MV
        fw.sleep_minutes = SLEEP_MINUTES
        fw.ultrasonic.distance = DISTANCE_CM
        fw.inputs = [nxt_brick.InputPort(fw.DEFAULT_SENSORS.get(i)) for i in range(4)]
        fw.analog_port(1, SOUND_RAW)
        fw.iomaps = {mid: bytearray(nxt_brick.iomap_pattern(mid, o) for o in range(size))
                     for _, mid, _, size in nxt_brick.MODULES}
        fw.sound = None


def test_every_ioctl_from_a_32_bit_client(brick):
    exe = client()
    fw = brick.fw
    reset_brick(fw)
    before = brick.emu.commands
    t0 = time.monotonic()
    r = subprocess.run([exe, brick.node, str(BATTERY_MV), str(SLEEP_MINUTES * 60000),
                        str(DISTANCE_CM), str(SOUND_RAW)],
                       capture_output=True, text=True, timeout=300)
    took = time.monotonic() - t0
    out = r.stdout
    failed = [line for line in out.splitlines() if line.startswith('FAIL')]
    assert r.returncode == 0 and not failed, 'nxt-compat-client exit %d:\n%s%s' % (
        r.returncode, out, r.stderr)
    ok = sorted(line.split()[1] for line in out.splitlines() if line.startswith('ok '))
    assert ok == CHECKED, 'not called or not passed: %s' % sorted(set(CHECKED) - set(ok))

    # Every call that reached the brick, and only those, were telegrams:
    # none of the refused telegrams and unknown numbers.
    sent = int(re.search(r'^telegrams (\d+)$', out, re.M).group(1))
    assert sent >= 17, out
    assert brick.emu.commands - before == sent, \
        'the brick got %d commands, the client counted %d' % (brick.emu.commands - before, sent)

    # What the client left on the brick.
    with fw.lock:
        assert fw.sound is not None and fw.sound[:2] == ('tone', TONE_HZ), fw.sound
        left = fw.sound[2] - fw.now()
        assert TONE_MS / 1000 - took - 1 <= left <= TONE_MS / 1000, \
            'the tone ends in %.1f s, not about %d s' % (left, TONE_MS // 1000)
        assert fw.program is None and fw.program_next is None
        # The no-reply SetInputMode, then the one with a reply.
        assert (fw.inputs[1].type, fw.inputs[1].mode) == (nxt_brick.SOUND_DB, nxt_brick.RAWMODE)
        assert fw.inputs[3].type == nxt_brick.LOWSPEED_9V
