"""The emulated sensor keeps the real sensors' 80 ms wait for the host's ACK,
and its `rude` option does what real sensors do to a host (issue 29): DATA of
the old mode until a SELECT is carried out, a glitch byte at the baud switch,
unflagged random garbage.

The first tests have no driver: the test plays the host on one end of a pty
and the emulator the sensor on the other, so the test alone decides when the
ACK comes and sees every byte. The last ones put rude sensors through the
driver on the null-modem line.
"""
import copy
import os
import select
import time

import pytest

import ev3
from ev3 import plug, read_attr, wait_value, write_attr

es = ev3.ev3_sensor


def read_handshake(fd, sdef, timeout=10.0):
    """Read one whole handshake (the emulator writes it in one go)."""
    want = len(es.handshake(sdef))
    data = b''
    deadline = time.monotonic() + timeout
    while len(data) < want and time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.1)
        if r:
            data += os.read(fd, 4096)
    return data


def wait_event(emu, prefix, count, timeout=5.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        got = [e for _, e in emu.events if e.startswith(prefix)]
        if len(got) >= count:
            return got
        time.sleep(0.01)
    return [e for _, e in emu.events if e.startswith(prefix)]


def test_late_ack_is_refused_and_a_timely_one_taken():
    master, slave = os.openpty()
    # A pty carries bytes at once: a long reset keeps the sensor's cycles
    # (handshake, 80 ms, reset, handshake...) apart.
    emu = es.EmulatedSensor(master, 'gyro', boot_delay=1.0)
    emu.start()
    try:
        sdef = emu.sdef
        assert read_handshake(slave, sdef) == es.handshake(sdef)
        # 300 ms after the handshake the sensor has given up and resets:
        # it flushes this ACK when it starts over.
        time.sleep(0.3)
        late = time.monotonic()
        os.write(slave, bytes([es.SYS_ACK]))
        refused = [t for t, e in emu.events if e.startswith('no ack')]
        assert refused and refused[0] < late, emu.events
        # The handshake again; this time the ACK comes at once.
        assert read_handshake(slave, sdef) == es.handshake(sdef), emu.events
        os.write(slave, bytes([es.SYS_ACK]))
        assert wait_event(emu, 'acked', 1), emu.events
        assert emu.handshakes == 1
        # In its data phase the sensor answers a NACK with DATA.
        os.write(slave, bytes([es.SYS_NACK]))
        r, _, _ = select.select([slave], [], [], 2.0)
        assert r, emu.events
        assert os.read(slave, 64)[0] & 0xc0 == 0xc0        # a DATA message
    finally:
        emu.stop()
        os.close(slave)
        os.close(master)


def host_side(kind, boot_delay=0.3, **kw):
    """An emulator on a pty whose other end the test plays: (emulator,
    host fd, master fd)."""
    master, slave = os.openpty()
    emu = es.EmulatedSensor(master, kind, boot_delay=boot_delay, **kw)
    emu.start()
    return emu, slave, master


def connect_by_hand(emu, fd):
    """Read the handshake, answer ACK; the bytes read before it."""
    hs = es.handshake(emu.sdef)
    data = b''
    deadline = time.monotonic() + 10
    while hs not in data and time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.1)
        if r:
            data += os.read(fd, 4096)
    assert hs in data, (data.hex(), emu.events)
    os.write(fd, bytes([es.SYS_ACK]))
    assert wait_event(emu, 'acked', 1), emu.events
    return data[:data.index(hs)]


def read_for(fd, seconds, nack_every=None):
    """Everything the sensor sends for `seconds`, with a NACK every
    `nack_every` seconds (as the host's keep-alive)."""
    data = b''
    end = time.monotonic() + seconds
    next_nack = time.monotonic()
    while time.monotonic() < end:
        if nack_every and time.monotonic() >= next_nack:
            os.write(fd, bytes([es.SYS_NACK]))
            next_nack += nack_every
        r, _, _ = select.select([fd], [], [], 0.01)
        if r:
            data += os.read(fd, 4096)
    return data


def split_data(data):
    """DATA messages with a right checksum, and the other bytes, as a host
    resynchronising byte by byte takes them: ([message], garbage bytes)."""
    msgs, junk, i = [], b'', 0
    while i < len(data):
        h = data[i]
        n = (1 << ((h >> 3) & 7)) + 2 if h & 0xc0 == 0xc0 and (h >> 3) & 7 <= 5 else 0
        if n and i + n <= len(data) and es.checksum(data[i:i + n - 1]) == data[i + n - 1]:
            msgs.append(data[i:i + n])
            i += n
        else:
            junk += data[i:i + 1]
            i += 1
    return msgs, junk


@pytest.mark.parametrize('kind,kw', [('gyro', {}), ('color', {'rude': 'old-mode'})])
def test_sensor_sends_the_old_mode_until_it_switches(kind, kw):
    """The gyro, as real ones do (and any sensor made rude so), goes on in
    its old mode until it has switched (GYRO-ANG for the 15 ms it takes to
    switch to GYRO-G&A): one message right after the SELECT, then its
    cadence."""
    emu, fd, master = host_side(kind, **kw)
    try:
        connect_by_hand(emu, fd)
        read_for(fd, 0.3, nack_every=0.1)
        os.write(fd, bytes([0x43, 3, es.checksum([0x43, 3])]))
        msgs, junk = split_data(read_for(fd, 0.5, nack_every=0.1))
        modes = [m[0] & 7 for m in msgs]
        assert 3 in modes, (modes, emu.events)
        first = modes.index(3)
        assert modes[:first] and set(modes[:first]) == {0}, modes
        assert set(modes[first:]) == {3}, modes
        assert emu.old_mode_frames >= 1
        assert not junk, junk.hex()
    finally:
        emu.stop()
        os.close(fd)
        os.close(master)


@pytest.mark.parametrize('kind,kw', [('gyro', {'old_mode': False}), ('color', {})])
def test_polite_sensor_is_quiet_while_it_switches(kind, kw):
    emu, fd, master = host_side(kind, **kw)
    try:
        connect_by_hand(emu, fd)
        read_for(fd, 0.3, nack_every=0.1)
        os.write(fd, bytes([0x43, 3, es.checksum([0x43, 3])]))
        read_for(fd, 0.5, nack_every=0.1)
        assert emu.old_mode_frames == 0
        assert 'mode 3' in [e for _, e in emu.events]
    finally:
        emu.stop()
        os.close(fd)
        os.close(master)


@pytest.mark.parametrize('kind', ['color', 'spike-dist'])
def test_rude_sensor_glitches_at_the_baud_switch(kind):
    """Right after the host's ACK, at the data phase's speed: 0xfe, 0xfc or
    0xff, then DATA."""
    emu, fd, master = host_side(kind, rude='glitch', fast_sync=False)
    try:
        connect_by_hand(emu, fd)
        data = read_for(fd, 0.3, nack_every=0.1)
        assert emu.glitches == 1, emu.events
        assert data[0] in es.GLITCH_BYTES, data.hex()
        # A Powered Up device's EXT_MODE before each DATA is no garbage.
        _, junk = split_data(data[1:].replace(es.cmd_msg(es.CMD_EXT_MODE, [0]), b''))
        assert not junk, data.hex()
    finally:
        emu.stop()
        os.close(fd)
        os.close(master)


def test_rude_sensor_sends_unflagged_random_garbage():
    """Garbage before the TYPE and between DATA messages: any byte values
    (not only the 0x00 and 0xff of a speed mismatch), never 0x04 before the
    handshake, never a message a host could take: every DATA message the
    sensor meant arrives whole."""
    emu, fd, master = host_side('gyro', rude='garbage', boot_delay=0.5)
    try:
        before = connect_by_hand(emu, fd)
        assert 1 <= len(before) <= es.GARBAGE_SYNC_MAX, before.hex()
        assert es.SYS_ACK not in before
        assert emu.sync_garbage_bytes == len(before)
        data = read_for(fd, 3.0, nack_every=0.1)
        emu.stop()
        data += read_for(fd, 0.2)
        msgs, junk = split_data(data)
        assert len(junk) == emu.garbage_bytes, (len(junk), emu.garbage_bytes)
        assert len(set(junk) - {0x00, 0xff}) >= 2, junk.hex()
        assert len(msgs) >= 30 and {m[0] for m in msgs} == {0xc8}, len(msgs)
        assert len(msgs) == emu.frames_sent
    finally:
        emu.stop()
        os.close(fd)
        os.close(master)


# ---- rude sensors through the driver --------------------------------------------------


def shown(m, raw):
    """The value the class shows for `raw`: RAW mapped onto SI (times
    10^decimals), truncated, when the ranges differ (non-negative here)."""
    (r0, r1), (s0, s1) = m.raw, m.si
    if (r0, r1) == (s0, s1):
        return raw
    f = 10 ** m.dec
    return int(s0 * f) + int((raw - r0) * (s1 * f - s0 * f) // (r1 - r0))


def slow_us(first_reply):
    """The ultrasonic sensor, its US-DC modes taking `first_reply` s to
    switch."""
    modes = list(es.US.modes)
    for i in (5, 6):
        m = copy.copy(modes[i])
        m.first_reply = first_reply
        modes[i] = m
    sdef = copy.copy(es.US)
    sdef.modes = modes
    return sdef


def test_rude_ultrasonic_dc_modes_never_show_the_old_value(line):
    """US-DC-CM (5) and US-DC-IN (6) both send messages tagged mode 5, and
    a rude sensor goes on in the old mode until it switches: the mode
    write returns with the new mode's value, never the old one's. The
    switch takes 50 ms here rather than the real sensor's 2, so that a
    value of the old mode taken for the new one stays for long enough to
    be read, however slow the guest."""
    emu, path = plug(line, slow_us(0.05), rude=True)
    emu.set_values(5, [111])
    emu.set_values(6, [76])
    for _ in range(3):
        for mode, want in (('US-DC-CM', 111), ('US-DC-IN', 76)):
            write_attr(path, 'mode', mode)
            assert (read_attr(path, 'mode'), read_attr(path, 'value0')) == (mode, str(want)), \
                emu.events[-6:]
    assert emu.old_mode_frames >= 6
    time.sleep(0.5)
    assert read_attr(path, 'value0') == '76'


@pytest.mark.parametrize('kind', ['color', 'us', 'gyro', 'spike-color'])
def test_rude_sensor_mode_writes_show_the_new_mode(line, kind):
    """Every mode that answers (not COL-CAL's kind) of a sensor rude in
    every way: each mode write returns with the new mode's own values."""
    emu, path = plug(line, kind, rude=True)
    sdef = emu.sdef
    modes = [i for i, m in enumerate(sdef.modes) if not m.deaf]
    want = {}
    for i in modes:
        m = sdef.modes[i]
        top = int(min(m.raw[1], 100))
        vals = [int(max(m.raw[0], 0)) + (11 * i + 3 * k + 1) % top for k in range(m.n)]
        emu.set_values(i, vals)
        want[i] = str(shown(m, vals[0]))
    token = read_attr(path, 'modes').split()
    order = modes[1:] + [modes[0]] + modes[::-1]
    for i in order:
        write_attr(path, 'mode', token[i])
        got = (read_attr(path, 'mode'), read_attr(path, 'value0'))
        assert got == (token[i], want[i]), (sdef.modes[i].name, emu.events[-6:])
    last = int(want[order[-1]])
    assert wait_value(path, 0, last) == last
    print('%s: %d old-mode frames, %d glitch(es), %d + %d garbage bytes'
          % (kind, emu.old_mode_frames, emu.glitches, emu.sync_garbage_bytes,
             emu.garbage_bytes))
    assert emu.old_mode_frames > 0
    # A glitch where the speed changed after the ACK (not after a fast sync).
    assert emu.glitches == (emu.sync_speeds[-1] != sdef.speed), emu.events
