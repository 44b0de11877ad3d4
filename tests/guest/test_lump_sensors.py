"""Emulated Powered Up (LUMP) devices through the real line discipline, over
the null-modem line: the BOOST colour and distance sensor (its recorded
handshake), the SPIKE colour and distance sensors. They register with all
their modes (up to 11 here), values read through sysfs and IIO, modes 8 and
up are selected (EXT_MODE before their DATA), and an EV3 sensor on the same
line works after a Powered Up device is unplugged."""
import time

import pytest

from ev3 import (ev3_sensor, find_sensor, iio_device, plug, read_attr, wait_attr_int, wait_gone,
                 wait_value, write_attr)

KINDS = ['boost-cds', 'spike-color', 'spike-dist']


def token(name):
    return name.replace(' ', '_')


def shown(m, raw):
    """The value the class shows: RAW mapped onto SI (times 10^decimals),
    truncated, when the two ranges differ (all non-negative here)."""
    (r0, r1), (s0, s1) = m.raw, m.si
    if (r0, r1) == (s0, s1):
        return raw
    f = 10 ** m.dec
    return int(s0 * f) + int((raw - r0) * (s1 * f - s0 * f) // (r1 - r0))


@pytest.mark.parametrize('kind', KINDS)
def test_lump_registers_with_all_modes(line, kind):
    sdef = ev3_sensor.SENSORS[kind]
    emu, path = plug(line, kind)
    assert read_attr(path, 'driver_name') == sdef.driver
    assert read_attr(path, 'modes').split(' ') == [token(m.name) for m in sdef.modes]
    assert len(sdef.modes) > 8
    assert read_attr(path, 'mode') == token(sdef.modes[0].name)
    # VERSION's firmware word, as LEGO writes it (BCD fields).
    fw = sdef.version[0]
    assert read_attr(path, 'fw_version') == '%x.%x.%02x.%04x' % (
        fw >> 28, fw >> 24 & 0xf, fw >> 16 & 0xff, fw & 0xffff)


@pytest.mark.parametrize('kind', KINDS)
def test_lump_every_mode(line, kind):
    """Every mode, 8 and up included, selected by its token; its values.
    The device is rude (ev3_sensor's `rude`): DATA of the old mode until it
    switches, a glitch at the baud switch, garbage."""
    sdef = ev3_sensor.SENSORS[kind]
    emu, path = plug(line, kind, rude=True)
    order = list(range(8, len(sdef.modes))) + list(range(8))
    for i in order:
        m = sdef.modes[i]
        n = m.n
        values = [int(m.raw[0]) + (7 * i + 3 * k + 1) % min(100, int(m.raw[1] - m.raw[0]))
                  for k in range(n)]
        emu.set_values(i, values)
        write_attr(path, 'mode', token(m.name))
        assert read_attr(path, 'mode') == token(m.name)
        assert read_attr(path, 'num_values') == str(n)
        for k in range(min(n, 8)):
            want = shown(m, values[k])
            assert wait_value(path, k, want) == want, (m.name, k)
    assert emu.old_mode_frames > 0


def test_lump_iio_rgb_and_high_mode(line):
    emu, path = plug(line, 'boost-cds', rude=True)
    dev = iio_device('lego-boost-color-dist')
    assert dev
    emu.set_values(6, [300, 400, 500])
    write_attr(dev, 'mode', 'RGB_I')
    assert wait_attr_int(dev, 'in_intensity_red_raw', 300) == 300
    assert int(read_attr(dev, 'in_intensity_green_raw')) == 400
    assert int(read_attr(dev, 'in_intensity_blue_raw')) == 500
    assert read_attr(path, 'mode') == 'RGB_I'
    # A mode of 8 and up through the IIO view too.
    write_attr(dev, 'mode', 'CALIB')
    assert read_attr(path, 'mode') == 'CALIB'


def test_ev3_sensor_after_lump_unplugged(line):
    emu, path = plug(line, 'spike-color')
    write_attr(path, 'mode', 'CALIB')         # mode 9: EXT_MODE 8 in force
    emu.unplug()
    assert wait_gone(path, 3.0)
    emu.stop()
    time.sleep(0.3)
    emu2 = line.plug('color')
    again = find_sensor(line.address, timeout=15)
    assert again
    assert read_attr(again, 'driver_name') == 'lego-ev3-color'
    emu2.set_values(0, [42])
    assert wait_value(again, 0, 42) == 42
    write_attr(again, 'mode', 'COL-AMBIENT')
    emu2.set_values(1, [17])
    assert wait_value(again, 0, 17) == 17


def test_lump_iio_distance(line):
    """The SPIKE distance sensor's cm modes are IIO distances in metres."""
    emu, path = plug(line, 'spike-dist')
    dev = iio_device('lego-spike-ultrasonic')
    assert dev
    emu.set_values(0, [123])                        # 123 cm
    assert wait_attr_int(dev, 'in_distance0_raw', 123) == 123
    assert float(read_attr(dev, 'in_distance0_scale')) == pytest.approx(0.01)
    assert read_attr(dev, 'mode') == 'DISTL'
