"""The systemd units of lego-ev3-attach (tools/systemd/lego-ev3-sensor@.service)
and of nxtctl connect (lego-nxt-bluetooth@.service), on the host: their
keys, and `systemd-analyze verify` of an instance with the tool built from
this checkout (no systemd needs to run; in the emulated
guest the check took twenty seconds).

  python3 -m pytest -v tests/packaging/test_systemd_unit.py
"""
import os
import re
import shutil
import subprocess

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
UNIT = os.path.join(TOP, 'tools/systemd/lego-ev3-sensor@.service')
NXT_UNIT = os.path.join(TOP, 'tools/systemd/lego-nxt-bluetooth@.service')


def unit_keys(unit=UNIT):
    keys = {}
    section = None
    for line in open(unit):
        line = line.strip()
        if not line or line.startswith('#'):
            continue
        if line.startswith('['):
            section = line.strip('[]')
            continue
        k, v = line.split('=', 1)
        keys.setdefault((section, k), []).append(v)
    return keys


def test_unit_keys():
    k = unit_keys()
    assert k[('Unit', 'BindsTo')] == ['dev-%i.device']
    assert 'dev-%i.device' in k[('Unit', 'After')]
    assert k[('Service', 'Type')] == ['simple']
    cmd = k[('Service', 'ExecStart')][0].split()
    assert os.path.basename(cmd[0]) == 'lego-ev3-attach'
    assert '--foreground' in cmd and cmd[-1] == '%I'
    assert '$LEGO_EV3_ATTACH_OPTS' in cmd
    assert any('%I' in v for v in k[('Service', 'EnvironmentFile')])
    assert k[('Service', 'DeviceAllow')] == ['/dev/%I rw']
    assert k[('Service', 'CapabilityBoundingSet')] == ['CAP_SYS_ADMIN']
    assert k[('Install', 'WantedBy')] == ['multi-user.target']


def verify(unit, tool_dir, tool, instance, tmp_path):
    """`systemd-analyze verify` of an instance of `unit`, whose ExecStart
    names `tool` bare (systemd's fixed search path), pointed at the one
    built from tools/`tool_dir` (not installed here): no error, no warning
    about the unit's lines (unknown keys and bad values are only warnings)."""
    sa = shutil.which('systemd-analyze')
    if not sa:
        pytest.skip('systemd-analyze not installed')
    r = subprocess.run(['make', '-s', '-C', os.path.join(TOP, 'tools', tool_dir),
                        'O=%s' % (tmp_path / 'bin')], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    built = tmp_path / 'bin' / tool
    assert os.access(built, os.X_OK)
    name = os.path.basename(unit)
    text, n = re.subn(r'^ExecStart=%s ' % re.escape(tool), 'ExecStart=%s ' % built,
                      open(unit).read(), flags=re.M)
    assert n == 1
    (tmp_path / name).write_text(text)
    inst = tmp_path / name.replace('@.', '@%s.' % instance)
    r = subprocess.run([sa, 'verify', '--man=no', str(inst)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert not re.search(r'%s:\d+' % re.escape(name), r.stderr), r.stderr


def test_unit_verifies(tmp_path):
    verify(UNIT, 'ev3-attach', 'lego-ev3-attach', 'ttyS1', tmp_path)


def test_nxt_unit_keys():
    k = unit_keys(NXT_UNIT)
    assert k[('Service', 'Type')] == ['simple']
    assert k[('Service', 'ExecStart')] == ['nxtctl connect --foreground %I']
    assert k[('Service', 'Restart')] == ['always']
    assert k[('Service', 'CapabilityBoundingSet')] == ['CAP_SYS_ADMIN']
    # nxtctl's daemon files (/run/nxtctl), shared by the instances.
    assert k[('Service', 'RuntimeDirectory')] == ['nxtctl']
    assert k[('Service', 'RuntimeDirectoryPreserve')] == ['yes']
    assert k[('Install', 'WantedBy')] == ['multi-user.target']


def test_nxt_unit_verifies(tmp_path):
    # (An address as the instance, as users name it, reads as verify's
    # FILE:ALIAS syntax here; the instance's value does not matter.)
    verify(NXT_UNIT, 'nxtctl', 'nxtctl', 'brick', tmp_path)
