"""The EV3 driver built without its lego-sensor class (LEGO_EV3_CLASS=n out
of tree, LEGO_EV3_UART_CLASS=n in tree): each sensor is an IIO device only.
make check builds that module beside the test kernel's modules
($LEGO_BUILD-no-class); the test swaps it in for the usual one and back."""
import os
import subprocess
import time

import pytest

import ev3
from ev3 import iio_device, read_attr, wait_attr_int, write_attr
from kmsg import Kmsg

NO_CLASS = os.environ.get('LEGO_BUILD', '') + '-no-class/drivers/lego/ev3/lego_ev3_uart.ko'


@pytest.fixture
def no_class_module(ev3_module):
    """The module without the class loaded instead of the usual one (which
    the ev3_module fixture loads again after the test)."""
    if not os.path.exists(NO_CLASS):
        pytest.skip('no build without the lego-sensor class: %s (make check builds it)'
                    % NO_CLASS)
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    subprocess.run(['insmod', NO_CLASS], check=True)
    yield
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)


def test_a_sensor_is_an_iio_device_only(no_class_module):
    assert not os.path.exists('/sys/class/lego-sensor'), 'the class is registered'
    log = Kmsg()
    line = ev3.Line(0)
    line.attach()
    try:
        emu = line.plug('us')
        dev = iio_device('lego-ev3-us', timeout=15)
        assert dev, 'no IIO device: %s' % emu.events
        assert read_attr(dev, 'label') == 'ttyNM0'
        emu.set_values(0, [263])
        assert wait_attr_int(dev, 'in_distance0_raw', 263) == 263
        # The mode through IIO, confirmed by the sensor as with the class.
        write_attr(dev, 'mode', 'US-DIST-IN')
        emu.set_values(1, [104])
        assert wait_attr_int(dev, 'in_distance1_raw', 104) == 104
        assert read_attr(dev, 'mode') == 'US-DIST-IN'
        lines = [text for _, text in log.read()]
        assert any('ttyNM0: lego-ev3-us connected at 57600 baud' in t for t in lines), lines
        assert not any(' connected as ' in t for t in lines), lines
    finally:
        line.close()
    assert ev3.wait_gone(dev, 5), 'the IIO device outlived the line'
    log.close()


def test_lights_named_after_the_driver(no_class_module):
    """Without the class a SPIKE colour sensor's lights are named after its
    driver name, and still reach the device."""
    line = ev3.Line(0)
    line.attach()
    try:
        emu = line.plug('spike-color')
        assert iio_device('lego-spike-color', timeout=15), emu.events
        leds = ['/sys/class/leds/lego-spike-color:white:light-%d' % i for i in range(3)]
        deadline = time.monotonic() + 5
        while not all(os.path.isdir(d) for d in leds) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert all(os.path.isdir(d) for d in leds), os.listdir('/sys/class/leds')
        write_attr(leds[0], 'brightness', '25')
        deadline = time.monotonic() + 3
        while emu.lump_writes[-1:] != [(3, bytes([25, 0, 0, 0]))] and \
                time.monotonic() < deadline:
            time.sleep(0.02)
        assert emu.lump_writes[-1:] == [(3, bytes([25, 0, 0, 0]))]
    finally:
        line.close()
    assert ev3.wait_gone(leds[0], 5), 'the LED device outlived the line'
