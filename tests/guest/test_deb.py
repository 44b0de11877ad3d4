"""The Debian packages of `make deb`, installed, used and purged with dpkg
in a private Debian root in the test VM.

The guest's root (the host's, read-only over 9p) cannot take packages and
the test kernel has no overlayfs: tests/packaging/debroot.py lays out a
tmpfs root in which the directories that dpkg and the maintainer scripts
write are real and the rest are symlinks into the real root. `make check`
builds the packages (`make deb`) and runs tests/packaging/deb-prepare.sh on
the host, which installs lego-mindstorms-dkms in such a root with dpkg, so
that its postinst has DKMS compile the modules for the test kernel there
(a DKMS build in the emulated guest takes over ten minutes), and saves the
root. Here, in the guest:

 1. the saved root is unpacked into tmpfs: DKMS built and installed the
    modules for the test kernel (dkms status, modinfo, vermagic);
 2. dpkg -i installs lego-mindstorms-tools, lego-mindstorms-dev and
    python3-lego-nxt-linux: postinst makes the system group lego, the
    headers compile with `pkg-config --cflags lego-mindstorms`;
 3. systemd-udevd, run in that root with the packages' rules, loads the
    DKMS-built lego_nxt_usb when the emulated brick is plugged in and gives
    /dev/nxtN to the group lego, mode 0660, with the uaccess and seat tags;
 4. dpkg --purge of the four packages removes every file they installed
    and the modules DKMS built (the group lego stays, as Debian's system
    groups do).

  nice -n 15 tests/vm-run -- python3 -m pytest -p no:cacheprovider tests/guest/test_deb.py
"""
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import pytest

from conftest import loaded, module_path, owned, pid_alive, run, unload, wait_for

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'emulator'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'packaging'))

import debroot  # noqa: E402

KVER = os.uname().release
SERIES = '.'.join(KVER.split('.')[:2])
WORK = '/tmp/lego-deb'
ROOT = WORK + '/root'
SERIAL = '0016530D0E0F'
MODULES = ['lego_ev3_uart', 'lego_nxt_usb']
GUEST_PACKAGES = ['lego-mindstorms-tools', 'lego-mindstorms-dev', 'python3-lego-nxt-linux']
ALL_PACKAGES = ['lego-mindstorms-dkms'] + GUEST_PACKAGES
# What dpkg, its scripts and systemd-sysusers may leave after a purge.
LEFT_BY_DPKG = ('var/lib/dpkg/', 'var/log/', 'var/cache/', 'tmp/', 'run/', 'etc/group',
                'etc/gshadow', 'etc/.pwd.lock', 'etc/group-', 'etc/gshadow-',
                'etc/ld.so.cache', 'var/lib/systemd/')


def chroot(cmd, **kw):
    try:
        return debroot.chroot(ROOT, cmd, **kw)
    except RuntimeError as e:
        pytest.fail(str(e))


def build_dir():
    return os.path.dirname(os.environ.get('LEGO_BUILD', '/nonexistent'))


def prepared():
    tar = os.path.join(build_dir(), 'deb-root-%s.tar' % SERIES)
    debs = os.path.join(build_dir(), 'deb')
    if not os.path.isfile(tar) or not glob.glob(debs + '/*.deb'):
        pytest.fail('no %s or no packages in %s: run `make deb DEB_OUT=%s` and '
                    'tests/packaging/deb-prepare.sh "$(tests/kernel/build-kernel.sh '
                    '--tree-only %s)" %s %s on the host first (make check does)'
                    % (tar, debs, debs, SERIES, debs, tar))
    return tar, debs


def listing(root):
    """Every path in the root's own tmpfs (not the symlinked real root)."""
    out = set()
    dev = os.lstat(root).st_dev
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if os.lstat(os.path.join(d, x)).st_dev == dev]
        for n in dirs + files:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out


def group_gid(name):
    with open(os.path.join(ROOT, 'etc/group')) as f:
        for line in f:
            fields = line.rstrip('\n').split(':')
            if fields[0] == name:
                return int(fields[2])
    return None


def sys_gid_max():
    try:
        with open(os.path.join(ROOT, 'etc/login.defs')) as f:
            m = re.search(r'^\s*SYS_GID_MAX\s+(\d+)', f.read(), re.M)
            return int(m.group(1)) if m else 999
    except OSError:
        return 999


@pytest.fixture(scope='module')
def state():
    """The unpacked root with its mounts, torn down (and vm-run's modules
    loaded again) at the end of the module."""
    tar, debs = prepared()
    st = {'debs': debs}
    mounted, points = [], []
    made_fd = False
    try:
        os.makedirs(WORK, exist_ok=True)
        run(['mount', '-t', 'tmpfs', '-o', 'mode=0755', 'tmpfs', WORK])
        mounted.append(WORK)
        os.makedirs(ROOT)
        run(['mount', '-t', 'tmpfs', '-o', 'mode=0755', 'tmpfs', ROOT])
        mounted.append(ROOT)
        t0 = time.monotonic()
        debroot.restore(tar, ROOT)
        print('test_deb: %s unpacked in %.0f s' % (tar, time.monotonic() - t0))
        with open(os.path.join(ROOT, 'kernel-release')) as f:
            assert f.read().strip() == KVER, 'the saved root is for another kernel'
        st['before'] = listing(ROOT)
        # dkms uses <(...), which needs /dev/fd.
        if not os.path.exists('/dev/fd'):
            os.symlink('/proc/self/fd', '/dev/fd')
            made_fd = True
        points = debroot.mount(ROOT)
        unload('lego_nxt_usb', 'lego_ev3_uart')
        yield st
    finally:
        for pid in st.get('udevd', []):
            if pid_alive(pid):
                os.kill(pid, signal.SIGKILL)
        unload('lego_nxt_usb', 'lego_ev3_uart')
        debroot.umount(points)
        if made_fd:
            os.unlink('/dev/fd')
        for path in reversed(mounted):
            subprocess.run(['umount', '-l', path])
        for name in MODULES:
            subprocess.run(['insmod', module_path(name)], check=True)


def test_dkms_built_the_modules_for_the_test_kernel(state):
    out = chroot(['dpkg-query', '-W', '-f', '${Status}', 'lego-mindstorms-dkms'])
    assert out == 'install ok installed', out
    status = chroot(['dkms', 'status', '-m', 'lego-mindstorms'])
    assert re.search(r'lego-mindstorms/\S+, %s, \S+: installed' % re.escape(KVER), status), status
    for name in MODULES:
        ko = '/lib/modules/%s/updates/dkms/%s.ko' % (KVER, name)
        assert os.path.isfile(ROOT + '/usr' + ko), ko
        assert chroot(['modinfo', '-k', KVER, '-F', 'filename', name]).strip() == ko
        assert chroot(['modinfo', '-F', 'vermagic', ko]).split()[0] == KVER


def test_install_the_other_packages(state):
    names = []
    for pkg in GUEST_PACKAGES:
        deb = debroot.debs(state['debs'])[pkg]
        shutil.copy(deb, os.path.join(ROOT, 'tmp'))
        names.append('/tmp/' + os.path.basename(deb))
    chroot(['dpkg', '-i'] + names)
    for pkg in ALL_PACKAGES:
        out = chroot(['dpkg-query', '-W', '-f', '${Status}', pkg])
        assert out == 'install ok installed', (pkg, out)
    # dpkg -L now, for the purge test.
    state['files'] = {p: chroot(['dpkg', '-L', p]).split('\n') for p in ALL_PACKAGES}
    gid = group_gid('lego')
    assert gid is not None, 'postinst made no group lego'
    assert gid <= sys_gid_max(), 'lego has GID %d: not a system group' % gid
    state['gid'] = gid
    for path in ('/usr/bin/nxtctl', '/usr/sbin/lego-ev3-attach',
                 '/usr/lib/udev/rules.d/70-lego-nxt.rules',
                 '/usr/lib/udev/rules.d/70-lego-ev3-iio.rules',
                 '/usr/share/doc/lego-mindstorms-tools/README.md.gz',
                 '/usr/share/doc/lego-mindstorms-tools/ev3-attach.rst.gz',
                 '/usr/share/doc/lego-mindstorms-tools/examples/nxt-ioctl.c',
                 '/usr/share/doc/lego-mindstorms-tools/examples/Makefile',
                 '/usr/share/doc/python3-lego-nxt-linux/nxt-python.rst.gz',
                 '/usr/lib/sysusers.d/lego-mindstorms.conf',
                 '/usr/lib/python3/dist-packages/lego_nxt_linux/__init__.py'):
        assert path in state['files']['lego-mindstorms-tools'] + \
            state['files']['python3-lego-nxt-linux'], path
        assert os.path.isfile(ROOT + path), path
    assert not os.path.exists(ROOT + '/usr/include/linux/lego_nxt.h')
    # The wheel's RECORD names only what the package installed (debian/rules
    # drops nxt/backend, and its lines).
    records = glob.glob(ROOT + '/usr/lib/python3/dist-packages/lego_nxt_linux-*.dist-info/RECORD')
    assert len(records) == 1, records
    site = os.path.dirname(os.path.dirname(records[0]))
    with open(records[0]) as f:
        missing = [ln.split(',')[0] for ln in f if ln.strip()
                   and not os.path.isfile(os.path.join(site, ln.split(',')[0]))]
    assert not missing, 'in RECORD, not installed: %s' % missing


def test_packaged_example_builds_with_the_installed_headers(state):
    """The examples of lego-mindstorms-tools, copied out of /usr/share/doc,
    build against lego-mindstorms-dev's headers (pkg-config)."""
    assert 'files' in state, 'the packages are not installed'
    chroot(['rm', '-rf', '/tmp/ex'])
    chroot(['cp', '-r', '/usr/share/doc/lego-mindstorms-tools/examples', '/tmp/ex'])
    chroot(['make', '-C', '/tmp/ex', 'O=/tmp/ex/out', '/tmp/ex/out/nxt-ioctl'])
    assert os.access(os.path.join(ROOT, 'tmp/ex/out/nxt-ioctl'), os.X_OK)


def test_headers_compile_with_pkg_config(state):
    cflags = chroot(['pkg-config', '--cflags', 'lego-mindstorms']).split()
    assert cflags == ['-I/usr/include/lego-mindstorms'], cflags
    with open(os.path.join(ROOT, 'tmp/p.c'), 'w') as f:
        f.write('#include <stdio.h>\n#include <linux/lego_nxt.h>\n'
                '#include <linux/lego_ev3_uart.h>\n'
                'int main(void) { printf("%lu\\n", (unsigned long)sizeof(struct nxt_tone)); '
                'return 0; }\n')
    chroot(['cc', '-Wall', '-Werror'] + cflags + ['-o', '/tmp/p', '/tmp/p.c'])
    assert int(chroot(['/tmp/p'])) > 0


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


def test_purge_removes_everything(state):
    assert 'files' in state, 'the packages are not installed'
    unload('lego_nxt_usb', 'lego_ev3_uart')
    chroot(['dpkg', '--purge'] + ALL_PACKAGES)
    for pkg in ALL_PACKAGES:
        r = subprocess.run(['chroot', ROOT, 'dpkg-query', '-W', '-f', '${Status}', pkg],
                           capture_output=True, text=True, env={'PATH': debroot.PATH})
        assert r.returncode != 0 or 'not-installed' in r.stdout, (pkg, r.stdout)
    # Every file of the packages is gone; a directory only if the real root
    # does not have it too (/usr/bin, /usr/share/doc, ...).
    left = []
    for pkg, paths in state['files'].items():
        for p in paths:
            if not p or p == '/.':
                continue
            if os.path.isdir(p):
                continue
            if os.path.lexists(ROOT + p):
                left.append(p)
    assert not left, 'left by dpkg --purge: %s' % left
    # What DKMS made is gone too.
    assert not os.path.exists(ROOT + '/var/lib/dkms/lego-mindstorms')
    assert not glob.glob(ROOT + '/usr/lib/modules/%s/updates/**/*.ko*' % KVER, recursive=True)
    r = subprocess.run(['chroot', ROOT, 'modinfo', '-k', KVER, 'lego_nxt_usb'],
                       capture_output=True, text=True, env={'PATH': debroot.PATH})
    assert r.returncode != 0, r.stdout
    # Nothing new in the root since before the installation but dpkg's
    # records and the group.
    after = listing(ROOT)
    new = {p for p in after - state['before'] if not p.startswith(LEFT_BY_DPKG)}
    assert not new, 'left after the purge: %s' % sorted(new)
