"""python-ev3dev2 (from PyPI, unmodified) drives the emulated sensors.

The sensors get the port labels in1..in4 from the module parameter, and
the shipped udev rule's chmod is applied as udev would, since the test VM
has no udev."""
import os
import re
import subprocess
import time

import pytest

import ev3
from conftest import module_path
from ev3 import find_sensor

# Imported here, at collection, not while the emulated sensors run: in a
# slow emulated machine, compiling these modules holds the interpreter long
# enough for the emulators (threads of this process) to miss keep-alives.
from ev3dev2 import get_current_platform
from ev3dev2.sensor import INPUT_1, INPUT_2, INPUT_3, INPUT_4
from ev3dev2.sensor.lego import ColorSensor, GyroSensor, InfraredSensor, UltrasonicSensor

RULE = os.path.join(os.path.dirname(__file__), '..', '..', 'tools', 'udev',
                    '90-lego-ev3-sensors.rules')


def apply_udev_rule(path):
    """Run the chmod commands of the shipped rule for one sensor."""
    with open(RULE) as f:
        rule = f.read()
    for cmd in re.findall(r'RUN\+="(/bin/chmod [^"]*)"', rule):
        subprocess.run(cmd.replace('/sys%p', path).split(), check=True,
                       stderr=subprocess.DEVNULL)


@pytest.fixture
def four_sensors(ev3_module):
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    subprocess.run(['insmod', module_path('lego_ev3_uart'),
                    'port_labels=ttyNM0=in1,ttyNM2=in2,ttyNM4=in3,ttyNM6=in4'], check=True)
    lines, emus = [], []
    try:
        for pair, kind in enumerate(['color', 'us', 'gyro', 'ir']):
            ln = ev3.Line(pair)
            ln.attach()
            lines.append(ln)
            # Four emulators share one Python process in an emulated
            # machine: slow the gyro's 650 Hz stream and start them one
            # after the other, so that each still answers its keep-alives.
            emus.append(ln.plug(kind, period_scale=10))
            time.sleep(0.5)
        time.sleep(1.0)
        for pair, ln in enumerate(lines):
            address = '%s:in%d' % (ln.address, pair + 1)
            for attempt in range(3):
                path = find_sensor(address, timeout=20)
                assert path, 'sensor on in%d missing' % (pair + 1)
                try:
                    apply_udev_rule(path)
                    break
                except subprocess.CalledProcessError:
                    time.sleep(0.5)     # it reconnected under us: find it again
            else:
                pytest.fail('could not apply the udev rule to %s' % address)
        os.environ['FAKE_SYS'] = ''
        yield emus
    finally:
        for ln in lines:
            ln.close()
        subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
        subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)


def eventually(fn, want, timeout=3.0):
    deadline = time.monotonic() + timeout
    got = fn()
    while got != want and time.monotonic() < deadline:
        time.sleep(0.05)
        got = fn()
    return got


def test_python_ev3dev2(four_sensors):
    color, us, gyro, ir = four_sensors
    assert get_current_platform() == 'fake'

    cs = ColorSensor(INPUT_1)
    color.set_values(0, [37])
    assert eventually(lambda: cs.reflected_light_intensity, 37) == 37
    color.set_values(2, [5])
    assert eventually(lambda: cs.color, 5) == 5
    assert cs.color_name == 'Red'
    assert cs.mode == 'COL-COLOR'

    ultra = UltrasonicSensor(INPUT_2)
    us.set_values(0, [263])
    assert eventually(lambda: ultra.distance_centimeters, 26.3) == pytest.approx(26.3)

    gs = GyroSensor(INPUT_3)
    gyro.set_values(0, [90])
    assert eventually(lambda: gs.angle, 90) == 90
    gs.reset()
    assert eventually(lambda: gs.angle, 0) == 0
    assert b'\x11' in gyro.writes

    irs = InfraredSensor(INPUT_4)
    ir.set_values(0, [64])
    assert eventually(lambda: irs.proximity, 64) == 64
