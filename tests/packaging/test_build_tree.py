"""Building in the source tree leaves it clean, and O= builds go anywhere
(host, no VM).

 - a copy of the tree (its git files) with every userspace program built in
   place (`make -C tools`, `make -C examples`, the benchmark clients) shows
   nothing new in `git status`: each built file is in a .gitignore;
 - `make -C examples O=DIR` builds into a directory that does not exist yet.

  python3 -m pytest -v tests/packaging/test_build_tree.py
"""
import os
import shutil
import subprocess

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
# What `make check` and a user build in the tree itself (not under .build).
IN_TREE = ['tools', 'examples', 'tests/bench/ev3', 'tests/bench/nxt']


def git(*args, cwd=TOP):
    return subprocess.run(['git', *args], cwd=cwd, capture_output=True, text=True,
                          check=True).stdout


@pytest.fixture(scope='module')
def tree(tmp_path_factory):
    if not shutil.which('git') or not os.path.isdir(os.path.join(TOP, '.git')) and \
            not os.path.isfile(os.path.join(TOP, '.git')):
        pytest.skip('not a git checkout')
    dst = tmp_path_factory.mktemp('tree')
    files = git('ls-files', '-co', '--exclude-standard', '-z').split('\0')
    for f in filter(None, files):
        src = os.path.join(TOP, f)
        if not os.path.lexists(src):
            continue                        # deleted, not yet committed
        os.makedirs(os.path.dirname(os.path.join(dst, f)), exist_ok=True)
        shutil.copy2(src, os.path.join(dst, f), follow_symlinks=False)
    env = dict(os.environ, GIT_AUTHOR_NAME='t', GIT_AUTHOR_EMAIL='t@t',
               GIT_COMMITTER_NAME='t', GIT_COMMITTER_EMAIL='t@t')
    for cmd in (['init', '-q'], ['add', '-A'], ['commit', '-q', '-m', 'copy']):
        subprocess.run(['git', *cmd], cwd=dst, check=True, capture_output=True, env=env)
    return dst


def test_in_tree_builds_leave_git_status_clean(tree):
    for d in IN_TREE:
        r = subprocess.run(['make', '-s', '-C', d], cwd=tree, capture_output=True, text=True)
        assert r.returncode == 0, (d, r.stdout[-2000:], r.stderr[-2000:])
    built = [os.path.join(d, f) for d in ('tools/nxtctl', 'tools/ev3-attach',
                                          'tools/lego-sensors', 'examples')
             for f in os.listdir(os.path.join(tree, d))
             if os.access(os.path.join(tree, d, f), os.X_OK) and
             not os.path.isdir(os.path.join(tree, d, f)) and
             '.' not in f]
    assert len(built) >= 5, built
    status = git('status', '--porcelain', '--untracked-files=all', cwd=tree)
    assert status == '', 'built files git does not ignore:\n' + status


def test_examples_build_into_a_new_directory(tree, tmp_path):
    out = tmp_path / 'a' / 'new' / 'dir'
    r = subprocess.run(['make', '-s', '-C', os.path.join(tree, 'examples'), 'O=%s' % out,
                        'all'], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert os.access(out / 'nxt-ioctl', os.X_OK)
    assert os.access(out / 'iio-capture', os.X_OK)


def test_make_deb_runs_lintian_only_when_asked():
    """`make deb` is a user's build: lintian (the project's check, which make
    check asks for with DEB_LINTIAN=1) is neither run nor required."""
    def cmd(*args):
        r = subprocess.run(['make', '-n', '-C', TOP, 'deb', 'DEB_OUT=/tmp/x', *args],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return [ln for ln in r.stdout.splitlines() if 'make-deb.sh' in ln]
    assert [ln.split() for ln in cmd()] == [['tests/packaging/make-deb.sh', '/tmp/x']], cmd()
    assert [ln.split() for ln in cmd('DEB_LINTIAN=1')] == \
        [['tests/packaging/make-deb.sh', '--lintian', '/tmp/x']], cmd('DEB_LINTIAN=1')
    with open(os.path.join(TOP, 'tests/check.sh')) as f:
        assert 'make -s deb DEB_OUT="$build/deb" DEB_LINTIAN=1' in f.read()
    # make-deb.sh asks for lintian only with --lintian.
    with open(os.path.join(TOP, 'tests/packaging/make-deb.sh')) as f:
        text = f.read()
    assert 'tools=(dpkg-buildpackage dh dh_dkms)\n[ "$lint" = 0 ] || tools+=(lintian)' in text
