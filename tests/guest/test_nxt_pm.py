"""USB runtime power management of the emulated brick and lego_nxt_usb.

lego_nxt_usb does not set supports_autosuspend in its struct usb_driver
and takes no runtime PM reference (usb_autopm_get_interface()): the USB
core keeps the interface of a bound brick runtime-active, with runtime PM
disabled, so that its device is never autosuspended, whatever userspace
allows in power/control (drivers/usb/core/driver.c, usb_probe_interface()
and autosuspend_check(): such interfaces are "permanently active"). The
driver's suspend(), resume() and reset_resume() run only in a system
sleep, which this VM cannot do (Documentation/lego/testing.rst).

What the tests show, with power/control "auto" and an autosuspend delay
of 0 on the brick's USB device: a bound brick stays active, with no file
open and with one, and keeps answering; and the same device with the
driver unbound is suspended (dummy_hcd suspends its port, the emulated
brick gets raw-gadget's suspend event), so that "stays active" is not
something this VM shows of every device. Binding the driver to the
suspended brick resumes it for the probe, and the brick answers through
its new node.
"""
import os
import time

import pytest

import nxtdev as nxt
from conftest import wait_for

SERIAL = '0016530B0A09'
VERSIONS_REPLY = b'\x02\x88\x00\x7c\x01\x1d\x01'
# How long an idle device with an autosuspend delay of 0 is watched: the
# USB core suspends one within milliseconds of its last use.
WATCH_S = 1.5


def power(dev, name):
    with open(os.path.join(dev, 'power', name)) as f:
        return f.read().strip()


def set_power(dev, name, value):
    with open(os.path.join(dev, 'power', name), 'w') as f:
        f.write(value)


@pytest.fixture
def autosuspend(brick):
    """The brick's USB device with autosuspend allowed after 0 ms; its
    settings are put back afterwards. Yields the device's sysfs directory."""
    dev = os.path.realpath(os.path.join(brick.interface(), '..'))
    saved = power(dev, 'control'), power(dev, 'autosuspend_delay_ms')
    set_power(dev, 'autosuspend_delay_ms', '0')
    set_power(dev, 'control', 'auto')
    yield dev
    set_power(dev, 'control', saved[0])
    set_power(dev, 'autosuspend_delay_ms', saved[1])
    assert wait_for(lambda: power(dev, 'runtime_status') == 'active'), \
        'the brick did not resume when autosuspend was forbidden again'


def emulator_events(brick, since):
    return [what for t, what in brick.emu.events if t >= since]


def stays_active(dev, seconds):
    """The runtime status of @dev, every 20 ms for @seconds: the first that
    is not "active", or "active"."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        status = power(dev, 'runtime_status')
        if status != 'active':
            return status
        time.sleep(0.02)
    return 'active'


def test_bound_brick_is_never_autosuspended(brick, autosuspend):
    dev = autosuspend
    t0 = time.monotonic()
    # No file open.
    assert stays_active(dev, WATCH_S) == 'active', \
        'the bound brick was autosuspended with no file open: if lego_nxt_usb ' \
        'now supports autosuspend, test_nxt_pm.py should test its suspend() ' \
        'and resume() through runtime PM'
    fd = brick.open()
    try:
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
        # A file open and idle.
        assert stays_active(dev, WATCH_S) == 'active', \
            'the bound brick was autosuspended with a file open'
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
    finally:
        os.close(fd)
    assert stays_active(dev, WATCH_S) == 'active', \
        'the bound brick was autosuspended after its file was closed'
    events = emulator_events(brick, t0)
    assert 'suspended' not in events, events


def test_unbound_brick_suspends_and_binding_resumes_it(brick, autosuspend):
    dev = autosuspend
    intf = brick.interface()
    name = os.path.basename(intf)
    t0 = time.monotonic()
    with open(os.path.join(nxt.DRIVER, 'unbind'), 'w') as f:
        f.write(name)
    try:
        assert wait_for(lambda: power(dev, 'runtime_status') == 'suspended', 5), \
            'the unbound brick was not autosuspended: runtime status %s' % \
            power(dev, 'runtime_status')
        assert wait_for(lambda: 'suspended' in emulator_events(brick, t0), 5), \
            'the emulated brick saw no suspend: %s' % emulator_events(brick, t0)
        assert not brick.emu.configured.is_set()
    finally:
        # Binding resumes the device for the probe.
        t1 = time.monotonic()
        with open(os.path.join(nxt.DRIVER, 'bind'), 'w') as f:
            f.write(name)
    brick.node = nxt.node_of(brick.serial)
    assert brick.node, 'no /dev/nxtN after binding the suspended brick'
    assert power(dev, 'runtime_status') == 'active'
    assert wait_for(lambda: 'resumed' in emulator_events(brick, t1), 5), \
        'the emulated brick saw no resume: %s' % emulator_events(brick, t1)
    fd = brick.open()
    try:
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
    finally:
        os.close(fd)
    assert stays_active(dev, WATCH_S) == 'active', \
        'the brick was autosuspended once the driver was bound again'
