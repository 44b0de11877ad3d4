"""The fast sync of Powered Up devices through the real line discipline.

The discipline sends SPEED 115200 at 115200 baud (the probe) when it is
attached, when a device resets (the break of its TX held low) and after a
loss. The emulated SPIKE colour and distance sensors listen for it while
they hold TX low and answer ACK, then send their handshake at 115200: read
back from the trace events (lego_ev3_uart) and the debugfs counters, and
timed against the same handshake at 2400. The BOOST colour and distance
sensor and the EV3 sensors do not answer: they still register at 2400 on
a port that probes, as does a SPIKE sensor whose reset the host did not
probe (on a pty, which has no break).
"""
import fcntl
import os
import select
import struct
import subprocess
import termios
import time

import pytest

import ev3
import tracing
from conftest import wait_for
from ev3 import ev3_sensor, find_sensor, wait_value

N_LEGOEV3 = 29
TIOCSLCKTRMIOS = 0x5457
CBAUD = 0o010017


class Trace(tracing.Trace):
    """The lego_ev3_uart events of one tty, with their timestamps."""

    def __init__(self):
        super().__init__('lego_ev3_uart')

    def of(self, tty):
        """[(time, name, fields)] of `tty`, in order."""
        return [e for e in self.timed() if e[2].get('tty') == tty]

    def registered(self, tty, timeout=5.0):
        """of(tty) once it holds a registration: the driver traces it just
        after the sensor's device appears, which find_sensor() waits for."""
        wait_for(lambda: any(n == 'ev3_uart_sensor' and f['event'] == 'registered'
                             for _, n, f in self.of(tty)), timeout)
        return self.of(tty)


@pytest.fixture
def trace():
    t = Trace()
    yield t
    t.stop()


def counters(tty):
    return tracing.counters('%s/lego_ev3_uart/%s/counters' % (tracing.DEBUGFS, tty))


def last_handshake(events):
    """The last handshake that registered a sensor: (seconds from its TYPE
    to its ACK, the events from just before the TYPE to the registration)."""
    reg = [i for i, (_, n, f) in enumerate(events)
           if n == 'ev3_uart_sensor' and f['event'] == 'registered']
    assert reg, 'no registration in the trace: %s' % events[-30:]
    end = reg[-1]
    acked = [i for i in range(end) if events[i][1] == 'ev3_uart_state'
             and events[i][2]['to'] == 'ACKED']
    typed = [i for i in range(acked[-1]) if events[i][1] == 'ev3_uart_state'
             and events[i][2]['from'] == 'SYNC' and events[i][2]['to'] == 'INFO']
    start = typed[-1]
    # From the last probe before it.
    begin = max([i for i in range(start) if events[i][1] == 'ev3_uart_tx'
                 and events[i][2]['msg'] == 'SPEED'] or [start])
    return events[acked[-1]][0] - events[start][0], events[begin:end + 1]


def plug_and_find(line, kind, **kw):
    emu = line.plug(kind, **kw)
    t0 = time.monotonic()
    path = find_sensor(line.address, timeout=20)
    assert path, 'no sensor for %s (emulator events: %s)' % (kind, emu.events)
    return emu, path, time.monotonic() - t0


@pytest.mark.parametrize('kind', ['spike-color', 'spike-dist'])
def test_spike_registers_by_fast_sync(trace, line, kind):
    emu, path, took = plug_and_find(line, kind)
    sdef = ev3_sensor.SENSORS[kind]
    assert ev3.read_attr(path, 'driver_name') == sdef.driver
    # The emulator answered the probe and the handshake it sent at 115200
    # was taken. Python in the emulated machine answers the probe in 4 to
    # 15 ms (the host waits 30 ms); one that answers too late waits for an
    # ACK in vain, resets, and the next probe but one catches it. The sensor
    # is registered before the emulator's thread has read the host's ACK.
    assert ev3.wait_handshakes(emu, 1) == 1 and emu.sync_speeds[-1] == 115200, emu.events
    assert set(emu.sync_speeds) == {115200} and emu.fast_syncs == len(emu.sync_speeds)
    ev = trace.registered(line.address)
    hs_time, hs = last_handshake(ev)
    names = [(n, f.get('msg') or f.get('to') or f.get('speed')) for _, n, f in hs]
    # The line went to 115200 for the probe, SPEED went out, the ACK came...
    before = [f['speed'] for _, n, f in ev[:ev.index(hs[0])] if n == 'ev3_uart_speed']
    assert before and before[-1] == '115200', names
    assert [f for _, n, f in hs if n == 'ev3_uart_tx' and f['msg'] == 'SPEED'
            and f['hdr'] == '0x52' and f['len'] == '6' and f['ret'] == '0'], hs
    fast = [f for _, n, f in hs if n == 'ev3_uart_state' and f['from'] == 'PROBE']
    assert fast and fast[0]['to'] == 'SYNC' and 'fast sync' in fast[0]['reason'], fast
    # ...the handshake asked for 115200, and no speed change followed the ACK.
    shake = [i for i, (_, n, _f) in enumerate(hs) if n == 'ev3_uart_handshake']
    assert shake and hs[shake[-1]][2]['speed'] == '115200', hs
    assert not [n for _, n, _f in hs[shake[-1]:] if n == 'ev3_uart_speed'], hs
    assert [f for _, n, f in hs[shake[-1]:] if n == 'ev3_uart_tx' and f['msg'] == 'ACK']
    # 741 or 665 bytes: 58 to 65 ms on the line at 115200 (3 s at 2400).
    assert hs_time < 0.5, hs_time
    c = counters(line.address)
    assert 1 <= c['fast_syncs'] <= emu.fast_syncs and c['registered'] == 1, c
    assert c['tx_speed'] == len([n for _, n, f in ev if n == 'ev3_uart_tx'
                                 and f['msg'] == 'SPEED']) >= c['fast_syncs'], c
    # The data phase at 115200.
    emu.set_values(1, [17])
    ev3.write_attr(path, 'mode', sdef.modes[1].name)
    assert wait_value(path, 0, 17) == 17
    print('%s: handshake %.1f ms at 115200, registered %.2f s after the plug, '
          '%d fast sync(s) for it' % (kind, hs_time * 1e3, took, emu.fast_syncs))


def test_fast_sync_is_much_faster_than_2400(trace, line):
    """The same SPIKE colour sensor, its probe answered, then ignored."""
    emu, path, took_fast = plug_and_find(line, 'spike-color')
    fast, _ = last_handshake(trace.registered(line.address))
    assert ev3.wait_handshakes(emu, 1) == 1 and emu.sync_speeds[-1] == 115200, emu.events
    emu.unplug()
    assert ev3.wait_gone(path, 5.0)
    emu.stop()
    time.sleep(0.3)
    emu, path, took_slow = plug_and_find(line, 'spike-color', fast_sync=False)
    slow, hs = last_handshake(trace.registered(line.address))
    assert emu.sync_speeds == [2400], emu.events
    # The probe went out at the plug's break, unanswered: back to 2400.
    assert [f for _, n, f in hs if n == 'ev3_uart_state' and f['from'] == 'PROBE'
            and f['reason'] == 'no answer to SPEED'], hs
    shake = [i for i, (_, n, _f) in enumerate(hs) if n == 'ev3_uart_handshake']
    assert [f['speed'] for _, n, f in hs[shake[-1]:] if n == 'ev3_uart_speed'] == ['115200'], hs
    print('spike-color handshake: %.1f ms at 115200, %.1f ms at 2400; registered '
          '%.2f s and %.2f s after the plug' % (fast * 1e3, slow * 1e3, took_fast, took_slow))
    assert slow > 2.5, slow                  # 741 bytes at 2400: 3.09 s
    assert slow > 10 * fast, (fast, slow)
    assert took_slow - took_fast > 2.0, (took_fast, took_slow)


@pytest.mark.parametrize('kind', ['boost-cds', 'color'])
def test_others_register_at_2400_on_a_probing_port(trace, line, kind):
    """The BOOST sensor and an EV3 sensor ignore the probe (it reaches them
    garbled: they listen at 2400). Rude ones (ev3_sensor's `rude`): garbage
    before their TYPE, a glitch at the baud switch."""
    emu, path, _ = plug_and_find(line, kind, rude=True)
    sdef = ev3_sensor.SENSORS[kind]
    assert ev3.read_attr(path, 'driver_name') == sdef.driver
    assert emu.fast_syncs == 0 and emu.sync_speeds[-1] == 2400, emu.events
    hs_time, hs = last_handshake(trace.registered(line.address))
    assert hs_time > 1.0, hs_time                # 311 or 716 bytes at 2400
    ev = trace.of(line.address)
    probes = [f for _, n, f in ev if n == 'ev3_uart_tx' and f['msg'] == 'SPEED']
    assert probes, 'no probe on the port'
    assert [f for _, n, f in ev if n == 'ev3_uart_state' and f['from'] == 'PROBE'
            and f['reason'] == 'no answer to SPEED']
    c = counters(line.address)
    assert c['fast_syncs'] == 0 and c['tx_speed'] == len(probes), c
    emu.set_values(0, [3])
    assert wait_value(path, 0, 3) == 3
    assert emu.sync_garbage_bytes > 0 and emu.glitches == 1, emu.events


def test_spike_at_2400_when_the_probe_misses_it(ev3_module):
    """On a pty there is no break: the host's probe when it is attached
    comes before the sensor listens, and the SPIKE sensor goes on at 2400
    as it does with a host that never probes."""
    master, slave = os.openpty()
    tty = 'pts' + os.ttyname(slave).split('/')[-1]
    emu = None
    try:
        fcntl.ioctl(slave, termios.TIOCSETD, struct.pack('i', N_LEGOEV3))
        time.sleep(0.2)
        emu = ev3_sensor.EmulatedSensor(master, 'spike-dist')
        emu.start()
        path = find_sensor(tty, timeout=20)
        assert path, emu.events
        assert ev3.read_attr(path, 'driver_name') == 'lego-spike-ultrasonic'
        assert emu.fast_syncs == 0 and emu.sync_speeds == [2400], emu.events
        assert counters(tty)['tx_speed'] >= 1
        emu.set_values(0, [77])
        assert wait_value(path, 0, 77) == 77
    finally:
        if emu:
            emu.stop()
        os.close(slave)
        os.close(master)


def attach_pty_and_go(kind, after_probe=False, **kw):
    """A pty with the discipline on its slave, and an emulated sensor on its
    master that paces what it sends at its speed (a pty paces nothing) and
    starts talking right after the attach: the emulator's thread attaches
    the discipline itself, just before its first byte; with after_probe,
    it also waits for the attach's probe (SPEED 115200) to reach it, so
    that its first byte comes while the host waits for an answer. Returns
    (master, slave, tty name, emulator, monotonic time of the attach)."""
    master, slave = os.openpty()
    tty = 'pts' + os.ttyname(slave).split('/')[-1]
    attached = []

    def attach():
        fcntl.ioctl(slave, termios.TIOCSETD, struct.pack('i', N_LEGOEV3))
        attached.append(time.monotonic())
        seen = b''
        while after_probe and ev3_sensor.PROBE not in seen and \
                time.monotonic() < attached[0] + 2:
            if select.select([master], [], [], 0.05)[0]:
                seen += os.read(master, 64)

    emu = ev3_sensor.EmulatedSensor(master, kind, pace=True, gate=attach, **kw)
    emu.start()
    assert wait_for(lambda: attached, 10), emu.events
    return master, slave, tty, emu, attached[0]


@pytest.mark.parametrize('kind', ['color', 'us', 'gyro', 'ir'])
def test_ev3_registers_on_its_first_handshake(trace, ev3_module, kind):
    """Issue 28: an EV3 sensor that starts its handshake (a real sensor's
    bytes, at 2400 baud's pace) right after the discipline is attached, as
    the attach's probe (SPEED at 115200) reaches it: on a pty the bytes arrive
    whatever the speed, and the probe used to drop them, TYPE included, so
    that only the sensor's second handshake was answered, a whole
    handshake later. Its first one must be answered: from its first byte
    to the registration takes the handshake's time on the wire, and less
    than the same again."""
    sdef = ev3_sensor.SENSORS[kind]
    wire = len(ev3_sensor.handshake(sdef)) * 10 / 2400     # 1.29 to 1.60 s
    master, slave, tty, emu, _ = attach_pty_and_go(kind, after_probe=True, boot_delay=0)
    try:
        path = find_sensor(tty, timeout=4 * wire + 5)
        t_found = time.monotonic()
        assert path, emu.events
        assert ev3.read_attr(path, 'driver_name') == sdef.driver
        took = t_found - emu.handshake_starts[0]
        print('%s: registered %.0f ms after the first handshake byte (wire time %.0f ms), '
              'after %d handshake(s)' % (kind, took * 1e3, wire * 1e3,
                                         len(emu.handshake_starts)))
        # Its first handshake was ACKed: no second one was sent.
        assert ev3.wait_handshakes(emu, 1, 5) == 1, emu.events
        assert len(emu.handshake_starts) == 1 and emu.sync_speeds == [2400], emu.events
        # A second handshake would take the wire time again (and the 80 ms
        # the sensor waits for an ACK): registered before twice the wire
        # time, whatever the load of the emulated machine adds.
        assert wire <= took < 2 * wire, (took, wire, emu.events)
        # It began during the probe: its TYPE ended the probe's wait.
        ev = trace.of(tty)
        assert [f for _, n, f in ev if n == 'ev3_uart_state' and f['from'] == 'PROBE'
                and f['to'] == 'INFO' and f['reason'] == 'TYPE message'], ev[:20]
        assert counters(tty)['fast_syncs'] == 0
        emu.set_values(0, [5])
        assert wait_value(path, 0, 5) == 5
    finally:
        emu.stop()
        os.close(slave)
        os.close(master)


def test_spike_fast_sync_on_a_pty_still_answered(trace, ev3_module):
    """The probe's TYPE hunt does not take a Powered Up device's ACK for
    anything else: a SPIKE sensor listening when the discipline is attached
    answers the attach's probe and registers by fast sync, its handshake
    (paced at 115200) under half a second."""
    master, slave, tty, emu, t_attach = attach_pty_and_go('spike-color', boot_delay=3)
    try:
        path = find_sensor(tty, timeout=10)
        took = time.monotonic() - t_attach
        assert path, emu.events
        assert emu.fast_syncs == 1 and emu.sync_speeds == [115200], emu.events
        hs_time, _ = last_handshake(trace.registered(tty))
        print('spike-color on a pty: handshake %.1f ms, registered %.2f s after the '
              'attach' % (hs_time * 1e3, took))
        assert hs_time < 0.5, hs_time
        assert took < 2.5, took         # not after the 3 s listening and a 2400 handshake
        assert counters(tty)['fast_syncs'] == 1
    finally:
        emu.stop()
        os.close(slave)
        os.close(master)


def test_probe_when_attached_mid_handshake(ev3_module):
    """Attached while an EV3 sensor is half through its handshake: the
    probe costs that handshake at most, the next one registers it."""
    ln = ev3.Line(1)
    emu = ln.plug('color')
    try:
        # The break (0.25 s), the boot delay (0.5 s), then 0.4 s of the 1.3 s.
        time.sleep(1.15)
        ln.attach()
        path = find_sensor(ln.address, timeout=15)
        assert path, emu.events
        assert ev3.read_attr(path, 'driver_name') == 'lego-ev3-color'
        assert emu.fast_syncs == 0 and set(emu.sync_speeds) == {2400}
        assert counters(ln.address)['tx_speed'] >= 1
    finally:
        ln.close()


def kernel_log():
    return subprocess.run(['dmesg'], capture_output=True, text=True, check=True).stdout


def test_no_probe_on_a_tty_that_cannot_do_115200(ev3_module):
    """A tty whose speed is locked at 2400 (as a UART that cannot do 115200):
    one line in the log, no SPEED sent from then on, and a 2400-baud sensor
    still connects."""
    ln = ev3.Line(0)
    ln.attach()
    emu = None
    try:
        time.sleep(0.3)                 # the probe of the attach, at 115200
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS,
                    struct.pack('IIIIB19s', 0, 0, CBAUD, 0, 0, bytes(19)))
        before = kernel_log().count('cannot set 115200 baud: no fast sync')
        sent = counters(ln.address)['tx_speed']
        slow = ev3_sensor.SensorDef(29, 'lego-ev3-color', 3, ev3_sensor.COLOR.modes,
                                    speed=2400)
        emu = ln.plug(slow)
        path = find_sensor(ln.address, timeout=15)
        assert path, emu.events
        emu.set_values(0, [9])
        assert wait_value(path, 0, 9) == 9
        # Lost, and back: the probes after the loss and the break are skipped.
        emu.unplug()
        assert ev3.wait_gone(path, 5.0)
        emu.plug()
        assert find_sensor(ln.address, timeout=15), emu.events
        assert kernel_log().count('cannot set 115200 baud: no fast sync') == before + 1
        assert counters(ln.address)['tx_speed'] == sent
    finally:
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS, struct.pack('IIIIB19s', 0, 0, 0, 0, 0, bytes(19)))
        ln.close()
