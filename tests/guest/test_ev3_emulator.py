"""The emulated sensor keeps the real sensors' 80 ms wait for the host's ACK.

No driver here: the test plays the host on one end of a pty and the emulator
the sensor on the other, so the test alone decides when the ACK comes.
"""
import os
import select
import time

import ev3

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
