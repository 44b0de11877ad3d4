"""USB runtime power management of the emulated brick and lego_nxt_usb.

lego_nxt_usb supports autosuspend: it takes a runtime PM reference
(usb_autopm_get_interface()) when the first file is opened and drops it
when the last is closed, when it also stops collecting replies. With
power/control "auto", a bound brick with no file open is suspended after
its autosuspend delay, and opening it resumes it (the firmware clears its
"configured" state on suspend and sets it again on resume, and has no
remote wakeup: research nxt.md). The driver's system-sleep callbacks are
not run here: this VM cannot sleep (Documentation/lego/testing.rst).

What the tests show, with power/control "auto" and an autosuspend delay
of 0 on the brick's USB device: an idle bound brick is suspended (dummy_hcd
suspends its port, the emulated brick gets raw-gadget's suspend event);
open() resumes it and it stays active, answering, while a file is open;
the last close lets it suspend again. Unbinding and binding the driver of
a suspended brick resumes it for the probe, and the brick answers through
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


def suspended(dev, timeout=5):
    return wait_for(lambda: power(dev, 'runtime_status') == 'suspended', timeout)


def test_open_file_keeps_the_brick_awake_and_idle_lets_it_sleep(brick, autosuspend):
    dev = autosuspend
    # The fixture allowed it: the brick may have suspended before this runs.
    assert suspended(dev), 'the idle bound brick was not autosuspended: runtime status %s' % \
        power(dev, 'runtime_status')
    assert wait_for(lambda: 'suspended' in emulator_events(brick, 0), 5), \
        'the emulated brick saw no suspend: %s' % emulator_events(brick, 0)
    t1 = time.monotonic()
    fd = brick.open()
    try:
        # open() returns with the brick resumed and its replies collected.
        assert power(dev, 'runtime_status') == 'active'
        assert 'resumed' in emulator_events(brick, t1), emulator_events(brick, t1)
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
        # A file open and idle.
        assert stays_active(dev, WATCH_S) == 'active', \
            'the brick was autosuspended with a file open'
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
        # A second file, closed: the first still holds the brick awake.
        os.close(brick.open())
        assert stays_active(dev, WATCH_S) == 'active', \
            'the brick was autosuspended when one of two files was closed'
    finally:
        t2 = time.monotonic()
        os.close(fd)
    assert suspended(dev), 'the brick was not autosuspended after its last file was closed'
    assert wait_for(lambda: 'suspended' in emulator_events(brick, t2), 5)


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
    assert wait_for(lambda: 'resumed' in emulator_events(brick, t1), 5), \
        'the emulated brick saw no resume: %s' % emulator_events(brick, t1)
    fd = brick.open()
    try:
        assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)
    finally:
        os.close(fd)
    assert suspended(dev), 'the brick was not autosuspended once idle again'
