"""The Debian packages of `make deb`, installed, used and purged with dpkg
in a private Debian root, on the host.

`make check` builds the packages (`make deb`) and runs
tests/packaging/deb-prepare.sh, which installs lego-mindstorms-dkms in a
root laid out by tests/packaging/debroot.py (the directories that dpkg and
the maintainer scripts write are real, the rest symlinks into the real
root), so that its postinst has DKMS compile the modules for the test
kernel, and saves that root as a tar file. Here, in a mount namespace of
this process's own (left at the end of the module):

 1. the saved root is unpacked into a tmpfs: DKMS built and installed the
    modules for the test kernel (modinfo, vermagic);
 2. dpkg -i installs lego-mindstorms-tools, lego-mindstorms-dev and
    python3-lego-nxt-linux: postinst makes the system group lego, the
    packaged example builds and the headers compile with
    `pkg-config --cflags lego-mindstorms`;
 3. dpkg --purge of the four packages removes every file they installed
    and the modules DKMS built (the group lego stays, as Debian's system
    groups do).

What needs the test kernel running (the DKMS-built module loaded by the
packaged udev rules when a brick is plugged in, the node's group and tags)
is tests/guest/test_deb.py's, in a root deb-prepare.sh leaves with every
package installed. Needs root:

  LEGO_DEB_ROOT=.build/deb-root-7.3.tar python3 -m pytest tests/packaging/test_deb.py
"""
import ctypes
import glob
import os
import re
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import debroot  # noqa: E402

PACKAGES = ['lego-mindstorms-tools', 'lego-mindstorms-dev', 'liblegonxt-dev',
            'python3-lego-nxt-linux']
ALL_PACKAGES = ['lego-mindstorms-dkms'] + PACKAGES
MODULES = ['lego_ev3_uart', 'lego_nxt', 'lego_nxt_usb', 'lego_nxt_serial']
# What dpkg, its scripts and systemd-sysusers may leave after a purge.
LEFT_BY_DPKG = ('var/lib/dpkg/', 'var/log/', 'var/cache/', 'tmp/', 'run/', 'etc/group',
                'etc/gshadow', 'etc/.pwd.lock', 'etc/group-', 'etc/gshadow-',
                'etc/ld.so.cache', 'var/lib/systemd/')
CLONE_NEWNS = 0x00020000


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert r.returncode == 0, '%s: exit %d\n%s%s' % (' '.join(cmd), r.returncode,
                                                     r.stdout[-3000:], r.stderr[-3000:])
    return r.stdout


def listing(root):
    """Every path in the root's own tmpfs (not the mounts in it)."""
    out = set()
    dev = os.lstat(root).st_dev
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if os.lstat(os.path.join(d, x)).st_dev == dev]
        for n in dirs + files:
            out.add(os.path.relpath(os.path.join(d, n), root))
    return out


def sys_gid_max(root):
    try:
        with open(os.path.join(root, 'etc/login.defs')) as f:
            m = re.search(r'^\s*SYS_GID_MAX\s+(\d+)', f.read(), re.M)
            return int(m.group(1)) if m else 999
    except OSError:
        return 999


class Root:
    """The unpacked root: its path, kernel release and the package files."""

    def __init__(self, path, debs):
        self.path = path
        self.debs = debs
        with open(os.path.join(path, 'kernel-release')) as f:
            self.kver = f.read().strip()
        self.files = {}

    def chroot(self, cmd, check=True):
        if check:
            try:
                return debroot.chroot(self.path, cmd)
            except RuntimeError as e:
                pytest.fail(str(e))
        return subprocess.run(['chroot', self.path] + cmd, capture_output=True, text=True,
                              env={'PATH': debroot.PATH})


@pytest.fixture(scope='module')
def root(tmp_path_factory):
    tar = os.environ.get('LEGO_DEB_ROOT')
    if not tar:
        pytest.skip('LEGO_DEB_ROOT is not set: make check sets it to the root that '
                    'tests/packaging/deb-prepare.sh saved')
    debs = os.path.join(os.path.dirname(tar), 'deb')
    if not os.path.isfile(tar) or not glob.glob(debs + '/*.deb'):
        pytest.fail('no %s or no packages in %s: run `make deb DEB_OUT=%s` and '
                    'tests/packaging/deb-prepare.sh KDIR %s %s first (make check does)'
                    % (tar, debs, debs, debs, tar))
    if os.geteuid() != 0:
        pytest.fail('needs root (a mount namespace, chroot, dpkg)')
    libc = ctypes.CDLL(None, use_errno=True)
    old = os.open('/proc/self/ns/mnt', os.O_RDONLY)
    path = str(tmp_path_factory.mktemp('deb') / 'root')
    os.makedirs(path)
    points = []
    try:
        assert libc.unshare(CLONE_NEWNS) == 0, os.strerror(ctypes.get_errno())
        run(['mount', '--make-rprivate', '/'])
        run(['mount', '-t', 'tmpfs', '-o', 'mode=0755', 'tmpfs', path])
        debroot.restore(tar, path)
        r = Root(path, debs)
        r.before = listing(path)
        # dkms uses <(...), which needs /dev/fd.
        assert os.path.exists('/dev/fd')
        points = debroot.mount(path)
        yield r
    finally:
        debroot.umount(points)
        subprocess.run(['umount', '-l', path])
        # Back to the namespace of the other tests.
        assert libc.setns(old, CLONE_NEWNS) == 0, os.strerror(ctypes.get_errno())
        os.close(old)


def test_dkms_built_the_modules_for_the_test_kernel(root):
    out = root.chroot(['dpkg-query', '-W', '-f', '${Status}', 'lego-mindstorms-dkms'])
    assert out == 'install ok installed', out
    status = root.chroot(['dkms', 'status', '-m', 'lego-mindstorms'])
    assert re.search(r'lego-mindstorms/\S+, %s, \S+: installed' % re.escape(root.kver),
                     status), status
    for name in MODULES:
        ko = '/lib/modules/%s/updates/dkms/%s.ko' % (root.kver, name)
        assert os.path.isfile(root.path + '/usr' + ko), ko
        assert root.chroot(['modinfo', '-k', root.kver, '-F', 'filename', name]).strip() == ko
        assert root.chroot(['modinfo', '-F', 'vermagic', ko]).split()[0] == root.kver


def test_install_the_other_packages(root):
    try:
        debroot.install(root.path, root.debs, PACKAGES)
    except RuntimeError as e:
        pytest.fail(str(e))
    for pkg in ALL_PACKAGES:
        out = root.chroot(['dpkg-query', '-W', '-f', '${Status}', pkg])
        assert out == 'install ok installed', (pkg, out)
    # dpkg -L now, for the purge test.
    root.files = {p: root.chroot(['dpkg', '-L', p]).split('\n') for p in ALL_PACKAGES}
    gid = debroot.group_gid(root.path, 'lego')
    assert gid is not None, 'postinst made no group lego'
    assert gid <= sys_gid_max(root.path), 'lego has GID %d: not a system group' % gid
    for path in ('/usr/bin/nxtctl', '/usr/sbin/lego-ev3-attach',
                 '/usr/lib/udev/rules.d/70-lego-nxt.rules',
                 '/usr/lib/udev/rules.d/70-lego-ev3-iio.rules',
                 '/usr/lib/udev/rules.d/90-lego-ev3-iiod.rules',
                 '/usr/share/doc/lego-mindstorms-tools/README.md.gz',
                 '/usr/share/doc/lego-mindstorms-tools/ev3-attach.rst.gz',
                 '/usr/share/doc/lego-mindstorms-tools/examples/nxt-ioctl.c',
                 '/usr/share/doc/lego-mindstorms-tools/examples/Makefile',
                 '/usr/share/doc/python3-lego-nxt-linux/nxt-python.rst.gz',
                 '/usr/lib/sysusers.d/lego-mindstorms.conf',
                 '/usr/lib/python3/dist-packages/lego_nxt_linux/__init__.py'):
        assert path in root.files['lego-mindstorms-tools'] + \
            root.files['python3-lego-nxt-linux'], path
        assert os.path.isfile(root.path + path), path
    assert not os.path.exists(root.path + '/usr/include/linux/lego_nxt.h')
    # The wheel's RECORD names only what the package installed (debian/rules
    # drops nxt/backend, and its lines).
    records = glob.glob(root.path +
                        '/usr/lib/python3/dist-packages/lego_nxt_linux-*.dist-info/RECORD')
    assert len(records) == 1, records
    site = os.path.dirname(os.path.dirname(records[0]))
    with open(records[0]) as f:
        missing = [ln.split(',')[0] for ln in f if ln.strip()
                   and not os.path.isfile(os.path.join(site, ln.split(',')[0]))]
    assert not missing, 'in RECORD, not installed: %s' % missing


def test_packaged_example_builds_with_the_installed_headers(root):
    """The examples of lego-mindstorms-tools, copied out of /usr/share/doc,
    build against lego-mindstorms-dev's headers and liblegonxt-dev's
    library (pkg-config)."""
    assert root.files, 'the packages are not installed'
    root.chroot(['rm', '-rf', '/tmp/ex'])
    root.chroot(['cp', '-r', '/usr/share/doc/lego-mindstorms-tools/examples', '/tmp/ex'])
    root.chroot(['make', '-C', '/tmp/ex', 'O=/tmp/ex/out', '/tmp/ex/out/nxt-ioctl'])
    assert os.access(os.path.join(root.path, 'tmp/ex/out/nxt-ioctl'), os.X_OK)
    # Linked with the packaged library: its symbols are in the program.
    nm = subprocess.run(['nm', os.path.join(root.path, 'tmp/ex/out/nxt-ioctl')],
                        capture_output=True, text=True, check=True).stdout
    assert ' T lnxt_reply_check' in nm


def test_headers_compile_with_pkg_config(root):
    assert root.files, 'the packages are not installed'
    cflags = root.chroot(['pkg-config', '--cflags', 'lego-mindstorms']).split()
    assert cflags == ['-I/usr/include/lego-mindstorms'], cflags
    with open(os.path.join(root.path, 'tmp/p.c'), 'w') as f:
        f.write('#include <stdio.h>\n#include <linux/lego_nxt.h>\n'
                '#include <linux/lego_ev3_uart.h>\n'
                'int main(void) { printf("%lu\\n", (unsigned long)sizeof(struct nxt_transaction)); '
                'return 0; }\n')
    root.chroot(['cc', '-Wall', '-Werror'] + cflags + ['-o', '/tmp/p', '/tmp/p.c'])
    assert int(root.chroot(['/tmp/p'])) > 0


def test_purge_removes_everything(root):
    assert root.files, 'the packages are not installed'
    root.chroot(['dpkg', '--purge'] + ALL_PACKAGES)
    for pkg in ALL_PACKAGES:
        r = root.chroot(['dpkg-query', '-W', '-f', '${Status}', pkg], check=False)
        assert r.returncode != 0 or 'not-installed' in r.stdout, (pkg, r.stdout)
    # Every file of the packages is gone; a directory only if the real root
    # does not have it too (/usr/bin, /usr/share/doc, ...).
    left = []
    for paths in root.files.values():
        for p in paths:
            if not p or p == '/.' or os.path.isdir(p):
                continue
            if os.path.lexists(root.path + p):
                left.append(p)
    assert not left, 'left by dpkg --purge: %s' % left
    # What DKMS made is gone too.
    assert not os.path.exists(root.path + '/var/lib/dkms/lego-mindstorms')
    assert not glob.glob(root.path + '/usr/lib/modules/%s/updates/**/*.ko*' % root.kver,
                         recursive=True)
    r = root.chroot(['modinfo', '-k', root.kver, 'lego_nxt_usb'], check=False)
    assert r.returncode != 0, r.stdout
    # Nothing new in the root since before the installation but dpkg's
    # records and the group (and the files the tests above made in /tmp).
    new = {p for p in listing(root.path) - root.before if not p.startswith(LEFT_BY_DPKG)}
    assert not new, 'left after the purge: %s' % sorted(new)
