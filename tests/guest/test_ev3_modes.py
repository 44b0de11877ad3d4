"""Mode switches of EV3 UART sensors: at wire speed, and no stale first value.

- Writing the mode a sensor is in already (the lego-sensor class's `mode`,
  IIO's `mode`, enabling an IIO buffer on the current mode's channels) sends
  no SELECT on the wire and returns at once. The null modem's wire log
  (wire.py) tells what the discipline wrote; the sensor here takes 200 ms to
  answer a SELECT, so a write that sent one and waited for its confirmation
  could not return in time.
- After a mode write, the first value read is the new mode's, through sysfs
  (as python-ev3dev2 does: write `mode`, read `value0` at once), IIO raw
  reads and IIO buffered capture. The gyro goes on in its old mode until it
  has switched, as real ones do (ev3_sensor's old_mode; uart-peers.md 3.4):
  one old-mode DATA message right after the SELECT, then its cadence, for
  the 15 ms the real sensor takes, or 60 ms (a slowed one, so that an old
  value taken for a new one would stay long enough to be read).
"""
import copy
import errno
import glob
import os
import struct
import threading
import time

import pytest

import ev3
import wire
from ev3 import ev3_sensor as es
from ev3 import drain, iio_device, plug, read_attr, write_attr

ANG, RATE, GA = 0, 1, 3     # GYRO-ANG, GYRO-RATE, GYRO-G&A
# Each mode's values: never the same in two modes.
VALUES = {ANG: [11], RATE: [-22], GA: [33, -44]}
# How long a write of the current mode may take: a SELECT sent and waited
# for takes the slow sensor's SLOW_REPLY at least.
SLOW_REPLY = 0.2
AT_ONCE = 0.1


def gyro(first_reply):
    """The gyro, switching modes in `first_reply` seconds."""
    sdef = copy.copy(es.GYRO)
    sdef.modes = [copy.copy(m) for m in es.GYRO.modes]
    for m in sdef.modes:
        if not m.deaf and m.cadence != 'nack':
            m.first_reply = first_reply
    return sdef


def plug_gyro(line, first_reply):
    emu, path = plug(line, gyro(first_reply))
    assert emu.old_mode, 'the gyro goes on in its old mode during a SELECT'
    for mode, vals in VALUES.items():
        emu.set_values(mode, vals)
    assert ev3.wait_value(path, 0, VALUES[ANG][0]) == VALUES[ANG][0]
    return emu, path


def port_of(line):
    return int(line.address[len('ttyNM'):])


def selects(since, port):
    """The SELECT messages the discipline wrote on `port` since `since`."""
    recs, lost = wire.read(since)
    assert not lost, 'the wire log overflowed'
    return [m for _, _, m in wire.host_messages(recs, port, 'w') if m[0] == 0x43]


def timed_write(path, attr, value):
    t0 = time.monotonic()
    write_attr(path, attr, value)
    return time.monotonic() - t0


def channel(dev, mode_name, index=0):
    """The IIO channel (in_X) of value `index` of a mode, by its label."""
    want = '%s value%d' % (mode_name, index)
    for f in glob.glob(os.path.join(dev, 'in_*_label')):
        if read_attr(dev, os.path.basename(f)) == want:
            return os.path.basename(f)[:-len('_label')]
    raise AssertionError('no IIO channel labelled %r' % want)


def test_writing_the_current_mode_sends_nothing(line):
    if not wire.available():
        pytest.skip('no null-modem wire log (debugfs)')
    emu, path = plug_gyro(line, SLOW_REPLY)
    dev = iio_device('lego-ev3-gyro')
    assert dev
    port = port_of(line)
    # A real switch is seen on the wire (one SELECT) and takes its time.
    since = wire.head()
    took = timed_write(path, 'mode', 'GYRO-RATE')
    assert took >= SLOW_REPLY, took
    assert selects(since, port) == [bytes([0x43, RATE, es.checksum([0x43, RATE])])]
    # The same mode again, every way a mode is written: nothing sent.
    since = wire.head()
    took = []
    for _ in range(5):
        took.append(timed_write(path, 'mode', 'GYRO-RATE'))
        took.append(timed_write(path, 'mode', '#%d' % RATE))
        took.append(timed_write(dev, 'mode', 'GYRO-RATE'))
    rate = channel(dev, 'GYRO-RATE')
    write_attr(dev, 'scan_elements/%s_en' % rate, '1')
    try:
        took.append(timed_write(dev, 'buffer/enable', '1'))
    finally:
        write_attr(dev, 'buffer/enable', '0')
        write_attr(dev, 'scan_elements/%s_en' % rate, '0')
    # The keep-alives go on meanwhile: the log is being written.
    time.sleep(0.25)
    sent = selects(since, port)
    print('\n%d writes of the current mode: %.1f ms at most, %d SELECT sent'
          % (len(took), max(took) * 1e3, len(sent)))
    assert not sent, 'SELECT sent for the current mode: %s' % [m.hex() for m in sent]
    assert max(took) < AT_ONCE, ['%.1f ms' % (t * 1e3) for t in took]
    assert read_attr(path, 'mode') == 'GYRO-RATE'
    assert int(read_attr(path, 'value0')) == VALUES[RATE][0]


@pytest.mark.parametrize('first_reply', [0.015, 0.06])
def test_sysfs_first_value_is_the_new_modes(line, first_reply):
    """Write `mode`, then read `value0` at once and for a while after: never
    a value of the old mode."""
    emu, path = plug_gyro(line, first_reply)
    order = [RATE, ANG, GA, RATE, GA, ANG] * 2
    names = read_attr(path, 'modes').split()
    for mode in order:
        old_frames = emu.old_mode_frames
        write_attr(path, 'mode', names[mode])
        got = []
        end = time.monotonic() + 0.05
        while time.monotonic() < end:
            got.append(tuple(int(read_attr(path, 'value%d' % i))
                             for i in range(len(VALUES[mode]))))
        assert read_attr(path, 'mode') == names[mode]
        bad = [v for v in got if list(v) != VALUES[mode]]
        assert not bad, '%s: read %s after the write (want %s); emulator: %s' % (
            names[mode], bad[:5], VALUES[mode], emu.events[-6:])
        assert emu.old_mode_frames > old_frames, 'the gyro sent no old-mode message'


@pytest.mark.parametrize('first_reply', [0.015, 0.06])
def test_iio_raw_first_value_is_the_new_modes(line, first_reply):
    """Write IIO's `mode`, then read the new mode's channel at once: its own
    value (the old mode's channels: EBUSY)."""
    emu, path = plug_gyro(line, first_reply)
    dev = iio_device('lego-ev3-gyro')
    assert dev
    chans = {m: channel(dev, n) for m, n in ((ANG, 'GYRO-ANG'), (RATE, 'GYRO-RATE'))}
    names = {ANG: 'GYRO-ANG', RATE: 'GYRO-RATE'}
    for mode in [RATE, ANG] * 5:
        other = ANG if mode == RATE else RATE
        write_attr(dev, 'mode', names[mode])
        got = []
        end = time.monotonic() + 0.05
        while time.monotonic() < end:
            got.append(int(read_attr(dev, chans[mode] + '_raw')))
        bad = [v for v in got if v != VALUES[mode][0]]
        assert not bad, '%s: read %s after the write (want %s); emulator: %s' % (
            names[mode], bad[:5], VALUES[mode][0], emu.events[-6:])
        with pytest.raises(OSError) as e:
            read_attr(dev, chans[other] + '_raw')
        assert e.value.errno == errno.EBUSY


def _scan_format(dev, chan):
    """struct format of one scan: the channel's value, then the timestamp."""
    kind = read_attr(dev, 'scan_elements/%s_type' % chan)     # e.g. le:s16/32>>0
    bits, storage = kind.split(':')[1][1:].split('>>')[0].split('/')
    assert kind.startswith('le:s'), kind
    code = {16: 'h', 32: 'i'}[int(storage)]
    return '<%s%dxq' % (code, 8 - int(storage) // 8)


@pytest.mark.parametrize('first_reply', [0.015, 0.06])
def test_iio_buffer_first_sample_is_the_new_modes(line, first_reply):
    """Enabling a buffer on another mode's channel switches the sensor: every
    sample captured, the first included, is of that mode."""
    emu, path = plug_gyro(line, first_reply)
    dev = iio_device('lego-ev3-gyro')
    assert dev
    num = dev.rsplit('iio:device', 1)[1]
    write_attr(dev, 'scan_elements/in_timestamp_en', '1')
    names = {ANG: 'GYRO-ANG', RATE: 'GYRO-RATE'}
    counts = []
    for mode in [RATE, ANG] * 3:
        chan = channel(dev, names[mode])
        write_attr(dev, 'scan_elements/%s_en' % chan, '1')
        fmt = _scan_format(dev, chan)
        fd = os.open('/dev/iio:device' + num, os.O_RDONLY | os.O_NONBLOCK)
        try:
            old_frames = emu.old_mode_frames
            write_attr(dev, 'buffer/enable', '1')
            time.sleep(0.1)
            data = drain(fd, 0.2)
            write_attr(dev, 'buffer/enable', '0')
            data += drain(fd, 0.2)
        finally:
            os.close(fd)
            write_attr(dev, 'scan_elements/%s_en' % chan, '0')
        size = struct.calcsize(fmt)
        samples = [struct.unpack_from(fmt, data, i)[0] for i in range(0, len(data) - size + 1, size)]
        assert samples, '%s: no sample captured' % names[mode]
        bad = [(i, v) for i, v in enumerate(samples) if v != VALUES[mode][0]]
        assert not bad, '%s: samples (index, value) %s of %d (want %d)' % (
            names[mode], bad[:5], len(samples), VALUES[mode][0])
        assert emu.old_mode_frames > old_frames, 'the gyro sent no old-mode message'
        counts.append(len(samples))
    print('\nsamples per capture: %s' % counts)


def test_values_read_during_a_switch_are_never_stale(line):
    """The infrared sensor sends leftovers for 1.1 s after it switched
    (ev3_sensor's IR_STALE_TIME), tagged with its new mode. Readers of its
    values while a mode write is under way (bin_data, all of a mode's values
    at once, and the IIO channel of IR-PROX) get a mode's own values only:
    the old mode's until the sensor switched, then, once the new mode's
    values can be trusted, the new mode's (a read waits until then), never
    a leftover."""
    emu, path = plug(line, 'ir')
    dev = iio_device('lego-ev3-ir')
    assert dev
    vals = {0: [42], 1: [5, -6, 7, -8, 9, -10, 11, -12]}
    for mode, v in vals.items():
        emu.set_values(mode, v)
    assert ev3.wait_value(path, 0, 42) == 42
    good = {bytes(x & 0xff for x in v).ljust(32, b'\0'): mode for mode, v in vals.items()}
    prox = channel(dev, 'IR-PROX') + '_raw'
    stop = threading.Event()
    seen, bad = [], []

    def read_bin():
        with open(os.path.join(path, 'bin_data'), 'rb', buffering=0) as f:
            while not stop.is_set():
                data = os.pread(f.fileno(), 32, 0)
                if data in good:
                    seen.append(good[data])
                else:
                    bad.append(('bin_data', data.hex()))

    def read_iio():
        while not stop.is_set():
            try:
                v = int(read_attr(dev, prox))
            except OSError as e:
                if e.errno != errno.EBUSY:
                    bad.append((prox, e.errno))
                continue
            if v != 42:
                bad.append((prox, v))

    readers = [threading.Thread(target=f) for f in (read_bin, read_iio)]
    for t in readers:
        t.start()
    try:
        for mode in (1, 0, 1, 0):
            t0 = time.monotonic()
            write_attr(path, 'mode', ('IR-PROX', 'IR-SEEK')[mode])
            # The write waits out the leftovers too.
            assert time.monotonic() - t0 >= es.IR_STALE_TIME - 0.05
            time.sleep(0.2)
    finally:
        stop.set()
        for t in readers:
            t.join(10)
    print('\n%d reads of bin_data: %d of IR-PROX, %d of IR-SEEK' % (
        len(seen), seen.count(0), seen.count(1)))
    assert not bad, 'stale values read: %s (of %d)' % (bad[:5], len(bad))
    assert seen.count(0) and seen.count(1)
