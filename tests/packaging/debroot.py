"""A private, writable Debian root for installing the built packages with
the real dpkg, where the real root is read-only (the test VM's, over 9p)
and there is no overlayfs (the test kernel has none).

The root is a tmpfs in which every directory that dpkg, the maintainer
scripts or DKMS write to is a real directory, and everything else a
symlink into the real root, which is bind-mounted at /.lower inside it
(a symlink tree, as lndir makes, only along the written paths):

 - /etc and /var/lib/dpkg are copies (the group file, dpkg's database),
   but for the files of the installed packages in /var/lib/dpkg/info,
   which dpkg only reads (and replaces, never rewrites, for the packages it
   installs): those are symlinks, as they are most of the database (30 MB
   on a developer's host), which the guest would unpack and dpkg copy;
 - /usr/lib/modules holds only the test kernel's directory, its build link
   pointing at the kernel tree, so DKMS builds for that kernel only;
 - /tmp, /run, /var/log, /var/tmp and /var/lib/man-db are empty
   (no man-db auto-update: its trigger does nothing);
 - each directory that a package contains is real, its other entries
   symlinks to the real root's; but the documentation directories (DOCS)
   start empty, as nothing in the root reads the other packages' manual
   pages (18,000 symlinks in man1 alone on a developer's host).

tests/packaging/deb-prepare.sh makes one on the host, installs
lego-mindstorms-dkms in it (DKMS compiles there, in seconds; in the
emulated guest it takes over ten minutes) and saves it as a tar file, which
tests/packaging/test_deb.py unpacks on the host to install the other
packages, use them and purge all. It then installs the other packages too
and leaves that root unpacked beside the tar (OUT_TAR without .tar), for
tests/guest/test_deb.py: the guest chroots into it over 9p, with no copy
(dpkg and DKMS run 60 to 160 times slower in the emulated guest than here:
a tar of this root took 56 s to unpack there, `dpkg -i` 58 s, `dpkg
--purge` 77 s).

  python3 tests/packaging/debroot.py prepare KDIR DEB_DIR OUT_TAR
      (as root, in a private mount namespace: deb-prepare.sh)
"""
import glob
import os
import re
import shutil
import subprocess
import sys

LOWER = '/.lower'
PATH = '/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin'
# Directories made empty (fresh) or copied (from the real root).
FRESH = ('tmp', 'run', 'var/tmp', 'var/log', 'var/lib/man-db')
COPIED = ('etc', 'var/lib/dpkg')
# Real and empty, with the packages' directories below: no symlinks.
DOCS = ('usr/share/man', 'usr/share/doc', 'usr/share/bash-completion')
# Under a copied directory, mirrored (symlinks) instead of copied.
LINKED = ('var/lib/dpkg/info',)
# Written by maintainer scripts or DKMS besides the packages' directories.
WRITTEN = ('usr/src', 'var/lib/dkms', 'var/lib/systemd', 'var/cache', 'root')
MOUNTS = ('proc', 'sys', 'dev')
PACKAGES = ('lego-mindstorms-dkms', 'lego-mindstorms-tools', 'lego-mindstorms-dev',
            'liblegonxt-dev', 'python3-lego-nxt-linux')


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise RuntimeError('%s: exit %d\n%s%s' % (' '.join(cmd), r.returncode,
                                                   r.stdout[-4000:], r.stderr[-4000:]))
    return r.stdout


def debs(deb_dir):
    """The .deb of each package in deb_dir (not the -dbgsym ones)."""
    found = {}
    for name in PACKAGES:
        paths = sorted(glob.glob(os.path.join(deb_dir, name + '_*.deb')))
        if len(paths) != 1:
            raise RuntimeError('%s: %d packages %s_*.deb (make deb)' % (deb_dir, len(paths), name))
        found[name] = paths[0]
    return found


def deb_dirs(deb):
    """The directories a package contains, without the leading ./"""
    listing = run(['dpkg-deb', '-c', deb])
    dirs = []
    for line in listing.splitlines():
        fields = line.split(None, 5)
        if len(fields) == 6 and fields[0].startswith('d'):
            d = fields[5].strip().lstrip('.').strip('/')
            if d:
                dirs.append(d)
    return dirs


def _mirror(root, rel):
    """root/rel becomes a real directory whose entries mirror /rel's."""
    dst = os.path.join(root, rel)
    if os.path.islink(dst):
        os.unlink(dst)
    os.makedirs(dst, exist_ok=True)
    real = '/' + rel
    for name in os.listdir(real):
        d = os.path.join(dst, name)
        if os.path.lexists(d):
            continue
        src = os.path.join(real, name)
        if os.path.islink(src):
            os.symlink(os.readlink(src), d)
        else:
            os.symlink(os.path.join(LOWER, rel, name), d)


def _resolve(path):
    """path (relative to /) with the real root's symlinks resolved, as far
    as it exists there (lib/modules -> usr/lib/modules)."""
    return os.path.relpath(os.path.realpath('/' + path.strip('/')), '/')


def writable(root, path, fresh=False):
    """Make root/path a real directory, and each directory above it."""
    rel = _resolve(path)
    if rel == '.':
        return
    parts = rel.split('/')
    for i in range(len(parts)):
        cur = '/'.join(parts[:i + 1])
        d = os.path.join(root, cur)
        last = i == len(parts) - 1
        if last and fresh:
            if os.path.islink(d):
                os.unlink(d)
            os.makedirs(d, exist_ok=True)
        elif os.path.islink(d) or not os.path.exists(d):
            in_docs = any(cur.startswith(x + '/') for x in DOCS)
            if os.path.isdir('/' + cur) and not os.path.islink('/' + cur) and not in_docs:
                _mirror(root, cur)
            else:
                if os.path.islink(d):
                    os.unlink(d)
                os.makedirs(d)


def build(root, deb_dir, kdir, kver):
    """Lay out the root (an empty, mounted tmpfs)."""
    _mirror(root, '')
    for m in MOUNTS + (LOWER.strip('/'),):
        writable(root, m, fresh=True)
    for d in FRESH:
        writable(root, d, fresh=True)
    for d in COPIED:
        dst = os.path.join(root, d)
        writable(root, os.path.dirname(d))
        if os.path.lexists(dst):
            os.unlink(dst)
        run(['cp', '-a', '/' + d, dst])
    for d in LINKED:
        shutil.rmtree(os.path.join(root, d))
        _mirror(root, d)
    for d in WRITTEN:
        writable(root, d)
    for d in DOCS:
        writable(root, d, fresh=True)
    for deb in debs(deb_dir).values():
        for d in deb_dirs(deb):
            writable(root, d)
    # /usr/lib/modules: the test kernel only, as dkms-prepare.sh lays it out.
    mods = os.path.join(root, _resolve('lib/modules'))
    if os.path.islink(mods):
        os.unlink(mods)
    else:
        shutil.rmtree(mods)
    os.makedirs(os.path.join(mods, kver))
    os.symlink(kdir, os.path.join(mods, kver, 'build'))
    for f in ('modules.builtin', 'modules.builtin.modinfo', 'modules.order'):
        if os.path.isfile(os.path.join(kdir, f)):
            shutil.copy(os.path.join(kdir, f), os.path.join(mods, kver))
    os.chmod(os.path.join(root, 'tmp'), 0o1777)
    os.chmod(os.path.join(root, 'var/tmp'), 0o1777)


def mount(root):
    """Bind the real root and the kernel's file systems into the root; the
    mount points, in the order to unmount them."""
    done = []
    run(['mount', '--bind', '-o', 'ro', '/', root + LOWER])
    done.append(root + LOWER)
    for m in MOUNTS:
        run(['mount', '--rbind', '/' + m, os.path.join(root, m)])
        done.append(os.path.join(root, m))
    return list(reversed(done))


def umount(points):
    for p in points:
        subprocess.run(['umount', '-l', p], capture_output=True)


def chroot(root, cmd, **kw):
    env = {'PATH': PATH, 'LC_ALL': 'C', 'DEBIAN_FRONTEND': 'noninteractive',
           'HOME': '/root', 'TMPDIR': '/tmp'}
    return run(['chroot', root] + cmd, env=env, **kw)


def save(root, tar):
    """The root's own files (not the mounts) as a tar file."""
    run(['tar', '-C', root, '--one-file-system', '-cf', tar + '.new', '.'])
    os.rename(tar + '.new', tar)


def restore(tar, root):
    run(['tar', '-C', root, '-xf', tar])


def group_gid(root, name):
    """The GID of group name in the root's /etc/group, or None."""
    with open(os.path.join(root, 'etc/group')) as f:
        for line in f:
            fields = line.rstrip('\n').split(':')
            if fields[0] == name:
                return int(fields[2])
    return None


def kernel_release(kdir):
    with open(os.path.join(kdir, 'include/generated/utsrelease.h')) as f:
        return re.search(r'UTS_RELEASE "([^"]+)"', f.read()).group(1)


def install(root, deb_dir, names):
    """dpkg -i the packages names (from deb_dir) in the mounted root; dpkg's output."""
    paths = []
    found = debs(deb_dir)
    for name in names:
        deb = found[name]
        shutil.copy(deb, os.path.join(root, 'tmp'))
        paths.append('/tmp/' + os.path.basename(deb))
    try:
        return chroot(root, ['dpkg', '-i'] + paths)
    finally:
        for p in paths:
            os.unlink(root + p)


def unpacked(tar):
    """Where prepare() leaves the root with every package installed."""
    return tar[:-len('.tar')] if tar.endswith('.tar') else tar + '.d'


def prepare(kdir, deb_dir, tar):
    """In a private mount namespace: a root with lego-mindstorms-dkms
    installed (dpkg -i: DKMS adds, builds and installs the modules for the
    test kernel), saved as tar; then with the other packages installed
    too, copied to unpacked(tar)."""
    kdir = os.path.abspath(kdir)
    kver = kernel_release(kdir)
    root = tar + '.root'
    full = unpacked(tar)
    for d in (full, full + '.new'):
        if os.path.lexists(d):
            shutil.rmtree(d)
    os.makedirs(root, exist_ok=True)
    run(['mount', '-t', 'tmpfs', '-o', 'mode=0755', 'tmpfs', root])
    points = []
    try:
        build(root, deb_dir, kdir, kver)
        points = mount(root)
        out = install(root, deb_dir, ['lego-mindstorms-dkms'])
        status = chroot(root, ['dkms', 'status', '-m', 'lego-mindstorms'])
        if not re.search(r'%s, \S+: installed' % re.escape(kver), status):
            raise RuntimeError('dkms did not install for %s:\n%s\n%s' % (kver, out, status))
        with open(tar + '.log', 'w') as f:
            f.write(out + status)
        umount(points)
        points = []
        with open(os.path.join(root, 'kernel-release'), 'w') as f:
            f.write(kver + '\n')
        save(root, tar)
        points = mount(root)
        out = install(root, deb_dir, [p for p in PACKAGES if p != 'lego-mindstorms-dkms'])
        with open(tar + '.log', 'a') as f:
            f.write(out)
        umount(points)
        points = []
        run(['cp', '-a', root + '/.', full + '.new'])
        os.rename(full + '.new', full)
    finally:
        umount(points)
        subprocess.run(['umount', '-l', root])
        os.rmdir(root)
    return kver


if __name__ == '__main__':
    if len(sys.argv) != 5 or sys.argv[1] != 'prepare':
        sys.exit('usage: %s prepare KDIR DEB_DIR OUT_TAR' % sys.argv[0])
    print(prepare(sys.argv[2], sys.argv[3], sys.argv[4]))
