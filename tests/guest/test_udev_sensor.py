"""The EV3 sensors' udev rules under systemd-udevd: what the group lego and
the user at the seat get.

systemd-udevd runs with tools/udev/70-lego-ev3-iio.rules and
90-lego-ev3-sensors.rules (in /run/udev/rules.d) and the group lego in a
private copy of /etc/group. An emulated gyro is plugged; then

 - the lego-sensor attributes userspace writes (mode, direct, command,
   poll_ms) and the IIO device's (mode, the buffer's enable and length,
   the channels' _en) belong to the group and are group-writable;
 - /dev/iio:deviceN is the group's, 0660, with the uaccess and seat tags;
 - a user (nobody) in the group changes the mode through both, and opens
   /dev/iio:deviceN; without the group it can do neither.
"""
import glob
import os
import re
import subprocess
import time

import pytest

import ev3
from conftest import run, udevd_with_rules, wait_for

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
RULES = ['70-lego-ev3-iio.rules', '90-lego-ev3-sensors.rules']
RULES_DIR = '/run/udev/rules.d'
WORK = '/tmp/lego-udev-sensor'
NOBODY = 65534


@pytest.fixture
def udevd(ev3_module):
    assert not subprocess.run(['pidof', 'systemd-udevd'], capture_output=True).stdout, \
        'a systemd-udevd is running already'
    with udevd_with_rules(WORK, RULES) as gid:
        yield gid


def for_group(path, gid):
    st = os.stat(path)
    return st.st_gid == gid and bool(st.st_mode & 0o020)


def as_nobody(groups, script):
    """Run a shell script as nobody with the supplementary groups given."""
    return subprocess.run(['setpriv', '--reuid=%d' % NOBODY, '--regid=%d' % NOBODY,
                           '--groups=' + (','.join(map(str, groups)) or str(NOBODY)),
                           'sh', '-c', script], capture_output=True, text=True, timeout=60)


def test_sensor_attributes_and_iio_node_for_group_and_seat(udevd):
    gid = udevd
    ln = ev3.Line(0)
    ln.attach()
    try:
        emu, path = ev3.plug(ln, 'gyro')
        assert ev3.wait_registered(ln.address, 1, timeout=60) is not False, 'gyro not published'
        iio = os.path.realpath(ev3.iio_device('lego-ev3-gyro', timeout=30) or '/nonexistent')
        assert os.path.isdir(iio), 'no IIO device for the gyro'
        node = '/dev/' + os.path.basename(iio)

        # The rules' RUN commands: udevd has run them once the node is done.
        attrs = [os.path.join(path, a) for a in ('mode', 'direct', 'command', 'poll_ms')]
        buffer = glob.glob(iio + '/buffer*/enable') + glob.glob(iio + '/buffer*/length')
        chans = glob.glob(iio + '/scan_elements/*_en') + glob.glob(iio + '/buffer0/*_en')
        assert buffer and chans, os.listdir(iio)
        attrs += [os.path.join(iio, 'mode')] + buffer + chans
        # udevd runs the rules' commands after the events, asynchronously:
        # a program started in this emulated (TCG, KASAN) machine takes a
        # second or more when the host is busy, and neither udevadm settle
        # (which does nothing in a chroot, as the tests run) nor
        # /run/udev/queue (gone before the event arrives) tell when they
        # are done. A rule that does not apply fails after the deadline.
        t0 = time.monotonic()
        done = wait_for(lambda: all(for_group(a, gid) for a in attrs), 180, interval=0.5)
        assert done, 'not for the group lego (%d) after %.0f s: %s' % (
            gid, time.monotonic() - t0,
            ['%s %d %o' % (a, os.stat(a).st_gid, os.stat(a).st_mode)
             for a in attrs if not for_group(a, gid)])
        assert wait_for(lambda: os.path.exists(node) and os.stat(node).st_gid == gid, 60), \
            'group of %s: not lego' % node
        for a in ('address', 'value0', 'modes'):
            assert not os.stat(os.path.join(path, a)).st_mode & 0o022, a

        assert os.stat(node).st_mode & 0o777 == 0o660, oct(os.stat(node).st_mode)
        props = run(['udevadm', 'info', '--query=property', '--name=' + node])
        tags = re.search(r'^TAGS=(.*)$', props, re.M)
        assert tags, props
        # uaccess, and seat: 71-seat.rules saw the tag, so it came early enough.
        assert {'uaccess', 'seat'} <= set(tags.group(1).strip(':').split(':')), props

        # A user in the group: mode through lego-sensor and IIO, the node.
        script = ('echo GYRO-RATE > %s/mode && echo GYRO-ANG > %s/mode && '
                  'exec 3<>%s' % (path, iio, node))
        r = as_nobody([gid], script)
        assert r.returncode == 0, r.stderr
        assert ev3.read_attr(path, 'mode') == 'GYRO-ANG'
        # Without the group: refused.
        for s in ('echo GYRO-RATE > %s/mode' % path, 'echo GYRO-RATE > %s/mode' % iio,
                  'exec 3<>%s' % node):
            r = as_nobody([], s)
            assert r.returncode != 0 and 'Permission denied' in r.stderr, (s, r.stderr)
        # Reading needs nothing.
        r = as_nobody([], 'cat %s/value0' % path)
        assert r.returncode == 0, r.stderr
    finally:
        ln.close()
