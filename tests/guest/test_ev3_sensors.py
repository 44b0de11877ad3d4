"""Emulated EV3 sensors through the real line discipline, over a null-modem
line that paces bytes at the baud rate and garbles bytes sent at the wrong
speed."""
import errno
import os
import time

import pytest

from ev3 import (ev3_sensor, find_sensor, plug, read_attr, wait_gone, wait_handshakes, wait_value,
                 write_attr)

KINDS = ['color', 'us', 'gyro', 'gyro-old', 'ir', 'fcl-humidity']


@pytest.mark.parametrize('kind', KINDS)
def test_handshake_registers_sensor(line, kind):
    sdef = ev3_sensor.SENSORS[kind]
    emu, path = plug(line, kind)
    assert read_attr(path, 'driver_name') == sdef.driver
    assert read_attr(path, 'modes').split(' ') == [m.name for m in sdef.modes]
    assert read_attr(path, 'mode') == sdef.modes[0].name
    assert read_attr(path, 'num_values') == str(sdef.modes[0].n)
    assert read_attr(path, 'decimals') == str(sdef.modes[0].dec)
    assert read_attr(path, 'units') == (sdef.modes[0].units or '')
    assert read_attr(path, 'commands') == ''
    assert os.path.realpath(os.path.join(path, 'device')).endswith('/ttyNM0')
    with open(os.path.join(path, 'uevent')) as f:
        uevent = f.read().split('\n')
    assert 'LEGO_DRIVER_NAME=' + sdef.driver in uevent
    assert 'LEGO_ADDRESS=ttyNM0' in uevent
    assert wait_handshakes(emu, 1, timeout=2) == 1, emu.events


@pytest.mark.parametrize('kind', KINDS)
def test_every_mode(line, kind):
    sdef = ev3_sensor.SENSORS[kind]
    emu, path = plug(line, kind)
    for i, m in enumerate(sdef.modes):
        if m.deaf:
            continue            # these make the sensor drop out: tested apart
        n = len(emu.values[i])
        values = [(7 * i + 3 * k + 1) % 100 for k in range(n)]
        emu.set_values(i, values)
        write_attr(path, 'mode', m.name)
        assert read_attr(path, 'mode') == m.name
        assert read_attr(path, 'num_values') == str(n)
        assert read_attr(path, 'units') == (m.units or '')
        assert read_attr(path, 'decimals') == str(m.dec)
        fmt = {0: 's8', 1: 's16', 2: 's32', 3: 'float'}[m.t]
        assert read_attr(path, 'bin_data_format') == fmt
        for k in range(n):
            assert wait_value(path, k, values[k]) == values[k], (m.name, k)
        if n < 8:               # value0 .. value7 exist
            with pytest.raises(OSError) as e:
                read_attr(path, 'value%d' % n)
            assert e.value.errno == errno.ENXIO


def test_unknown_mode_is_einval(line):
    emu, path = plug(line, 'color')
    with pytest.raises(OSError) as e:
        write_attr(path, 'mode', 'NO-SUCH-MODE')
    assert e.value.errno == errno.EINVAL
    with pytest.raises(OSError) as e:
        write_attr(path, 'command', 'anything')
    assert e.value.errno == errno.EINVAL
    # UART sensors are not polled: poll_ms can be neither read nor set.
    with pytest.raises(OSError) as e:
        read_attr(path, 'poll_ms')
    assert e.value.errno == errno.EOPNOTSUPP
    with pytest.raises(OSError) as e:
        write_attr(path, 'poll_ms', '100')
    assert e.value.errno == errno.EOPNOTSUPP


def test_values_follow_the_sensor(line):
    emu, path = plug(line, 'color')
    for v in (0, 17, 100, 42):
        emu.set_values(0, [v])
        assert wait_value(path, 0, v) == v
    with open(os.path.join(path, 'bin_data'), 'rb') as f:
        data = f.read()
    assert len(data) == 32 and data[0] == 42


def test_rgb_raw_bad_checksums_and_fourth_value(line):
    emu, path = plug(line, 'color')
    emu.set_values(4, [300, 400, 500, 12])
    write_attr(path, 'mode', 'RGB-RAW')
    assert read_attr(path, 'num_values') == '4'
    assert [wait_value(path, k, v) for k, v in enumerate([300, 400, 500, 12])] == \
        [300, 400, 500, 12]


def test_ultrasonic_cm_and_dc_in(line):
    emu, path = plug(line, 'us')
    emu.set_values(0, [263])
    assert wait_value(path, 0, 263) == 263          # 26.3 cm, 1 decimal
    assert read_attr(path, 'units') == 'cm'
    emu.set_values(6, [76])
    write_attr(path, 'mode', 'US-DC-IN')             # streams as mode 5
    assert wait_value(path, 0, 76) == 76
    time.sleep(0.5)
    assert read_attr(path, 'mode') == 'US-DC-IN'
    # The one-shot mode answers once, 61 ms after SELECT.
    emu.set_values(3, [120])
    write_attr(path, 'mode', 'US-SI-CM')
    assert wait_value(path, 0, 120) == 120


def test_gyro_reset_through_direct(line):
    emu, path = plug(line, 'gyro')
    emu.set_values(0, [42])
    assert wait_value(path, 0, 42) == 42
    with open(os.path.join(path, 'direct'), 'wb') as f:
        f.write(b'\x11')
    assert wait_value(path, 0, 0) == 0
    assert emu.writes == [b'\x11']
    with pytest.raises(OSError) as e:
        with open(os.path.join(path, 'direct'), 'wb') as f:
            f.write(bytes(33))
    assert e.value.errno == errno.EINVAL


def test_ir_settles_before_mode_write_returns(line):
    emu, path = plug(line, 'ir')
    emu.set_values(2, [1, 2, 3, 4])
    t0 = time.monotonic()
    write_attr(path, 'mode', 'IR-REMOTE')
    took = time.monotonic() - t0
    assert took >= 1.0, 'mode write returned before the IR sensor settled (%.2f s)' % took
    assert [int(read_attr(path, 'value%d' % k)) for k in range(4)] == [1, 2, 3, 4]


def test_keepalive_holds_10s(line):
    emu, path = plug(line, 'color')
    time.sleep(10)
    assert os.path.isdir(path)
    assert emu.handshakes == 1, emu.events


def test_unplug_and_replug(line):
    emu, path = plug(line, 'gyro')
    t0 = time.monotonic()
    emu.unplug()
    assert wait_gone(path, 3.0)
    gone_after = time.monotonic() - t0
    assert gone_after < 1.5, 'devices removed only after %.2f s' % gone_after
    emu.plug()
    again = find_sensor(line.address, timeout=15)
    assert again
    assert read_attr(again, 'driver_name') == 'lego-ev3-gyro'


def test_mode_restored_after_reconnect(line):
    emu, path = plug(line, 'color')
    write_attr(path, 'mode', 'COL-COLOR')
    emu.unplug()
    assert wait_gone(path, 3.0)
    time.sleep(1.2)                  # long enough for the sensor's watchdog
    emu.plug()
    again = find_sensor(line.address, timeout=15)
    assert again
    deadline = time.monotonic() + 3
    while read_attr(again, 'mode') != 'COL-COLOR' and time.monotonic() < deadline:
        time.sleep(0.05)
    assert read_attr(again, 'mode') == 'COL-COLOR'


def test_hostile_sensor_survived(line):
    emu, path = plug(line, 'color', hostile=True)
    assert read_attr(path, 'driver_name') == 'lego-ev3-color'
    emu.set_values(0, [33])
    assert wait_value(path, 0, 33) == 33


def test_detach_with_files_open(line):
    emu, path = plug(line, 'color')
    f = open(os.path.join(path, 'value0'))
    g = open(os.path.join(path, 'mode'), 'r+')
    line.detach()
    assert wait_gone(path, 2.0)
    with pytest.raises(OSError) as e:
        f.seek(0)
        f.read()
    assert e.value.errno == errno.ENODEV
    with pytest.raises(OSError):
        g.seek(0)
        g.write('COL-AMBIENT')
        g.flush()
    f.close()
    try:
        g.close()
    except OSError:
        pass


def test_mode_that_silences_the_sensor_is_not_restored_forever(line):
    """IR-S-ALT makes the real sensor stop answering keep-alives: the host
    drops it, restores the mode once after the reconnect, and when that
    drops it again gives up, so the sensor comes back in its default mode."""
    emu, path = plug(line, 'ir')
    try:
        write_attr(path, 'mode', 'IR-S-ALT')
    except OSError as e:
        assert e.errno in (errno.ETIMEDOUT, errno.ENODEV)
    assert wait_gone(path, 3.0)
    deadline = time.monotonic() + 30
    found = None
    while time.monotonic() < deadline and not found:
        p = find_sensor(line.address, timeout=1)
        try:
            if p and read_attr(p, 'mode') == 'IR-PROX' and emu.handshakes >= 3:
                found = p
        except OSError:
            pass
    assert found, 'sensor never came back in IR-PROX (%d handshakes)' % emu.handshakes
    time.sleep(2)
    assert read_attr(found, 'mode') == 'IR-PROX'


def test_port_label_ioctl(line):
    import fcntl
    import termios
    SET, GET = 0x4010e301, 0x8010e302      # _IOW/_IOR(0xE3, 1/2, char[16])
    fcntl.ioctl(line.fd, SET, b'in3'.ljust(16, b'\0'))
    assert fcntl.ioctl(line.fd, GET, bytes(16)).rstrip(b'\0') == b'in3'
    for bad in (b'in 3', b'a:b', b'x' * 16):
        with pytest.raises(OSError) as e:
            fcntl.ioctl(line.fd, SET, bad.ljust(16, b'\0')[:16])
        assert e.value.errno == errno.EINVAL
    # termios ioctls still work with the discipline attached.
    assert termios.tcgetattr(line.fd)[4] == termios.B2400
    line.plug('color')
    path = find_sensor('ttyNM0:in3', timeout=15)
    assert path, 'no sensor with the labelled address'
    with open(os.path.join(path, 'uevent')) as f:
        assert 'LEGO_ADDRESS=ttyNM0:in3' in f.read().split('\n')
