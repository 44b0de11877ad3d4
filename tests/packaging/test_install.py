"""`make install DESTDIR=...` and `make uninstall` (host side, no VM).

Runs on a copy of the checkout (the build writes objects next to the
sources), against the test kernel's tree when it is built, otherwise the
running kernel's headers:

  python3 -m pytest -v tests/packaging
"""
import glob
import os
import re
import shutil
import subprocess

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))


def kdir():
    tree = os.environ.get('LEGO_KERNEL_TREE')
    if tree:
        return tree
    r = subprocess.run([os.path.join(TOP, 'tests/kernel/build-kernel.sh'), '--tree-only', 'newest'],
                       capture_output=True, text=True)
    if r.returncode == 0 and r.stdout.strip():
        return r.stdout.strip()
    build = '/lib/modules/%s/build' % os.uname().release
    if os.path.isdir(build):
        return build
    pytest.skip('no kernel tree: build the test kernel or install the headers')


def make(src, *args):
    r = subprocess.run(['make', '-C', src] + list(args), capture_output=True, text=True)
    assert r.returncode == 0, 'make %s: exit %d\n%s%s' % (' '.join(args), r.returncode,
                                                          r.stdout[-3000:], r.stderr[-3000:])
    return r.stdout + r.stderr


def listing(root):
    files = set()
    for d, _, names in os.walk(root):
        for n in names:
            files.add(os.path.relpath(os.path.join(d, n), root))
    return files


@pytest.fixture(scope='module')
def src(tmp_path_factory):
    dst = str(tmp_path_factory.mktemp('src') / 'lego')
    shutil.copytree(TOP, dst, symlinks=True, ignore=shutil.ignore_patterns(
        '.git', '.build', '*.o', '*.ko', '*.mod', '*.mod.c', '.*.cmd', 'modules.order',
        'Module.symvers', '__pycache__', '.pytest_cache'))
    return dst


@pytest.fixture(scope='module')
def tree():
    return kdir()


def dkms_version(src):
    with open(os.path.join(src, 'dkms.conf')) as f:
        return re.search(r'^PACKAGE_VERSION="([^"]+)"', f.read(), re.M).group(1)


def krelease(tree):
    with open(os.path.join(tree, 'include/generated/utsrelease.h')) as f:
        return re.search(r'UTS_RELEASE "([^"]+)"', f.read()).group(1)


def expected(tree, prefix, udevdir, unitdir, sysusersdir, src):
    kver = krelease(tree)
    exp = {
        'lib/modules/%s/updates/drivers/lego/ev3/lego_ev3_uart.ko' % kver,
        'lib/modules/%s/updates/drivers/lego/nxt/lego_nxt.ko' % kver,
        'lib/modules/%s/updates/drivers/lego/nxt/lego_nxt_usb.ko' % kver,
        'lib/modules/%s/updates/drivers/lego/nxt/lego_nxt_serial.ko' % kver,
        prefix + '/include/lego-mindstorms/linux/lego_ev3_uart.h',
        prefix + '/include/lego-mindstorms/linux/lego_nxt.h',
        prefix + '/share/pkgconfig/lego-mindstorms.pc',
        sysusersdir + '/lego-mindstorms.conf',
    }
    for r in os.listdir(os.path.join(src, 'tools/udev')):
        if r.endswith('.rules'):
            exp.add(udevdir + '/' + r)
    units = os.path.join(src, 'tools/systemd')
    if os.path.isdir(units):
        for u in os.listdir(units):
            if re.search(r'\.(service|socket|path|timer)$', u):
                exp.add(unitdir + '/' + u)
    return exp


@pytest.mark.parametrize('prefix,udevdir,unitdir,sysusersdir', [
    ('/usr/local', 'etc/udev/rules.d', 'usr/local/lib/systemd/system', 'etc/sysusers.d'),
    ('/usr', 'usr/lib/udev/rules.d', 'usr/lib/systemd/system', 'usr/lib/sysusers.d'),
])
def test_install_and_uninstall_destdir(src, tree, tmp_path, prefix, udevdir, unitdir,
                                       sysusersdir):
    dest = str(tmp_path / 'stage')
    make(src, 'install', 'KDIR=' + tree, 'DESTDIR=' + dest, 'PREFIX=' + prefix)
    files = listing(dest)
    exp = expected(tree, prefix.lstrip('/'), udevdir, unitdir, sysusersdir, src)
    missing = exp - files
    assert not missing, 'not installed: %s' % sorted(missing)
    # Nothing in the directory of the distribution's kernel headers.
    assert not os.path.exists(os.path.join(dest, prefix.lstrip('/'), 'include/linux'))
    # Nothing else but the tools (under PREFIX) and their documentation.
    extra = {f for f in files - exp if not f.startswith(prefix.lstrip('/') + '/')}
    assert not extra, 'installed outside PREFIX: %s' % sorted(extra)
    # No test-only module, and no module index in a staged install.
    kos = {f for f in files if f.endswith('.ko')}
    assert len(kos) == 4, sorted(kos)
    assert not [f for f in files if os.path.basename(f).startswith('modules.')], \
        'depmod ran on DESTDIR'
    make(src, 'uninstall', 'KDIR=' + tree, 'DESTDIR=' + dest, 'PREFIX=' + prefix)
    left = listing(dest)
    assert not left & exp, 'left by make uninstall: %s' % sorted(left & exp)
    assert not os.path.exists(os.path.join(dest, prefix.lstrip('/'), 'include/lego-mindstorms'))


def test_pkg_config_file_compiles_a_program(src, tmp_path):
    """The installed headers with `pkg-config --cflags lego-mindstorms`:
    <linux/lego_nxt.h> from INCLUDEDIR/lego-mindstorms, the rest of
    <linux/...> from the system."""
    if not shutil.which('pkg-config') or not shutil.which('cc'):
        pytest.skip('needs pkg-config and cc')
    dest = str(tmp_path / 'stage')
    make(src, 'install-userspace', 'DESTDIR=' + dest, 'PREFIX=/usr')
    pc = os.path.join(dest, 'usr/share/pkgconfig/lego-mindstorms.pc')
    with open(pc) as f:
        text = f.read()
    ver = dkms_version(src)
    assert re.search(r'^Version: %s$' % re.escape(ver), text, re.M), text
    env = dict(os.environ, PKG_CONFIG_PATH=os.path.dirname(pc),
               PKG_CONFIG_SYSROOT_DIR=dest)
    r = subprocess.run(['pkg-config', '--cflags', 'lego-mindstorms'], capture_output=True,
                       text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ['-I%s/usr/include/lego-mindstorms' % dest], r.stdout
    prog = tmp_path / 'p.c'
    prog.write_text('#include <linux/types.h>\n#include <linux/lego_nxt.h>\n'
                    '#include <linux/lego_ev3_uart.h>\n'
                    'int main(void) { return 0; }\n')
    r = subprocess.run(['cc', '-Wall', '-Werror'] + r.stdout.split() +
                       ['-o', str(tmp_path / 'p'), str(prog)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_unit_documentation_is_installed(src, tmp_path):
    """Each man page the systemd unit's Documentation= names is one that
    `make install-userspace` installs: the unit's own program's, not
    ldattach(8)."""
    dest = str(tmp_path / 'stage')
    make(src, 'install-userspace', 'DESTDIR=' + dest, 'PREFIX=/usr')
    units = glob.glob(os.path.join(dest, 'usr/lib/systemd/system/*.service'))
    assert units, listing(dest)
    for unit in units:
        with open(unit) as f:
            text = f.read()
        docs = re.findall(r'^Documentation=(.*)$', text, re.M)
        assert docs, unit
        pages = [p for d in docs for p in d.split()]
        execs = re.findall(r'^ExecStart=(\S+)', text, re.M)
        for page in pages:
            m = re.fullmatch(r'man:([\w.@-]+)\((\d)\)', page)
            assert m, (unit, page)
            path = os.path.join(dest, 'usr/share/man/man%s/%s.%s' % (m.group(2), m.group(1),
                                                                     m.group(2)))
            assert os.path.exists(path) or os.path.exists(path + '.gz'), \
                '%s: %s is not installed by this project' % (os.path.basename(unit), page)
        assert any('man:%s(' % os.path.basename(e) in ' '.join(pages) for e in execs), \
            (unit, execs, pages)


def test_dkms_source_has_only_the_build_files(src, tmp_path):
    dest = str(tmp_path / 'stage')
    make(src, 'dkms-source', 'DESTDIR=' + dest)
    ver = dkms_version(src)
    root = os.path.join(dest, 'usr/src/lego-mindstorms-' + ver)
    assert sorted(os.listdir(root)) == ['Kbuild', 'Makefile', 'dkms.conf', 'drivers', 'include']
    files = listing(root)
    assert 'drivers/lego/ev3/ev3_uart_ldisc.c' in files
    assert 'include/uapi/linux/lego_nxt.h' in files
    assert not [f for f in files if f.endswith(('.o', '.ko', '.cmd'))]


def test_dkms_conf_names_the_built_modules(src):
    with open(os.path.join(src, 'dkms.conf')) as f:
        conf = f.read()
    names = re.findall(r'^BUILT_MODULE_NAME\[(\d)\]="([^"]+)"', conf, re.M)
    locs = dict(re.findall(r'^BUILT_MODULE_LOCATION\[(\d)\]="([^"]+)"', conf, re.M))
    assert {n for _, n in names} == {'lego_ev3_uart', 'lego_nxt', 'lego_nxt_usb',
                                     'lego_nxt_serial'}
    for i, n in names:
        # The Makefile (shared with the in-tree build) builds the module
        # when its option is set; the out-of-tree Kbuild sets it to m.
        path = os.path.join(src, locs[i])
        makefile = open(os.path.join(path, 'Makefile')).read()
        m = re.search(r'^obj-\$\((CONFIG_\w+)\) \+= %s\.o$' % n, makefile, re.M)
        assert m, (n, path)
        kbuild = open(os.path.join(path, 'Kbuild')).read()
        assert re.search(r'^%s := m$' % m.group(1), kbuild, re.M), (n, path)
        assert re.search(r'^include \$\(\w+\)$', kbuild, re.M), (n, path)
    assert re.search(r'^MAKE\[0\]=".*KDIR=\$\{kernel_source_dir\}', conf, re.M)
    assert re.search(r'^AUTOINSTALL="yes"', conf, re.M)


def test_make_dkms_install_twice_and_remove(src, tree):
    """make dkms-install (again: it replaces the version) and dkms-remove,
    in a private mount namespace with tmpfs over DKMS's directories."""
    if os.getuid() != 0 or not shutil.which('dkms') or not shutil.which('unshare'):
        pytest.skip('needs root, dkms and unshare')
    kver = krelease(tree)
    script = r'''
set -e
for d in /var/lib/dkms /usr/src /lib/modules; do mount -t tmpfs tmpfs $d; done
mkdir -p /lib/modules/{k} && ln -s {tree} /lib/modules/{k}/build
for n in 1 2; do make -s -C {src} dkms-install DKMS_KERNEL={k}; done
echo "status: $(dkms status)"
ls /lib/modules/{k}/updates/dkms
make -s -C {src} dkms-remove
echo "after: $(dkms status)"
ls /usr/src /var/lib/dkms
find /lib/modules -name '*.ko*'
'''.format(k=kver, tree=tree, src=src)
    r = subprocess.run(['unshare', '-m', '--propagation', 'private', 'bash', '-c', script],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    out = r.stdout
    status, after = out.split('status: ', 1)[1].split('after: ', 1)
    assert re.search(r'lego-mindstorms/\S+, %s, \S+: installed' % re.escape(kver), status)
    for ko in ('lego_ev3_uart.ko', 'lego_nxt.ko', 'lego_nxt_usb.ko', 'lego_nxt_serial.ko'):
        assert ko in status, (ko, status)
    assert '.ko' not in after and 'lego-mindstorms' not in after, after


def test_kernel_without_iio_kfifo_gets_a_clear_error(src, tree):
    """A kernel without CONFIG_IIO_KFIFO_BUF (the variable emptied on the
    command line, as in a .config without it) must stop the build with a
    message that says so, not with an unresolved symbol at load time."""
    r = subprocess.run(['make', '-C', src, 'KDIR=' + tree, 'CONFIG_IIO_KFIFO_BUF='],
                       capture_output=True, text=True)
    assert r.returncode != 0
    assert 'needs a kernel with CONFIG_IIO and CONFIG_IIO_KFIFO_BUF' in r.stdout + r.stderr
    # And with the option, the same tree builds (make clean reads no config).
    make(src, 'KDIR=' + tree, 'clean')


def test_dkms_conf_builds_for_6_1_and_later_only(src):
    """BUILD_EXCLUSIVE_KERNEL, matched as dkms matches it (bash's =~ on the
    kernel release), takes 6.1 and every later release, and no older one."""
    take = ['6.1.0-56-amd64', '6.1.158', '6.12.117+deb12-amd64', '6.9.0', '6.19.1',
            '7.0.0-rc1', '7.3.4-amd64', '10.2.1', '6.1']
    refuse = ['6.0.19', '5.15.0-91-generic', '5.10.0-32-amd64', '4.19.0', '3.16.0', '6.0']
    script = 'source "$1/dkms.conf"; shift; for v; do [[ $v =~ $BUILD_EXCLUSIVE_KERNEL ]] && echo "$v"; done; true'
    r = subprocess.run(['bash', '-c', script, 'x', src] + take + refuse,
                       capture_output=True, text=True, env={'kernel_source_dir': '/k', 'PATH': os.environ['PATH']})
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == take


def test_dkms_skips_a_kernel_older_than_6_1(src, tree):
    """dkms build for a 5.10 kernel (the test tree under that release name:
    dkms decides on the name before it builds) is skipped with exit 77 and
    its BUILD_EXCLUSIVE message; nothing is built or installed."""
    if os.getuid() != 0 or not shutil.which('dkms') or not shutil.which('unshare'):
        pytest.skip('needs root, dkms and unshare')
    script = r'''
for d in /var/lib/dkms /usr/src /lib/modules; do mount -t tmpfs tmpfs $d; done
mkdir -p /lib/modules/5.10.0-99-amd64 && ln -s {tree} /lib/modules/5.10.0-99-amd64/build
make -s -C {src} dkms-source >/dev/null || exit 1
dkms add -m lego-mindstorms -v {ver} >/dev/null || exit 1
dkms build -m lego-mindstorms -v {ver} -k 5.10.0-99-amd64
echo "rc=$?"
find /lib/modules /var/lib/dkms -name '*.ko*'
'''.format(tree=tree, src=src, ver=dkms_version(src))
    r = subprocess.run(['unshare', '-m', '--propagation', 'private', 'bash', '-c', script],
                       capture_output=True, text=True)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert 'rc=77' in out, out[-3000:]
    assert 'BUILD_EXCLUSIVE' in out, out[-3000:]
    assert '.ko' not in r.stdout.split('rc=77', 1)[1], out[-3000:]
