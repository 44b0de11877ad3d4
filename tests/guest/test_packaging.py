"""Packaging: the drivers through DKMS, and loaded on demand.

Runs in the test VM against the test kernel, in a private setup that hides
the host's files: tmpfs over /lib/modules, /var/lib/dkms and /usr/src, with
/lib/modules/$(uname -r)/build pointing at the test kernel's tree.

 1. dkms add, build and install, run on the host by
    tests/packaging/dkms-prepare.sh (`make check` does it; a dkms build in
    the emulated guest had not finished after 14 minutes; on the host it
    takes 8 s)
    into $LEGO_BUILD/../dkms-SERIES: the guest copies its /var/lib/dkms,
    /usr/src and /lib/modules into tmpfs at their places, and checks that
    the modules are in updates/dkms, that modinfo and modprobe find them
    there;
 2. with lego_ev3_uart unloaded, TIOCSETD 29 on a pty makes the kernel load
    it (request_module("tty-ldisc-29") through /proc/sys/kernel/modprobe);
 3. with lego_nxt_usb unloaded, plugging the emulated brick makes udevd
    load it by its modalias, and tools/udev/70-lego-nxt.rules gives
    /dev/nxtN to the group lego, with the by-serial link;
dkms status and dkms remove on the test kernel's tree are
tests/packaging/test_install.py's, on the host.

The modules that vm-run loaded are unloaded first and loaded again from
$LEGO_MODULES at the end, so later tests see the usual setup.
"""
import fcntl
import glob
import os
import re
import subprocess
import sys

import pytest

from conftest import (MODULES, UNLOAD, loaded, module_path, owned, run, udevd_with_rules,
                      unload, wait_for)

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
KVER = os.uname().release
NAME = 'lego-mindstorms'
WORK = '/tmp/lego-packaging'
TIOCSETD = 0x5423
N_LEGOEV3 = 29
N_LEGONXT = 8
SERIAL = '0016530A0B0C'


def version():
    with open(os.path.join(TOP, 'dkms.conf')) as f:
        return re.search(r'^PACKAGE_VERSION="([^"]+)"', f.read(), re.M).group(1)


def prepared():
    """The host-side dkms result for the running kernel."""
    series = '.'.join(KVER.split('.')[:2])
    out = os.path.join(os.path.dirname(os.environ.get('LEGO_BUILD', '/nonexistent')),
                       'dkms-' + series)
    try:
        with open(os.path.join(out, 'kernel-release')) as f:
            ok = f.read().strip() == KVER
    except OSError:
        ok = False
    if not ok:
        pytest.fail('no dkms build for %s in %s: run tests/packaging/dkms-prepare.sh '
                    '"$(tests/kernel/build-kernel.sh --tree-only %s)" %s on the host first '
                    '(make check does)' % (KVER, out, series, out))
    return out


def mount_tmpfs(path, mounted):
    os.makedirs(path, exist_ok=True)
    run(['mount', '-t', 'tmpfs', '-o', 'mode=0755', 'tmpfs', path])
    mounted.append(path)


@pytest.fixture(scope='module')
def dkms_setup():
    """The private tmpfs setup, torn down (and vm-run's modules reloaded) at
    the end of the module."""
    out = prepared()
    mounted = []
    made_fd = False
    old_modprobe = open('/proc/sys/kernel/modprobe').read().strip()
    try:
        for path, copy in (('/lib/modules', 'modules'), ('/var/lib/dkms', 'dkms'),
                           ('/usr/src', 'src')):
            mount_tmpfs(path, mounted)
            run(['cp', '-a', os.path.join(out, copy) + '/.', path])
        mount_tmpfs(WORK, mounted)
        # dkms uses <(...), which needs /dev/fd (made by udev or systemd on
        # a real system, not by the VM's devtmpfs).
        if not os.path.exists('/dev/fd'):
            os.symlink('/proc/self/fd', '/dev/fd')
            made_fd = True
        moddir = '/lib/modules/' + KVER
        assert os.path.isfile(os.readlink(moddir + '/build') + '/Makefile')
        unload(*UNLOAD)
        yield moddir
    finally:
        with open('/proc/sys/kernel/modprobe', 'w') as f:
            f.write(old_modprobe)
        unload(*UNLOAD)
        if made_fd:
            os.unlink('/dev/fd')
        for path in reversed(mounted):
            subprocess.run(['umount', '-l', path])
        for name in MODULES:
            subprocess.run(['insmod', module_path(name)], check=True)


@pytest.fixture(scope='module')
def installed(dkms_setup):
    """The drivers as dkms installed them (on the host, see the top)."""
    src = '/usr/src/%s-%s' % (NAME, version())
    assert os.path.isfile(src + '/dkms.conf')
    assert not os.path.exists(src + '/tests'), 'the DKMS sources include the tests'
    return dkms_setup


def test_dkms_installs_to_updates_dkms(installed):
    for name in MODULES:
        ko = '%s/updates/dkms/%s.ko' % (installed, name)
        assert os.path.isfile(ko), ko
        info = run(['modinfo', '-k', KVER, '-F', 'filename', name]).strip()
        assert info == ko
        assert run(['modinfo', '-F', 'vermagic', ko]).split()[0] == KVER
    # No test-only module was installed.
    kos = sorted(os.path.basename(p) for p in glob.glob(installed + '/updates/**/*.ko',
                                                          recursive=True))
    assert kos == sorted(n + '.ko' for n in MODULES)
    # dkms status, and dkms remove, on the same kernel tree:
    # tests/packaging/test_install.py's, on the host (dkms, a bash script
    # that forks hundreds of times, took 21 s here to print its status).


def test_modprobe_loads_the_dkms_copy(installed):
    assert not loaded('lego_ev3_uart')
    out = run(['modprobe', '-v', 'lego_ev3_uart'])
    assert '%s/updates/dkms/lego_ev3_uart.ko' % installed in out, out
    assert loaded('lego_ev3_uart')
    run(['modprobe', '-r', 'lego_ev3_uart'])
    assert not loaded('lego_ev3_uart')


@pytest.fixture
def kernel_modprobe(installed):
    """/proc/sys/kernel/modprobe pointing at the host's modprobe, logging.

    The kernel runs it with the root of PID 1, the initramfs of the test VM,
    where the tests' root (the host's) is /host: a wrapper there chroots."""
    log = os.path.join(WORK, 'modprobe.log')
    wrapper = os.path.join(WORK, 'modprobe')
    chroot = '/host' if os.path.isdir('/proc/1/root/host' + WORK) else ''
    with open(wrapper, 'w') as f:
        f.write('#!/bin/sh\n'
                'PATH=/bin:/sbin:/usr/bin:/usr/sbin\n'
                'echo "$@" >> %s\n' % (chroot + log))
        if chroot:
            f.write('exec chroot %s /sbin/modprobe "$@"\n' % chroot)
        else:
            f.write('exec /sbin/modprobe "$@"\n')
    os.chmod(wrapper, 0o755)
    with open('/proc/sys/kernel/modprobe', 'w') as f:
        f.write(chroot + wrapper)
    yield log


def ldisc_loads(log, number, module, also=()):
    """TIOCSETD `number` on a pty makes the kernel load `module` (and
    `also`) through modprobe's alias tty-ldisc-N; the modules go after."""
    master, slave = os.openpty()
    try:
        fcntl.ioctl(slave, TIOCSETD, number.to_bytes(4, 'little'))
        for m in (module,) + also:
            assert loaded(m), 'TIOCSETD %d did not load %s' % (number, m)
        fcntl.ioctl(slave, TIOCSETD, (0).to_bytes(4, 'little'))    # back to N_TTY
    finally:
        os.close(slave)
        os.close(master)
    with open(log) as f:
        calls = f.read()
    assert 'tty-ldisc-%d' % number in calls, calls
    run(['rmmod', module] + list(also))


def test_ldisc_29_loads_lego_ev3_uart(kernel_modprobe):
    assert not loaded('lego_ev3_uart')
    ldisc_loads(kernel_modprobe, N_LEGOEV3, 'lego_ev3_uart')


def test_ldisc_8_loads_lego_nxt_serial(kernel_modprobe):
    """N_LEGONXT: the NXT's serial transport, with the core it uses."""
    unload('lego_nxt_serial', 'lego_nxt_usb', 'lego_nxt')
    ldisc_loads(kernel_modprobe, N_LEGONXT, 'lego_nxt_serial', ('lego_nxt',))


@pytest.fixture
def udevd(installed):
    """systemd-udevd with tools/udev/70-lego-nxt.rules and a group lego;
    its state in /run (a tmpfs in the guest). Yields the group's GID."""
    with udevd_with_rules(WORK, ['70-lego-nxt.rules']) as gid:
        yield gid


def test_brick_plug_loads_lego_nxt_usb_and_udev_rule(udevd):
    import nxtdev
    import nxt_brick
    unload('lego_nxt_usb')
    emu = nxt_brick.RawGadgetBrick(udc='dummy_udc.0', serial=SERIAL)
    link = '/dev/nxt/by-serial/' + SERIAL
    emu.start()
    try:
        assert emu.wait_configured(15), 'brick not configured'
        assert wait_for(lambda: loaded('lego_nxt_usb'), 30), \
            'plugging the brick did not load lego_nxt_usb'
        node = nxtdev.node_of(SERIAL, 15)
        assert node, 'no /dev/nxtN for the brick'
        assert wait_for(lambda: os.path.exists(link), 15), link + ' missing'
        assert os.path.realpath(link) == node
        # udevd changes the group and the mode in two calls: wait for both.
        assert wait_for(lambda: owned(node, udevd), 15), \
            '%s: group %d, mode %o; not lego (%d), 660' % (
                node, os.stat(node).st_gid, os.stat(node).st_mode & 0o777, udevd)
    finally:
        emu.unplug()
    assert wait_for(lambda: not nxtdev.interface_of(SERIAL), 15), 'the brick outlived its unplug'
    assert wait_for(lambda: not os.path.lexists(link), 15), link + ' left behind'

