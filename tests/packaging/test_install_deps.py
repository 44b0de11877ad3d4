"""tests/install-deps.sh's Python side (host, no VM, no network).

 - tests/lib/check-requirements.py fails on a package that is missing or
   whose version differs from the one tests/requirements.txt names, and
   passes on the installed versions;
 - tests/lib/venv.sh: the venv's directory follows requirements.txt's
   content, and lego_venv_activate puts a complete venv first in PATH and
   leaves PATH alone without one;
 - install-deps.sh runs pip only in the venv (Debian's python3 refuses
   `pip install`: PEP 668), and every script that runs the Python tests
   activates the venv.

The whole of install-deps.sh on a stock Debian 12 is
tests/packaging/clean-root.sh's (a debootstrapped root).

  python3 -m pytest -v tests/packaging/test_install_deps.py
"""
import importlib.metadata as md
import os
import re
import subprocess
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
CHECK = os.path.join(TOP, 'tests/lib/check-requirements.py')
VENV_SH = os.path.join(TOP, 'tests/lib/venv.sh')
# The scripts that run Python tests on the host or hand the host's python3
# to the test VM.
RUNNERS = ('tests/check.sh', 'tests/arm64/check.sh', 'tests/demo/run.sh',
           'tests/bench/run.sh', 'tests/soak/run.sh', 'tests/vm-run')


def check(tmp_path, text):
    req = tmp_path / 'requirements.txt'
    req.write_text(text)
    return subprocess.run([sys.executable, CHECK, str(req)],
                          capture_output=True, text=True)


def test_check_requirements_passes_installed_versions(tmp_path):
    pytest_ver = md.version('pytest')
    r = check(tmp_path, f'# comment\n\npytest=={pytest_ver}  # pinned\npytest>=1\n')
    assert r.returncode == 0, r.stderr
    # The project's own list, in the Python that runs these tests.
    r = subprocess.run([sys.executable, CHECK, os.path.join(TOP, 'tests/requirements.txt')],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_check_requirements_fails_on_other_version(tmp_path):
    r = check(tmp_path, 'pytest==0.0.1\n')
    assert r.returncode == 1
    assert re.search(r'pytest: \S+ installed, ==0\.0\.1 wanted', r.stderr), r.stderr
    r = check(tmp_path, 'pytest<1\n')
    assert r.returncode == 1 and 'pytest' in r.stderr, r.stderr


def test_check_requirements_fails_on_missing(tmp_path):
    r = check(tmp_path, 'pytest>=1\nno-such-package-lego-mindstorms==1.0\n')
    assert r.returncode == 1
    assert 'no-such-package-lego-mindstorms: not installed' in r.stderr, r.stderr
    assert 'pytest' not in r.stderr, r.stderr


def venv_sh(script, top, cache, path='/usr/bin:/bin'):
    env = {'PATH': path, 'HOME': str(cache), 'LEGO_CACHE': str(cache)}
    r = subprocess.run(['bash', '-c', f'. {VENV_SH}; {script}', 'venv', str(top)],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


def fake_top(tmp_path, reqs):
    top = tmp_path / 'top'
    (top / 'tests').mkdir(parents=True, exist_ok=True)
    (top / 'tests/requirements.txt').write_text(reqs)
    return top


def test_venv_dir_follows_requirements(tmp_path):
    cache = tmp_path / 'cache'
    top = fake_top(tmp_path, 'pytest>=7\n')
    a = venv_sh('lego_venv_dir "$1"', top, cache)
    assert a.startswith(str(cache / 'venv') + '/'), a
    assert venv_sh('lego_venv_dir "$1"', top, cache) == a
    top = fake_top(tmp_path, 'pytest>=8\n')
    assert venv_sh('lego_venv_dir "$1"', top, cache) != a


def test_venv_activate(tmp_path):
    cache = tmp_path / 'cache'
    top = fake_top(tmp_path, 'pytest>=7\n')
    v = venv_sh('lego_venv_dir "$1"', top, cache)
    show = 'lego_venv_activate "$1"; echo "$PATH"; command -v python3 || true'
    # No venv, or an unfinished one: PATH as it was.
    assert venv_sh(show, top, cache).splitlines()[0] == '/usr/bin:/bin'
    os.makedirs(os.path.join(v, 'bin'))
    py = os.path.join(v, 'bin/python3')
    with open(py, 'w') as f:
        f.write('#!/bin/sh\n')
    os.chmod(py, 0o755)
    assert venv_sh(show, top, cache).splitlines()[0] == '/usr/bin:/bin'
    open(os.path.join(v, '.done'), 'w').close()
    out = venv_sh(show, top, cache).splitlines()
    assert out == [f'{v}/bin:/usr/bin:/bin', py]
    # Twice: once in PATH.
    out = venv_sh('lego_venv_activate "$1"; lego_venv_activate "$1"; echo "$PATH"', top, cache)
    assert out == f'{v}/bin:/usr/bin:/bin'


def test_install_deps_runs_pip_in_the_venv_only():
    with open(os.path.join(TOP, 'tests/install-deps.sh')) as f:
        code = [ln for ln in f if not ln.lstrip().startswith('#')]
    pips = [ln.strip() for ln in code if re.search(r'\bpip\b', ln) and 'echo' not in ln]
    assert pips, 'install-deps.sh installs no PyPI package'
    for ln in pips:
        assert ln.startswith('"$venv/bin/python3" -m pip '), ln
    assert any(re.search(r'/usr/bin/python3 -m venv\b', ln) for ln in code)
    assert any('check-requirements.py' in ln for ln in code)
    assert any(re.search(r'\bpython3-venv\b', ln) for ln in code)


def test_runners_activate_the_venv():
    for rel in RUNNERS:
        with open(os.path.join(TOP, rel)) as f:
            text = f.read()
        assert re.search(r'^\. "\$top/tests/lib/venv\.sh"$', text, re.M), rel
        assert re.search(r'^lego_venv_activate "\$top"$', text, re.M), rel
