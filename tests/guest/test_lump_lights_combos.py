"""Powered Up lights and combined modes, through the real line discipline
over the null-modem line:

- the SPIKE colour sensor's three lights are LED class devices
  (sensorN:white:light-0..2, max_brightness 100): a brightness written
  reaches the device as the LIGHT mode's values (EXT_MODE + DATA, sent
  while the device is in LIGHT, as Pybricks does), the user's mode and
  values stay, and the timer trigger blinks a light;
- a buffered IIO capture whose channels span several modes of a device
  that offers them together (MODE_COMBOS) gets them in one scan: a Technic
  Large motor's speed, position and absolute position (its recorded
  handshake), the BOOST sensor's proximity and RGB; a scan mask no
  combination covers is refused (EINVAL).
"""
import errno
import glob
import os
import struct
import time

import pytest

from ev3 import drain, iio_device, plug, read_attr, wait_registered, wait_value, write_attr

LEDS = '/sys/class/leds'


def _leds(path, n=0):
    """The LED devices of the sensor at `path`, waiting for `n` of them
    (the LED view registers them after the class device appears)."""
    def found():
        return sorted(glob.glob('%s/%s:*' % (LEDS, os.path.basename(path))))
    _wait(lambda: len(found()) >= n)
    return found()


def _wait(cond, timeout=3.0):
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.02)
    return True


def _sent(emu, payload, mode=3):
    """Wait until the device's last values for `mode` are `payload` (the
    LED core may set a brightness from its work item)."""
    return _wait(lambda: emu.lump_writes and emu.lump_writes[-1] == (mode, payload))


def test_spike_color_lights_are_leds(line):
    emu, path = plug(line, 'spike-color')
    name = os.path.basename(path)
    leds = _leds(path, 3)
    assert [os.path.basename(d) for d in leds] == \
        ['%s:white:light-%d' % (name, i) for i in range(3)]
    for d in leds:
        assert read_attr(d, 'max_brightness') == '100'
        assert read_attr(d, 'brightness') == '0'
    # The user reads REFLT: it stays while the lights are set.
    emu.set_values(1, [33])
    write_attr(path, 'mode', 'REFLT')
    assert wait_value(path, 0, 33) == 33

    write_attr(leds[1], 'brightness', '40')
    # EXT_MODE 0, DATA of mode 3: the three values padded to four bytes,
    # sent while the device was in LIGHT.
    assert _sent(emu, bytes([0, 40, 0, 0])), emu.lump_writes
    assert emu.lump_write_modes[-1] == 3
    assert emu.values[3] == [0, 40, 0]
    assert read_attr(path, 'mode') == 'REFLT'
    assert _wait(lambda: emu.mode == 1), emu.events[-10:]
    emu.set_values(1, [34])
    assert wait_value(path, 0, 34) == 34

    write_attr(leds[0], 'brightness', '100')
    assert _sent(emu, bytes([100, 40, 0, 0])), emu.lump_writes
    # Above max_brightness: the LED core makes it 100.
    write_attr(leds[2], 'brightness', '255')
    assert _sent(emu, bytes([100, 40, 100, 0])), emu.lump_writes
    assert read_attr(leds[1], 'brightness') == '40'
    write_attr(leds[1], 'brightness', '0')
    assert _sent(emu, bytes([100, 0, 100, 0])), emu.lump_writes
    assert len(emu.lump_writes) == 4
    assert all(m == 3 for m in emu.lump_write_modes)
    assert read_attr(path, 'mode') == 'REFLT'


def test_spike_color_light_timer_trigger(line):
    emu, path = plug(line, 'spike-color')
    led = _leds(path, 3)[2]
    if 'timer' not in read_attr(led, 'trigger'):
        pytest.skip('no timer trigger in this kernel')
    write_attr(led, 'brightness', '70')
    assert _sent(emu, bytes([0, 0, 70, 0]))
    n0 = len(emu.lump_writes)
    write_attr(led, 'trigger', 'timer')
    write_attr(led, 'delay_on', '150')
    write_attr(led, 'delay_off', '150')
    time.sleep(2.0)
    write_attr(led, 'trigger', 'none')
    time.sleep(0.5)
    blinks = [p[2] for _, p in emu.lump_writes[n0:]]
    # Light 2 went on and off, again and again; the other two stayed off.
    changes = sum(1 for a, b in zip(blinks, blinks[1:]) if (a == 0) != (b == 0))
    assert changes >= 4, blinks
    assert all(p[0] == 0 and p[1] == 0 for _, p in emu.lump_writes[n0:])
    assert set(blinks) <= {0, 70, 100}, blinks
    # Stopped: no more writes.
    n1 = len(emu.lump_writes)
    time.sleep(0.6)
    assert len(emu.lump_writes) == n1
    assert read_attr(path, 'mode') == 'COLOR'


def test_no_leds_without_lights(line):
    emu, path = plug(line, 'boost-cds')
    assert wait_registered(line.address) is not False
    assert _leds(path) == []


def _channels(dev):
    """{label: scan element name stem} of an IIO device's channels."""
    out = {}
    for f in glob.glob(dev + '/in_*_label'):
        stem = os.path.basename(f)[:-len('_label')]
        out[read_attr(dev, os.path.basename(f))] = stem
    return out


def _capture(dev, stems, body, seconds):
    """Enable a buffer of `stems` and the timestamp, run body(), read the
    scans for `seconds` more, disable: the raw bytes."""
    num = dev.rsplit('iio:device', 1)[1]
    for s in stems:
        write_attr(dev, 'scan_elements/%s_en' % s, '1')
    write_attr(dev, 'scan_elements/in_timestamp_en', '1')
    fd = os.open('/dev/iio:device' + num, os.O_RDONLY | os.O_NONBLOCK)
    data = b''
    try:
        write_attr(dev, 'buffer/enable', '1')
        data += body(fd)
        data += drain(fd, seconds)
        write_attr(dev, 'buffer/enable', '0')
        data += drain(fd, 0.5)
    finally:
        os.close(fd)
        for s in stems:
            write_attr(dev, 'scan_elements/%s_en' % s, '0')
    return data


def test_technic_motor_combined_capture(line):
    """Speed, position and absolute position in one scan: every scan holds
    values the emulator sent together (they change together, so a scan
    mixing two messages would break pos == 1000 * speed + 7)."""
    emu, path = plug(line, 'technic-l')
    dev = iio_device('lego-technic-l-motor')
    assert dev
    ch = _channels(dev)
    stems = [ch['SPEED value0'], ch['POS value0'], ch['APOS value0']]
    emu.set_many({1: [0], 2: [7], 3: [-90]})

    def vary(fd):
        got = b''
        for k in range(1, 60):
            emu.set_many({1: [k], 2: [1000 * k + 7], 3: [k - 90]})
            time.sleep(0.03)
            got += drain(fd, 0.01)
        return got

    data = _capture(dev, stems, vary, 0.3)
    assert emu.combo_setups == [(0, ((1, 0), (2, 0), (3, 0)))], emu.events[-10:]
    # Three s32 values, 4 bytes of padding, the s64 timestamp.
    scans = [struct.unpack_from('<iii4xq', data, i) for i in range(0, len(data) - 23, 24)]
    assert len(data) % 24 == 0
    assert len(scans) > 50, len(scans)
    bad = [s for s in scans if s[1] != 1000 * s[0] + 7 or s[2] != s[0] - 90]
    assert not bad, bad[:5]
    speeds = {s[0] for s in scans}
    assert len(speeds) > 30, sorted(speeds)
    stamps = [s[3] for s in scans]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    # Disabled: the combined mode ended (a SELECT), the user's mode is back.
    assert _wait(lambda: emu.combo is None)
    assert read_attr(path, 'mode') == 'POWER'
    write_attr(path, 'mode', 'POS')
    emu.set_values(2, [4242])
    assert wait_value(path, 0, 4242) == 4242


def test_boost_combined_and_refused(line):
    """The BOOST sensor's proximity and RGB in one scan; AMBI is in no
    combination (MODE_COMBOS 0x004f): a mask with it and PROX is refused."""
    emu, path = plug(line, 'boost-cds')
    dev = iio_device('lego-boost-color-dist')
    assert dev
    ch = _channels(dev)
    write_attr(dev, 'scan_elements/%s_en' % ch['PROX value0'], '1')
    with pytest.raises(OSError) as e:
        write_attr(dev, 'scan_elements/%s_en' % ch['AMBI value0'], '1')
    assert e.value.errno == errno.EINVAL
    write_attr(dev, 'scan_elements/%s_en' % ch['PROX value0'], '0')

    stems = [ch['PROX value0'], ch['RGB_I value0'], ch['RGB_I value1'], ch['RGB_I value2']]
    emu.set_many({1: [0], 6: [0, 0, 0]})

    def vary(fd):
        got = b''
        for k in range(1, 11):
            emu.set_many({1: [k], 6: [100 + k, 200 + k, 300 + k]})
            time.sleep(0.05)
            got += drain(fd, 0.01)
        return got

    data = _capture(dev, stems, vary, 0.3)
    assert emu.combo_setups[-1] == (0, ((1, 0), (6, 0), (6, 1), (6, 2)))
    scans = [struct.unpack_from('<iiiiq', data, i) for i in range(0, len(data) - 23, 24)]
    assert len(scans) > 10
    assert all((s[1], s[2], s[3]) == ((100 + s[0], 200 + s[0], 300 + s[0]) if s[0] else
                                     (0, 0, 0)) for s in scans), scans[:5]
    assert len({s[0] for s in scans}) >= 8


def test_mode_data_attribute(line):
    """The BOOST sensor's COL O and IR Tx take values through mode_data:
    sent in their mode, as the lights' are; the user's mode stays."""
    emu, path = plug(line, 'boost-cds')
    assert read_attr(path, 'mode_data') == 'COL_O IR_Tx'
    emu.set_values(3, [55])
    write_attr(path, 'mode', 'REFLT')
    write_attr(path, 'mode_data', 'IR_Tx -2\n')
    assert emu.lump_writes[-1] == (7, bytes([0xfe, 0xff]))
    assert emu.lump_write_modes[-1] == 7
    write_attr(path, 'mode_data', 'COL_O 9')
    assert emu.lump_writes[-1] == (5, bytes([9]))
    assert emu.values[5] == [9]
    assert read_attr(path, 'mode') == 'REFLT'
    assert wait_value(path, 0, 55) == 55
    for bad, err in (('COL_O 1 2', errno.EINVAL), ('REFLT 1', errno.EINVAL),
                     ('COL_O x', errno.EINVAL), ('IR_Tx 40000', errno.ERANGE),
                     ('NOSUCH 1', errno.EINVAL)):
        with pytest.raises(OSError) as e:
            write_attr(path, 'mode_data', bad)
        assert e.value.errno == err, bad
    assert len(emu.lump_writes) == 2


def test_mode_data_ev3_sensor(line):
    emu, path = plug(line, 'color')
    assert read_attr(path, 'mode_data') == ''
    with pytest.raises(OSError) as e:
        write_attr(path, 'mode_data', 'COL-REFLECT 1')
    assert e.value.errno == errno.EINVAL
    assert wait_registered(line.address) is not False
    assert _leds(path) == []
