"""liblegonxt (tools/liblegonxt), the userspace encoding of the NXT's
direct and system commands: its unit test built with ASan and UBSan and
run, and the library built with every warning an error."""
import os
import re
import subprocess

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
LIB = os.path.join(TOP, 'tools', 'liblegonxt')


def make(tmp_path, *targets):
    return subprocess.run(['make', '-s', '-C', LIB, 'O=%s' % tmp_path, 'WERROR=1'] + list(targets),
                          capture_output=True, text=True)


def test_unit_test_passes(tmp_path):
    r = make(tmp_path, 'check')
    assert r.returncode == 0, r.stdout + r.stderr
    m = re.search(r'test_legonxt: (\d+) checks, (\d+) failed', r.stdout)
    assert m, r.stdout
    assert int(m.group(1)) > 150 and m.group(2) == '0'


def test_library_and_pkg_config_file(tmp_path):
    r = make(tmp_path, 'all')
    assert r.returncode == 0, r.stdout + r.stderr
    nm = subprocess.run(['nm', '-g', '--defined-only', str(tmp_path / 'liblegonxt.a')],
                        capture_output=True, text=True, check=True).stdout
    exported = set(re.findall(r' T (\w+)', nm))
    with open(os.path.join(LIB, 'legonxt.h')) as f:
        declared = set(re.findall(r'^\w[\w ]*?\**(lnxt_\w+)\(', f.read(), re.M))
    # Everything the header declares is defined, and nothing else is exported.
    assert declared and declared == exported, (declared ^ exported)
    pc = (tmp_path / 'legonxt.pc').read_text()
    assert 'Libs: -L${libdir} -llegonxt' in pc
