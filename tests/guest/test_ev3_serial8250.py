"""EV3 sensors on a real 8250 UART.

tests/vm-run gives the test VM two more 16550A ports, ttyS1 and ttyS2, joined
through QEMU by a unix socket (the console stays on ttyS0). The discipline is
attached to ttyS1, the emulator plays the sensor on ttyS2. The socket carries
bytes but no baud rate: the emulator reads ttyS1's speed with tcgetattr and
garbles what it sends while the two speeds differ, as a wire would.
"""
import os
import termios
import time

import pytest

from ev3 import (SerialLine, find_sensor, plug, read_attr, serial_pair, wait_gone, wait_handshakes,
                 wait_value, write_attr)

PAIR = serial_pair()

pytestmark = pytest.mark.skipif(
    'LEGO_SERIAL_PAIR' in os.environ and not PAIR,
    reason='the VM was started with --no-serial-pair')


@pytest.fixture
def sline(ev3_module):
    assert len(PAIR) == 2, 'LEGO_SERIAL_PAIR not set: start the VM with tests/vm-run'
    ln = SerialLine(*PAIR)
    ln.attach()
    yield ln
    ln.close()
    assert not find_sensor(ln.address, timeout=0.1), 'sensor left behind after detach'


def wait_speed(ln, baud, timeout=3.0):
    deadline = time.monotonic() + timeout
    while ln.speed() != baud and time.monotonic() < deadline:
        time.sleep(0.02)
    return ln.speed()


def test_ports_are_16550a_and_console_stays_on_ttyS0():
    assert len(PAIR) == 2, 'LEGO_SERIAL_PAIR not set: start the VM with tests/vm-run'
    for name in PAIR:
        # 4 is PORT_16550A in the serial core's numbering.
        assert read_attr('/sys/class/tty/' + name, 'type') == '4', name
    # tests/vm-run --arch arm64 has its console on the PL011 (LEGO_CONSOLE).
    console = os.environ.get('LEGO_CONSOLE', 'ttyS0')
    assert read_attr('/sys/class/tty/console', 'active').split()[-1] == console


@pytest.mark.parametrize('kind', ['color', 'gyro'])
def test_sensor_on_8250(sline, kind):
    emu, path = plug(sline, kind)
    sdef = emu.sdef
    assert read_attr(path, 'driver_name') == sdef.driver
    assert read_attr(path, 'address') == sline.address
    assert os.path.realpath(os.path.join(path, 'device')).endswith('/' + sline.address)
    # The discipline switched the UART to the sensor's speed.
    assert wait_speed(sline, 57600) == 57600

    emu.set_values(0, [42])
    assert wait_value(path, 0, 42) == 42

    # A mode switch: SELECT goes out at 57600 and is confirmed.
    new = 3 if kind == 'color' else 1      # REF-RAW (2 values), GYRO-RATE
    m = sdef.modes[new]
    values = [123, 456][:m.n]
    emu.set_values(new, values)
    write_attr(path, 'mode', m.name)
    assert read_attr(path, 'mode') == m.name
    for k, v in enumerate(values):
        assert wait_value(path, k, v) == v

    # Unplug: the sensor goes away and the UART back to 2400 baud.
    emu.unplug()
    assert wait_gone(path, 3.0)
    assert wait_speed(sline, 2400) == 2400
    # Replug: a new handshake at 2400, the speed switch again, the chosen
    # mode restored.
    emu.plug()
    again = find_sensor(sline.address, timeout=15)
    assert again, emu.events
    assert wait_handshakes(emu, 2) == 2, emu.events
    assert wait_speed(sline, 57600) == 57600
    deadline = time.monotonic() + 3
    while read_attr(again, 'mode') != m.name and time.monotonic() < deadline:
        time.sleep(0.05)
    assert read_attr(again, 'mode') == m.name
    emu.set_values(new, [v + 1 for v in values])
    for k, v in enumerate(values):
        assert wait_value(again, k, v + 1) == v + 1


def test_speed_mismatch_garbles_the_line(sline):
    """The line is only as good as the speeds on both ends: set the host end
    to 9600 behind the discipline's back and the sensor's DATA turns into
    garbage, the discipline drops the sensor and (back at 2400) connects it
    again once the sensor has reset."""
    emu, path = plug(sline, 'gyro')
    assert wait_speed(sline, 57600) == 57600
    attrs = termios.tcgetattr(sline.fd)
    attrs[4] = attrs[5] = termios.B9600
    termios.tcsetattr(sline.fd, termios.TCSANOW, attrs)
    assert wait_gone(path, 3.0), 'the sensor stayed although its data was garbled'
    assert emu.garbled > 0
    again = find_sensor(sline.address, timeout=15)
    assert again, emu.events
    assert wait_handshakes(emu, 2) == 2, emu.events
    assert wait_speed(sline, 57600) == 57600
    emu.set_values(0, [-17])
    assert wait_value(again, 0, -17) == -17
