"""The Debian packages of `make deb`, installed in a private Debian root,
driving the test kernel: systemd-udevd, run in that root with the packaged
rules, loads the module DKMS built when the emulated brick is plugged in and
gives /dev/nxtN to the group lego, mode 0660, with the uaccess and seat tags.

`make check` builds the packages (`make deb`) and runs
tests/packaging/deb-prepare.sh on the host, which installs them with dpkg in
a root laid out by tests/packaging/debroot.py (DKMS compiles the modules for
the test kernel there) and leaves it unpacked beside its tar. The guest
chroots into that directory over 9p, with tmpfs on its /run and /tmp: dpkg
and DKMS, 60 to 160 times slower in the emulated guest than on the host, do
not run here. Installing, using and purging the packages is
tests/packaging/test_deb.py's, on the host.

  nice -n 15 tests/vm-run -- python3 -m pytest -p no:cacheprovider tests/guest/test_deb.py
"""
import os
import re
import signal
import subprocess
import sys

import pytest

from conftest import MODULES, UNLOAD, loaded, module_path, owned, pid_alive, run, unload, wait_for

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'emulator'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'packaging'))

import debroot  # noqa: E402

KVER = os.uname().release
SERIES = '.'.join(KVER.split('.')[:2])
SERIAL = '0016530D0E0F'


def build_dir():
    return os.path.dirname(os.environ.get('LEGO_BUILD', '/nonexistent'))


ROOT = debroot.unpacked(os.path.join(build_dir(), 'deb-root-%s.tar' % SERIES))


def chroot(cmd, **kw):
    try:
        return debroot.chroot(ROOT, cmd, **kw)
    except RuntimeError as e:
        pytest.fail(str(e))


@pytest.fixture(scope='module')
def state():
    """The root deb-prepare.sh left, with /run and /tmp of its own and the
    kernel's file systems; torn down (and vm-run's modules loaded again) at
    the end of the module."""
    if not os.path.isfile(os.path.join(ROOT, 'kernel-release')):
        pytest.fail('no root in %s: run `make deb DEB_OUT=%s/deb` and '
                    'tests/packaging/deb-prepare.sh "$(tests/kernel/build-kernel.sh '
                    '--tree-only %s)" %s/deb %s.tar on the host first (make check does)'
                    % (ROOT, build_dir(), SERIES, build_dir(), ROOT))
    with open(os.path.join(ROOT, 'kernel-release')) as f:
        assert f.read().strip() == KVER, 'the root is for another kernel'
    st = {'gid': debroot.group_gid(ROOT, 'lego')}
    assert st['gid'] is not None, 'postinst made no group lego'
    mounted, points = [], []
    try:
        for d in ('run', 'tmp'):
            run(['mount', '-t', 'tmpfs', '-o', 'mode=%s' % ('1777' if d == 'tmp' else '0755'),
                 'tmpfs', os.path.join(ROOT, d)])
            mounted.append(os.path.join(ROOT, d))
        points = debroot.mount(ROOT)
        unload(*UNLOAD)
        yield st
    finally:
        for pid in st.get('udevd', []):
            if pid_alive(pid):
                os.kill(pid, signal.SIGKILL)
        unload(*UNLOAD)
        debroot.umount(points)
        for path in reversed(mounted):
            subprocess.run(['umount', '-l', path])
        for name in MODULES:
            subprocess.run(['insmod', module_path(name)], check=True)


@pytest.fixture
def udevd(state):
    """systemd-udevd run in the root: its rules and /etc/group, its
    kmod loading from the root's /lib/modules."""
    before = set(subprocess.run(['pidof', 'systemd-udevd'], capture_output=True,
                                text=True).stdout.split())
    chroot(['/lib/systemd/systemd-udevd', '--daemon'])
    out = subprocess.run(['pidof', 'systemd-udevd'], capture_output=True, text=True).stdout
    pids = [int(p) for p in set(out.split()) - before]
    assert pids, 'systemd-udevd did not start'
    state['udevd'] = pids
    try:
        yield pids
    finally:
        for pid in pids:
            if pid_alive(pid):
                os.kill(pid, signal.SIGTERM)
        if not wait_for(lambda: not any(pid_alive(p) for p in pids), 20):
            for pid in pids:
                if pid_alive(pid):
                    os.kill(pid, signal.SIGKILL)


def test_brick_gets_group_lego_and_uaccess(state, udevd):
    import nxtdev
    import nxt_brick
    assert 'gid' in state, 'the packages are not installed'
    assert not loaded('lego_nxt_usb')
    emu = nxt_brick.RawGadgetBrick(udc='dummy_udc.0', serial=SERIAL)
    emu.start()
    try:
        assert emu.wait_configured(15), 'brick not configured'
        assert wait_for(lambda: loaded('lego_nxt_usb'), 30), \
            'plugging the brick did not load lego_nxt_usb'
        # The DKMS-built module, not the one of the test build.
        ko = '/lib/modules/%s/updates/dkms/lego_nxt_usb.ko' % KVER
        build_id = re.search(r'Build ID: ([0-9a-f]+)', chroot(['readelf', '-n', ko]))
        assert build_id, 'no build ID in ' + ko
        with open('/sys/module/lego_nxt_usb/notes/.note.gnu.build-id', 'rb') as f:
            assert f.read().hex().endswith(build_id.group(1)), \
                'the loaded lego_nxt_usb is not the one DKMS built'
        node = nxtdev.node_of(SERIAL, 15)
        assert node, 'no /dev/nxtN for the brick'
        # udevd changes the group and the mode in two calls: wait for both.
        assert wait_for(lambda: owned(node, state['gid']), 15), \
            '%s: group %d, mode %o; not lego (%d), 660' % (
                node, os.stat(node).st_gid, os.stat(node).st_mode & 0o777, state['gid'])
        link = '/dev/nxt/by-serial/' + SERIAL
        assert wait_for(lambda: os.path.realpath(link) == node, 15), link
        props = chroot(['udevadm', 'info', '--query=property', '--name=' + node])
        tags = re.search(r'^TAGS=(.*)$', props, re.M)
        assert tags, props
        # uaccess, and seat: 71-seat.rules saw the tag, so it came early enough.
        assert {'uaccess', 'seat'} <= set(tags.group(1).strip(':').split(':')), props
    finally:
        emu.unplug()
    assert wait_for(lambda: not nxtdev.interface_of(SERIAL), 15), 'the brick outlived its unplug'

