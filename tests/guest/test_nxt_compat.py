"""The NXT ioctls from a 32-bit program: lego_nxt_usb's compat_ioctl.

The driver hands 32-bit callers to its own ioctl handler through
compat_ptr_ioctl, which is right only while every structure of
include/uapi/linux/lego_nxt.h has the same layout on i386 as on x86_64
(and so every ioctl number, whose size field is the structure's size).
tests/guest/nxt_compat_client.c, built static with gcc -m32 by
tests/build-modules.sh, prints its layout of the header, which is compared
here with nxtdev's x86_64 description (itself checked against the header
by test_nxt_usb.py); then it issues every ioctl of the header on the
emulated brick's /dev/nxtN and checks each reply, and this test checks
what the brick saw.

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
ALL_IOCTLS = sorted(list(nxt.IOCTLS) + ['TRANSACT', 'SET_TIMEOUT', 'GET_TIMEOUT'])

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


def member_offsets(sname):
    """Offsets of the named members of nxtdev's description of a structure
    (its formats are packed, with the padding written out)."""
    fmt, names = nxt.STRUCTS[sname]
    names = names.split()
    offsets, pos = {}, 0
    for count, code in re.findall(r'(\d*)([a-zA-Z])', fmt[1:]):
        n = int(count or 1)
        if code == 'x':
            pos += n
        elif code == 's':
            offsets[names[len(offsets)]] = pos
            pos += n
        else:
            for _ in range(n):
                offsets[names[len(offsets)]] = pos
                pos += struct.calcsize('<' + code)
    assert len(offsets) == len(names) and pos == nxt.struct_size(sname), sname
    return offsets


def test_layout_is_the_same_for_i386():
    out = subprocess.run([client(), '--layout'], capture_output=True, text=True,
                         check=True, timeout=60).stdout
    c = dict(line.split() for line in out.splitlines())
    c = {k: int(v) for k, v in c.items()}
    assert c.pop('long') == 4, 'the client is not a 32-bit program'
    wrong = []
    for sname in nxt.STRUCTS:
        if c.pop(sname) != nxt.struct_size(sname):
            wrong.append('sizeof(struct nxt_%s)' % sname)
        offsets = member_offsets(sname)
        printed = {k.split('.', 1)[1] for k in c if k.startswith(sname + '.')}
        assert printed == set(offsets), 'struct nxt_%s: the client prints %s, nxtdev has %s' % (
            sname, sorted(printed), sorted(offsets))
        for member, off in offsets.items():
            if c.pop('%s.%s' % (sname, member)) != off:
                wrong.append('offsetof(struct nxt_%s, %s)' % (sname, member))
    for name in ALL_IOCTLS:
        if c.pop(name) != nxt.ioctl_number(name):
            wrong.append('NXT_IOC_' + name)
    assert not c, 'the client prints what nxtdev does not describe: %s' % sorted(c)
    assert not wrong, 'i386 and x86_64 differ: ' + ', '.join(wrong)


def reset_brick(fw):
    """The state nxt_compat_client.c expects: no program, motors at rest
    with zero counters, and the values it is told."""
    with fw.lock:
        fw.program = fw.program_next = None
        fw.motors = [nxt_brick.Motor() for _ in range(3)]
        fw.motor_time = fw.now()
        fw.battery_mv = BATTERY_MV
        fw.sleep_minutes = SLEEP_MINUTES
        fw.ultrasonic.distance = DISTANCE_CM
        fw.analog_port(1, SOUND_RAW)
        fw.sound = None
        for q in fw.mailboxes:
            q.clear()


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
    assert ok == ALL_IOCTLS, 'ioctls not called or not passed: %s' % sorted(
        set(ALL_IOCTLS) - set(ok))

    # Every call that reached the brick, and only those, were telegrams.
    sent = int(re.search(r'^telegrams (\d+)$', out, re.M).group(1))
    assert brick.emu.commands - before == sent, \
        'the brick got %d commands, the client counted %d' % (brick.emu.commands - before, sent)

    # What the client left on the brick.
    with fw.lock:
        assert fw.sound is not None and fw.sound[:2] == ('tone', TONE_HZ), fw.sound
        left = fw.sound[2] - fw.now()
        assert TONE_MS / 1000 - took - 1 <= left <= TONE_MS / 1000, \
            'the tone ends in %.1f s, not about %d s' % (left, TONE_MS // 1000)
        assert fw.program is None and fw.program_next is None
        assert not fw.mailboxes[3], 'the message the client wrote to inbox 3 is still there'
        m = fw.motors[1]
        assert (m.power, m.runstate, m.limit) == (0, 0, 0)
        assert (round(m.tacho), round(m.block), round(m.rotation)) == (0, 0, 0)
        assert (fw.inputs[1].type, fw.inputs[1].mode) == (nxt_brick.SOUND_DB, nxt_brick.RAWMODE)
        assert fw.inputs[3].type == nxt_brick.LOWSPEED_9V
