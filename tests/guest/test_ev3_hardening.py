"""Sensors that follow every rule of the protocol and still ask too much:
the handshakes of issue 17 that crashed the kernel, mode names that sysfs
cannot list as they are, a UART that cannot reach the sensor's speed, and
the module's own inputs (port labels)."""
import errno
import functools
import fcntl
import glob
import os
import select
import struct
import subprocess
import termios
import threading
import time

import pytest

import ev3
import tracing
from ev3 import find_sensor, iio_device, read_attr, wait_value, write_attr
from ev3_sensor import S8, S16, Mode, SensorDef
from conftest import loaded, module_path, wait_for

TIOCSLCKTRMIOS = 0x5457
CBAUD = 0o010017


def kernel_log():
    return subprocess.run(['dmesg'], capture_output=True, text=True).stdout


def iio_attrs(dev):
    """Every readable attribute of an IIO device: {name: text or errno}."""
    out = {}
    for path in glob.glob(dev + '/*') + glob.glob(dev + '/*/*'):
        if os.path.isdir(path) or not os.access(path, os.R_OK):
            continue
        name = os.path.relpath(path, dev)
        try:
            with open(path) as f:
                out[name] = f.read().strip()
        except OSError as e:
            out[name] = e.errno
    return out


def test_huge_scale_is_left_out_not_divided(line):
    """Issue 17: RAW 0..1 and SI 0..2e7 in C (a scale of 2e10 m°C per raw
    unit) made ev3_iio_scale() raise a divide error in the work that registers
    the sensor, and the kernel panicked. The sensor must register; its channel, whose scale IIO
    cannot show, is left out, and with no channel left there is no IIO
    device."""
    sdef = SensorDef(90, 'ev3-uart-90', 1, [
        Mode('TEMP', (0, 1), (0, 2e7), 'C', 1, S16, 4, 0)], speed=57600)
    emu = line.plug(sdef)
    path = find_sensor(line.address, timeout=15)
    assert path, 'not registered (events: %s)' % emu.events
    assert read_attr(path, 'driver_name') == 'ev3-uart-90'
    emu.set_values(0, [1])
    assert wait_value(path, 0, 20000000) == 20000000     # ev3dev's scaling
    assert iio_device('ev3-uart-90', timeout=1) is None


def test_256_values_get_256_channels(line):
    """Issue 17: 8 modes of 32 s8 values each, in units IIO knows, wrote 256
    channels into arrays of 65 (KASAN: slab-out-of-bounds). Every value
    gets its channel now, every attribute reads, and a buffer captures all
    32 values of one mode."""
    units = ['deg', 'd/s', 'cm', 'C', 'mm', 'inch', 'mV', 'lx']
    sdef = SensorDef(88, 'ev3-uart-88', 8, [
        Mode('M%d' % i, (-128, 127), (-128, 127), units[i], 32, S8, 4, 0,
             cadence='continuous', period=0.05)
        for i in range(8)], speed=57600)
    emu = line.plug(sdef)
    path = find_sensor(line.address, timeout=20)
    assert path, 'not registered (events: %s)' % emu.events
    # The IIO registration of 256 channels takes seconds on the debug
    # kernel (ev3.wait_registered()): the sensor is published after it,
    # and from then on its IIO device is there.
    assert ev3.wait_registered(line.address) is not False, emu.events
    dev = iio_device('ev3-uart-88', timeout=1)
    assert dev, emu.events
    attrs = iio_attrs(dev)
    raw = [a for a in attrs if a.endswith('_raw')]
    assert len(raw) == 256, (sorted(attrs), emu.events)
    assert len([a for a in attrs if a.startswith('scan_elements/') and
                a.endswith('_en')]) == 257                  # and the timestamp
    assert read_attr(dev, 'label') == line.address
    for name, v in attrs.items():
        if name.endswith('_scale'):
            assert float(v) != 0, name
        # Channels of modes other than the current one: EBUSY, nothing else.
        if name.endswith('_raw') and not isinstance(v, str):
            assert v == errno.EBUSY, name
    # Mode 0 (deg): 32 angle channels, in_angl0..31; their values.
    emu.set_values(0, list(range(-16, 16)))
    assert wait_value(path, 7, -9) == -9
    assert [int(read_attr(dev, 'in_angl%d_raw' % i)) for i in range(32)] == \
        list(range(-16, 16))
    assert read_attr(dev, 'in_angl31_label') == 'M0 value31'
    # A buffer of all 32 values of mode 3 (C, in_temp0..31).
    write_attr(dev, 'mode', 'M3')
    emu.set_values(3, list(range(90, 122)))            # s8
    for i in range(32):
        write_attr(dev, 'scan_elements/in_temp%d_en' % i, '1')
    write_attr(dev, 'scan_elements/in_timestamp_en', '1')
    num = dev.rsplit('iio:device', 1)[1]
    fd = os.open('/dev/iio:device' + num, os.O_RDONLY | os.O_NONBLOCK)
    try:
        write_attr(dev, 'buffer/enable', '1')
        data = b''
        deadline = time.monotonic() + 10
        while len(data) < 3 * 136 and time.monotonic() < deadline:
            select.select([fd], [], [], 0.2)
            try:
                data += os.read(fd, 4096)
            except BlockingIOError:
                pass
        # Another mode while the buffer captures M3: EBUSY, not silence.
        with pytest.raises(OSError) as e:
            write_attr(path, 'mode', 'M1')
        assert e.value.errno == errno.EBUSY
        write_attr(dev, 'buffer/enable', '0')
    finally:
        os.close(fd)
    assert len(data) >= 136
    scan = struct.unpack('<32iq', data[:136])
    assert list(scan[:32]) == list(range(90, 122))
    write_attr(path, 'mode', 'M1')
    assert read_attr(path, 'mode') == 'M1'


def test_mode_names_with_spaces_and_twins(line):
    """Real devices name modes "COL O" or "IR Tx", and nothing forbids two
    modes of one name: "modes" lists each so that it can be split on spaces
    and written back to "mode"."""
    sdef = SensorDef(91, 'ev3-uart-91', 4, [
        Mode('COL O', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
        Mode('IR Tx', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
        Mode('TWIN', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
        Mode('TWIN', (0, 100), (0, 100), 'pct', 1, S8, 3, 0)], speed=57600)
    line.plug(sdef)
    path = find_sensor(line.address, timeout=15)
    assert path
    modes = read_attr(path, 'modes').split(' ')
    assert modes == ['COL_O', 'IR_Tx', '#2', '#3']
    assert read_attr(path, 'mode') == 'COL_O'
    for m in ['IR_Tx', '#3', '#2', 'COL_O']:
        write_attr(path, 'mode', m)
        assert read_attr(path, 'mode') == m
    write_attr(path, 'mode', 'IR Tx')          # the name as the sensor sent it
    assert read_attr(path, 'mode') == 'IR_Tx'
    for bad in ['TWIN', '#4', 'IR']:
        with pytest.raises(OSError) as e:
            write_attr(path, 'mode', bad)
        assert e.value.errno == errno.EINVAL


def test_twin_rgb_modes_get_an_iio_device(line):
    """Issue 28: a colour sensor (type 29) with two RGB-RAW modes gave two
    in_intensity_red_raw (and green, blue) channels, and the IIO core
    refused the whole device. The first RGB-RAW keeps the colour names, the
    twin's values are indexed intensity channels."""
    color = ev3.ev3_sensor.COLOR
    rgb = color.modes[4]
    sdef = SensorDef(29, 'lego-ev3-color', 3, color.modes[:5] + [rgb], speed=57600,
                     quirks=False)
    emu = line.plug(sdef)
    path = find_sensor(line.address, timeout=15)
    assert path, 'not registered (events: %s)' % emu.events
    assert read_attr(path, 'modes') == 'COL-REFLECT COL-AMBIENT COL-COLOR REF-RAW #4 #5'
    dev = iio_device('lego-ev3-color', timeout=3)
    assert dev, 'no IIO device: %s' % kernel_log()[-2000:]
    attrs = iio_attrs(dev)
    for c in ['red', 'green', 'blue']:
        assert 'in_intensity_%s_raw' % c in attrs, sorted(attrs)
    # COL-REFLECT, COL-AMBIENT, REF-RAW (2), RGB-RAW's fourth, the twin's 3.
    indexed = sorted(a for a in attrs if a.startswith('in_intensity') and
                     a.endswith('_raw') and a[12:13].isdigit())
    assert indexed == ['in_intensity%d_raw' % i for i in range(8)], sorted(attrs)
    assert read_attr(dev, 'in_intensity5_label') == '#5 value0'
    write_attr(path, 'mode', '#5')
    emu.set_values(5, [11, 22, 33])
    assert wait_value(path, 2, 33) == 33
    assert [int(read_attr(dev, 'in_intensity%d_raw' % i)) for i in (5, 6, 7)] == [11, 22, 33]


def test_failing_device_is_backed_off(line):
    """Issue 28: a device that sends its handshake, one good DATA message
    and seven bad ones, and does it again (a Powered Up one by fast sync,
    every 100 ms or so), had a class device and an IIO device registered
    and unregistered each time, with their uevents and four lines of log.
    After three such failures in a row its reconnects are held off (1 s,
    doubled at every failure: ev3_uart_proto.h), and the port's lines are
    rate limited; once the device behaves it is registered again and
    stays. Played by a small sensor at 2400 baud that resets quickly, one
    connection every half second or so."""
    sdef = SensorDef(99, 'ev3-uart-99', 1, [
        Mode('TEST', (0, 100), (0, 100), 'pct', 1, S8, 3, 0)], speed=57600, quirks=False)
    trace = tracing.Trace('lego_ev3_uart')

    def driver_lines():
        log = kernel_log()
        return log.count(line.address + ':') + log.count('lego-sensor sensor')

    log_before = driver_lines()
    try:
        emu = line.plug(sdef, flaky=True, boot_delay=0.15)
        t0 = time.monotonic()
        time.sleep(10.0)
        took = time.monotonic() - t0
        events = [(t, f['event']) for t, n, f in trace.timed()
                  if n == 'ev3_uart_sensor' and f.get('tty') == line.address]
    finally:
        trace.stop()
    lines = driver_lines() - log_before
    reg = [t for t, e in events if e == 'registered']
    lost = [t for t, e in events if e == 'lost']
    print('flaky device: %d registrations, %d resets, %d log lines in %.1f s'
          % (len(reg), emu.flaky_resets, lines, took))
    assert len(reg) >= 5, (events, emu.events[-10:])
    # From the fourth loss on, the next registration waits 1 s, 2 s, 4 s...
    waits = []
    for k in range(3, len(reg) - 1):
        waits.append(reg[k + 1] - max(t for t in lost if t < reg[k + 1]))
    print('waits after the fourth loss on: %s' % ['%.2f' % w for w in waits])
    for k, w in enumerate(waits):
        assert w >= min(2 ** k, 32), (k, waits, events)
    # At most DEFAULT_RATELIMIT_BURST (10) lines a 5 s interval.
    assert lines <= 10 * (1 + int(took // 5)), lines
    # It kept trying; its handshakes were left unanswered meanwhile.
    assert len(emu.sync_speeds) > emu.handshakes, emu.events[-20:]
    # Well again: registered at the end of the wait in force, and it stays.
    emu.flaky = False
    path = find_sensor(line.address, timeout=2 ** len(waits) + 10)
    assert path, emu.events[-20:]
    emu.set_values(0, [3])
    assert wait_value(path, 0, 3) == 3
    time.sleep(1.0)
    assert ev3.read_attr(path, 'driver_name') == 'ev3-uart-99'


@pytest.mark.no_wire_timing('its writes fail on purpose: the keep-alives stop')
def test_write_errors_are_logged_once(line):
    """Issue 28: a tty whose writes fail (the null modem's fail_writes)
    had a warning for each keep-alive, every 100 ms, as long as it lasted.
    The first error is logged, the others only counted until a message
    goes out again; then the sensor connects again."""
    emu = line.plug('gyro')
    path = find_sensor(line.address, timeout=15)
    assert path, emu.events
    knob = '/sys/module/lego_nullmodem/parameters/fail_writes'
    before = kernel_log().count(line.address + ': cannot send')
    errors = tracing.counters('/sys/kernel/debug/lego_ev3_uart/%s/counters'
                              % line.address)['tx_errors']
    write_attr(os.path.dirname(knob), 'fail_writes', '1')     # ttyNM0
    try:
        # The keep-alives fail, the sensor resets, its next handshakes go
        # unanswered: writes fail for 4 s.
        time.sleep(4.0)
    finally:
        write_attr(os.path.dirname(knob), 'fail_writes', '0')
    c = tracing.counters('/sys/kernel/debug/lego_ev3_uart/%s/counters' % line.address)
    warned = kernel_log().count(line.address + ': cannot send') - before
    print('%d write errors, %d lines' % (c['tx_errors'] - errors, warned))
    assert c['tx_errors'] - errors >= 7, c
    assert warned == 1, warned
    # Writes work again: the sensor is back, and the log says so once.
    path = find_sensor(line.address, timeout=15, gone_from=None)
    assert path, emu.events[-10:]
    assert wait_for(lambda: kernel_log().count(line.address + ': sending to the tty again'), 5)


def test_close_wakes_a_mode_write_on_a_sensor_published_meanwhile(ev3_module):
    """Issue 28: close() wakes the mode changes waiting on the port's
    sensor, but a sensor that the port's work registered while close() waited for
    it got no wake-up: a mode write on it waited out its 250 ms, holding up
    the unregistering. A sensor of 256 channels takes seconds to register
    on the test kernel: the line is closed meanwhile, while mode writes on
    its class device (which the emulator never confirms) follow one
    another; the last must end (ENODEV) as soon as close() marks the
    sensor gone, the trace's "closed" event."""
    units = ['deg', 'd/s', 'cm', 'C', 'mm', 'inch', 'mV', 'lx']
    sdef = SensorDef(88, 'ev3-uart-88', 8, [
        Mode('M%d' % i, (-128, 127), (-128, 127), units[i], 32, S8, 4, 0,
             cadence='continuous', period=0.05)
        for i in range(8)], speed=57600)
    clock = os.path.join(tracing.tracefs(), 'trace_clock')
    with open(clock) as f:
        old_clock = [w.strip('[]') for w in f.read().split() if w.startswith('[')][0]
    with open(clock, 'w') as f:
        f.write('mono')                 # time.monotonic()'s clock
    trace = tracing.Trace('lego_ev3_uart')
    lates = []
    try:
        for _ in range(2):
            ln = ev3.Line(0)
            ln.attach()
            emu = ln.plug(sdef, ignore_select=True)
            path = find_sensor(ln.address, timeout=20)
            assert path, emu.events
            ends = []
            stop = threading.Event()

            def writer():
                while not stop.is_set():
                    try:
                        write_attr(path, 'mode', 'M1')
                        err = 0
                    except OSError as e:
                        err = e.errno
                    ends.append((time.monotonic(), err))
                    if err in (errno.ENODEV, errno.ENOENT):
                        return

            t = threading.Thread(target=writer)
            t.start()
            time.sleep(0.3)
            registered = iio_device('ev3-uart-88', timeout=0)
            ln.detach()                 # waits for the registration
            stop.set()
            t.join(5)
            emu.stop()
            closed = [ts for ts, n, f in trace.timed() if n == 'ev3_uart_sensor' and
                      f.get('tty') == ln.address and f['event'] == 'closed']
            assert closed and ends, (closed, ends)
            assert registered is None, 'registered before the close: nothing tested'
            last, err = ends[-1]
            assert err in (errno.ENODEV, errno.ENOENT), ends
            lates.append(last - closed[-1])
            write_attr(tracing.tracefs(), 'trace', '')
    finally:
        trace.stop()
        with open(clock, 'w') as f:
            f.write(old_clock)
    print('mode writes ended %s ms after the close marked the sensor gone'
          % ['%.0f' % (x * 1e3) for x in lates])
    for late in lates:
        assert late < 0.05, lates


def test_speed_the_uart_cannot_set(ev3_module):
    """A tty whose speed is locked (TIOCSLCKTRMIOS, as a UART that cannot do
    the sensor's speed): the driver says so once and stops answering that
    sensor, rather than connecting and losing it for ever."""
    ln = ev3.Line(0)
    ln.attach()
    try:
        # Lock the speed bits at 2400, where attaching left them.
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS,
                    struct.pack('IIIIB19s', 0, 0, CBAUD, 0, 0, bytes(19)))
        before = kernel_log().count('cannot set 57600 baud')
        emu = ln.plug('us')
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and \
                sum(1 for _, w in emu.events if w == 'handshake sent') < 4:
            time.sleep(0.1)
        sent = sum(1 for _, w in emu.events if w == 'handshake sent')
        assert sent >= 4, emu.events
        assert kernel_log().count('cannot set 57600 baud') == before + 1
        # Only the first handshake was answered.
        assert emu.handshakes <= 1
        assert find_sensor(ln.address, timeout=0.5) is None
    finally:
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS, struct.pack('IIIIB19s', 0, 0, 0, 0, 0, bytes(19)))
        ln.close()


def test_ldisc_number_is_fixed(ev3_module):
    """The discipline always takes 29 (N_DEVELOPMENT): a parameter choosing
    the number could replace any discipline, N_TTY included."""
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    try:
        r = subprocess.run(['insmod', module_path('lego_ev3_uart'), 'ldisc_num=30'],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr      # an unknown parameter is ignored
        with open('/proc/tty/ldiscs') as f:
            ldiscs = dict(line.split() for line in f)
        assert ldiscs.get('n_legoev3') == '29'
        assert not os.path.exists('/sys/module/lego_ev3_uart/parameters/ldisc_num')
    finally:
        if not loaded('lego_ev3_uart'):
            subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)


@pytest.mark.parametrize('labels', ['ttyNM0=in:1', 'ttyNM0=\xe9t\xe9', '=in1', 'ttyNM0',
                                    'ttyNM0=' + 'x' * 16])
def test_port_labels_are_checked(ev3_module, labels):
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    try:
        r = subprocess.run(['insmod', module_path('lego_ev3_uart'), 'port_labels=' + labels],
                           capture_output=True)
        assert r.returncode != 0
        assert not loaded('lego_ev3_uart')
    finally:
        if not loaded('lego_ev3_uart'):
            subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)


def test_label_ioctl_takes_ascii_only(line):
    LEGO_EV3_SET_PORT_LABEL = 0x4010e301      # _IOW(0xE3, 0x01, 16 bytes)
    for bad in [b'\xe9t\xe9', b'in 1', b'in/1']:
        with pytest.raises(OSError) as e:
            fcntl.ioctl(line.fd, LEGO_EV3_SET_PORT_LABEL, bad.ljust(16, b'\0'))
        assert e.value.errno == errno.EINVAL
    fcntl.ioctl(line.fd, LEGO_EV3_SET_PORT_LABEL, b'in-1.a_B'.ljust(16, b'\0'))


def ack_ns():
    with open('/sys/module/lego_nullmodem/parameters/ack_ns') as f:
        return [int(x) for x in f.read().split(',')]


def test_driver_acks_within_80ms_on_the_line(line):
    """The sensor waits 80 ms for the host's ACK. The emulator cannot judge
    that any more (it counts the wait on its own clock, see
    ev3_sensor.wait_ack()), so the null modem times both ACKs on the line
    itself: from the sensor's ACK's last bit to the host's ACK's. Once for
    each EV3 sensor (the line fixture checks every handshake of every test
    the same way, wire.py, but excuses an ACK the VM was stalled for)."""
    delays = []
    for kind in ['color', 'us', 'gyro', 'ir']:
        before = ack_ns()
        emu = line.plug(kind)
        path = find_sensor(line.address, timeout=15)
        assert path, (kind, emu.events)
        after = ack_ns()
        assert after[0] != before[0] and after[1] != before[1]
        delays.append((after[0] - after[1]) / 1e6)
        emu.stop()
        assert ev3.wait_gone(path, 5)
    # 10 ms on purpose, then the ACK's own 4.2 ms on the wire at 2400 baud.
    assert all(14 <= d < 80 for d in delays), delays


@pytest.mark.no_wire_timing('the UART takes 2 bytes at a time: a NACK waits behind the SELECT or '
                            'WRITE being written, and the next period is that much shorter '
                            '(77.8 ms seen; the keep-alive is timed from its work, not the wire)')
def test_partial_writes_are_finished(line):
    """A UART that takes part of a message (its buffer is full) must get the
    rest once it has room, never a truncated frame: every SELECT and WRITE
    here is taken a byte or two at a time."""
    param = '/sys/module/lego_nullmodem/parameters/fifo_room'
    emu = line.plug('gyro')
    path = find_sensor(line.address, timeout=15)
    assert path
    with open(param, 'w') as f:
        f.write('2')
    try:
        for mode in ['GYRO-RATE', 'GYRO-ANG', 'GYRO-RATE']:
            write_attr(path, 'mode', mode)
            assert read_attr(path, 'mode') == mode
        with open(os.path.join(path, 'direct'), 'wb', buffering=0) as f:
            f.write(bytes([0x11] + [0x55] * 8))      # a 10-byte WRITE message
        deadline = time.monotonic() + 3
        while not emu.writes and time.monotonic() < deadline:
            time.sleep(0.05)
        # 9 bytes go out as 16, padded with zeros (a power of two).
        assert emu.writes == [bytes([0x11] + [0x55] * 8 + [0] * 7)]
        time.sleep(1.5)                              # NACKs keep it alive
        assert read_attr(path, 'mode') == 'GYRO-RATE'
        assert emu.handshakes == 1
    finally:
        with open(param, 'w') as f:
            f.write('0')


def test_iio_device_held_open_across_unplug(line):
    """/dev/iio:deviceN held open (a buffer enabled) outlives the sensor:
    reads and ioctls fail cleanly, nothing touches the freed sensor."""
    emu = line.plug('gyro')
    assert find_sensor(line.address, timeout=15)
    dev = iio_device('lego-ev3-gyro')
    assert dev
    write_attr(dev, 'scan_elements/in_angl0_en', '1')
    write_attr(dev, 'buffer/enable', '1')
    num = dev.rsplit('iio:device', 1)[1]
    fd = os.open('/dev/iio:device' + num, os.O_RDONLY | os.O_NONBLOCK)
    try:
        emu.stop()
        assert ev3.wait_gone(dev, 5)
        # The sysfs directory goes first (cdev_device_del()); until
        # iio_device_unregister() has then cleared the device's info, a
        # read may still return the scans captured before the unplug.
        deadline = time.monotonic() + 5
        while True:
            try:
                os.read(fd, 4096)
            except OSError as e:
                assert e.errno in (errno.ENODEV, errno.EAGAIN), e
                break
            assert time.monotonic() < deadline, 'reads still succeed 5 s after the unplug'
            time.sleep(0.01)
        for _ in range(3):
            with pytest.raises(OSError) as e:
                os.read(fd, 64)
            assert e.value.errno in (errno.ENODEV, errno.EAGAIN)
            select.select([fd], [], [], 0.1)
        # IIO_GET_EVENT_FD_IOCTL on a device that is gone.
        with pytest.raises(OSError) as e:
            fcntl.ioctl(fd, 0x80046990, b'\0' * 4)
        assert e.value.errno == errno.ENODEV
    finally:
        os.close(fd)


def test_mode_write_right_after_reconnect(line):
    """Issue 17: after a reconnect the driver restores the user's mode while
    the user may already write another. One of them wins, the sensor
    confirms it, and its values flow (the parser must not be left waiting
    for a mode the sensor is not in)."""
    emu = line.plug('gyro')
    path = find_sensor(line.address, timeout=15)
    assert path
    write_attr(path, 'mode', 'GYRO-RATE')           # restored after reconnects
    for i in range(3):
        emu.unplug()
        assert ev3.wait_gone(path, 5)
        emu.plug()
        sd = ev3.open_sensor(line.address, timeout=15)
        assert sd, emu.events
        try:
            sd.write('mode', 'GYRO-ANG')        # at once, racing the restore
            emu.set_values(0, [40 + i])
            deadline = time.monotonic() + 3
            while sd.read('value0') != str(40 + i) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert sd.read('mode') == 'GYRO-ANG'
            assert sd.read('value0') == str(40 + i)
            path = sd.path
        finally:
            sd.close()
        write_attr(path, 'mode', 'GYRO-RATE')


# The transmit side's queue (issue 28). The null modem's tx_stall holds a
# port's transmitter as a UART whose FIFO is full and whose CTS is held off:
# the discipline's messages then wait in its own queue (tx_buf) and go out
# when the port wakes it. Its wire log tells what went out, when, at what
# speed.

def _release_and_watch(port=0, settle=0.3):
    """Release ttyNM<port>'s transmitter; what it sent from then on, for
    `settle` seconds: [(ns, baud, byte)]."""
    t = time.monotonic_ns()
    ev3.stall(port, False)
    time.sleep(settle)
    return ev3.wire(port, since_ns=t)


# conftest.wait_for, polling every 2 ms: the transmit tests watch counters
# that move within a few milliseconds.
_wait = functools.partial(wait_for, interval=0.002)


def _hex(sent):
    return ' '.join('%02x@%d' % (b, baud) for _, baud, b in sent)


def _stall_empty(port):
    """Hold ttyNM<port>'s transmitter when it holds nothing: a keep-alive
    taken just before would be held in the port, not in the discipline's
    queue."""
    for _ in range(50):
        ev3.clear_wire(port)
        ev3.stall(port, True)
        if ev3.nm_state(port)['held'] == 0:
            return
        ev3.stall(port, False)
        time.sleep(0.02)
    raise AssertionError('ttyNM%d never empty' % port)


def test_probe_message_does_not_outlive_its_speed(ev3_module):
    """Issue 28: what the discipline had queued for the tty survived a
    speed change. Attached to a line whose transmitter is held, the fast
    sync probe's SPEED 115200 waits in the queue while the probe switches
    to 115200, waits its 30 ms and goes back to 2400; once the transmitter
    may send, nothing of it must go out (it went out at 2400, to a sensor
    hunting at 2400)."""
    ev3.load_nullmodem()
    ln = ev3.Line(0)
    ev3.clear_wire(0)
    ev3.stall(0, True)
    try:
        ln.fd = os.open(ln.host, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        fcntl.ioctl(ln.fd, termios.TIOCSETD, struct.pack('i', ev3.N_LEGOEV3))
        # The probe queued its SPEED (the counter counts it), and it is
        # over: back at 2400 baud.
        assert _wait(lambda: ev3.counters(ln.address).get('tx_speed') == 1 and
                     ev3.counters(ln.address).get('state') == 0 and
                     termios.tcgetattr(ln.fd)[5] == termios.B2400, 2), \
            ev3.counters(ln.address)
        assert ev3.nm_state(0)['held'] == 0
        sent = _release_and_watch()
    finally:
        ev3.stall(0, False)
        ln.close()
    print('sent after the probe, once the transmitter could: [%s]' % _hex(sent))
    assert not sent, 'the probe\'s SPEED went out after the probe: %s' % _hex(sent)


def test_ack_does_not_go_out_at_the_sensor_speed(line):
    """Issue 28: an ACK still queued when ev3_uart_ack() switches to the sensor's
    speed went out at that speed, where the sensor (listening at 2400)
    reads garbage. The transmitter is held from before the handshake's
    end; released once the line is at 57600, it may send the keep-alives
    queued at 57600, never the ACK. The sensor, left without its ACK,
    starts over and connects once the line sends again."""
    emu = line.plug('gyro')
    _stall_empty(0)
    try:
        assert _wait(lambda: termios.tcgetattr(line.fd)[5] == termios.B57600, 10), \
            (emu.events, ev3.counters(line.address))
        sent = _release_and_watch(settle=0.15)
    finally:
        ev3.stall(0, False)
    print('sent once the transmitter could: [%s]' % _hex(sent))
    acks = [(baud, b) for _, baud, b in sent if b == 0x04 and baud != 2400]
    assert not acks, 'an ACK went out at the sensor\'s speed: %s' % _hex(sent)
    # The keep-alives queued at 57600 do go out, at 57600.
    fast = [b for _, baud, b in sent if baud == 57600]
    assert fast and set(fast) == {0x02}, _hex(sent)
    assert find_sensor(line.address, timeout=15), emu.events


def _locked_2400_sensor(sdef):
    """ttyNM0 locked at 2400 baud (TIOCSLCKTRMIOS before the attach: the
    probe cannot set 115200, and no probe is made from then on), the
    discipline attached and the 2400-baud sensor `sdef` registered:
    (Line, emulator, SensorDir)."""
    ev3.load_nullmodem()
    ln = ev3.Line(0)
    ln.fd = os.open(ln.host, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        attrs = termios.tcgetattr(ln.fd)
        attrs[4] = attrs[5] = termios.B2400
        attrs[2] = (attrs[2] & ~CBAUD) | termios.B2400
        termios.tcsetattr(ln.fd, termios.TCSANOW, attrs)
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS,
                    struct.pack('IIIIB19s', 0, 0, CBAUD, 0, 0, bytes(19)))
        fcntl.ioctl(ln.fd, termios.TIOCSETD, struct.pack('i', ev3.N_LEGOEV3))
        assert _wait(lambda: ev3.counters(ln.address).get('speed_changes', 0) >= 2 and
                     ev3.counters(ln.address).get('state') == 0, 2), ev3.counters(ln.address)
        emu = ln.plug(sdef)
        sd = ev3.open_sensor(ln.address, timeout=20)
        assert sd, emu.events
        assert ev3.wait_registered(ln.address) is not False
        return ln, emu, sd
    except BaseException:
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS, struct.pack('IIIIB19s', 0, 0, 0, 0, 0, bytes(19)))
        ln.close()
        raise


def test_queue_for_a_lost_sensor_is_dropped(ev3_module):
    """Issue 28: a SELECT or a WRITE still queued when a sensor was lost
    reached the next one. On a line whose speed is locked at 2400 (no
    probe, no speed change: the speed change cannot drop them), a 2400-baud
    sensor gets a WRITE and a SELECT while the transmitter is held, and is
    unplugged; once it is lost and the transmitter may send, none of that
    (nor the keep-alives queued meanwhile) must go out. The next sensor
    then connects and receives no WRITE."""
    sdef = SensorDef(92, 'ev3-uart-92', 2, [
        Mode('ONE', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
        Mode('TWO', (0, 100), (0, 100), 'pct', 1, S8, 3, 0)], speed=2400, quirks=False)
    ln, emu, sd = _locked_2400_sensor(sdef)
    try:
        _stall_empty(0)
        ends = []

        def select():
            try:
                sd.write('mode', 'TWO')
                ends.append(0)
            except OSError as e:
                ends.append(e.errno)

        try:
            sd.write('direct', '\x11')
            t = threading.Thread(target=select)
            t.start()
            assert _wait(lambda: ev3.counters(ln.address).get('tx_select', 0) >= 1, 2)
            emu.unplug()
            assert sd.wait_gone(5), emu.events
            assert _wait(lambda: ev3.counters(ln.address).get('lost') == 1 and
                         ev3.counters(ln.address).get('state') == 0, 2)
            t.join(5)
            c = ev3.counters(ln.address)
            sent = _release_and_watch()
        finally:
            ev3.stall(0, False)
            sd.close()
        print('queued while held: %d WRITE, %d SELECT, %d NACK; sent after the loss: [%s]'
              % (c['tx_write'], c['tx_select'], c['tx_nack'], _hex(sent)))
        assert ends and ends[0] in (errno.ENODEV, errno.ETIMEDOUT), ends
        assert not sent, 'queued for the lost sensor, sent after: %s' % _hex(sent)
        emu.writes.clear()
        emu.plug()
        assert find_sensor(ln.address, timeout=20), emu.events
        time.sleep(0.3)
        assert emu.writes == [], emu.writes
    finally:
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS, struct.pack('IIIIB19s', 0, 0, 0, 0, 0, bytes(19)))
        ln.close()


def test_bytes_the_tty_holds_for_a_lost_sensor_are_dropped(ev3_module):
    """Issue 28, the tty driver's side: dropping the discipline's own queue
    is not enough when the tty driver still holds bytes it has not sent (a
    UART's buffer behind a held transmitter, a USB adapter's). A 32-byte
    WRITE to a 2400-baud sensor (140 ms on the wire) is held in the port,
    and the sensor is unplugged; once it is lost and the transmitter may
    send, none of the WRITE must go out (to the next sensor)."""
    sdef = SensorDef(92, 'ev3-uart-92', 2, [
        Mode('ONE', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
        Mode('TWO', (0, 100), (0, 100), 'pct', 1, S8, 3, 0)], speed=2400, quirks=False)
    ln, emu, sd = _locked_2400_sensor(sdef)
    try:
        try:
            for _ in range(10):
                ev3.clear_wire(0)
                fd = os.open('direct', os.O_WRONLY, dir_fd=sd.fd)
                try:
                    os.write(fd, bytes([0x11] + [0x55] * 31))
                finally:
                    os.close(fd)
                ev3.stall(0, True)
                held = ev3.nm_state(0)['held']
                if held:
                    break
                ev3.stall(0, False)
                time.sleep(0.2)
            assert held, 'the WRITE was never held in the port'
            emu.unplug()
            assert sd.wait_gone(5), emu.events
            assert _wait(lambda: ev3.counters(ln.address).get('lost') == 1 and
                         ev3.counters(ln.address).get('state') == 0, 2)
            sent = _release_and_watch()
        finally:
            ev3.stall(0, False)
            sd.close()
        print('held in the port: %d bytes; sent after the loss: [%s]' % (held, _hex(sent)))
        assert not sent, 'held for the lost sensor, sent after: %s' % _hex(sent)
    finally:
        fcntl.ioctl(ln.fd, TIOCSLCKTRMIOS, struct.pack('IIIIB19s', 0, 0, 0, 0, 0, bytes(19)))
        ln.close()


def test_write_wakeup_is_clear_after_detach(ev3_module):
    """Issue 28: close must leave TTY_DO_WRITE_WAKEUP clear for the next
    discipline. The flag is set while the discipline waits for room (its
    probe's SPEED on a held transmitter); after the switch back to N_TTY,
    with the transmitter still held (so that no wakeup clears it through
    N_TTY), it must read clear. Only the end state: the race the order of
    close()'s steps closes (a tx_work setting the flag again between the
    clear and its cancel) cannot be made to happen, see testing.rst."""
    ev3.load_nullmodem()
    ln = ev3.Line(0)
    ev3.stall(0, True)
    try:
        ln.fd = os.open(ln.host, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        fcntl.ioctl(ln.fd, termios.TIOCSETD, struct.pack('i', ev3.N_LEGOEV3))
        assert _wait(lambda: ev3.counters(ln.address).get('tx_speed') == 1 and
                     ev3.counters(ln.address).get('state') == 0, 2), ev3.counters(ln.address)
        during = ev3.nm_state(0)['write_wakeup']
        fcntl.ioctl(ln.fd, termios.TIOCSETD, struct.pack('i', 0))     # N_TTY
        after = ev3.nm_state(0)['write_wakeup']
    finally:
        ev3.stall(0, False)
        ln.close()
    print('TTY_DO_WRITE_WAKEUP: %d while waiting for room, %d after the detach' % (during, after))
    assert during == 1
    assert after == 0
