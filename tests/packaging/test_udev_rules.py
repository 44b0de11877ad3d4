"""The udev rules of tools/udev and the sysusers.d file of tools/sysusers
(host side, no VM): the seat's access and the group "lego" must work.

 - systemd acts on TAG+="uaccess" in 71-seat.rules and 73-seat-late.rules:
   a rule file that adds the tag must sort before them;
 - systemd 258 ignores a whole rule line whose GROUP= names a group that is
   not a system group: the uaccess tag stands on lines without GROUP=;
 - every group the rules name is the system group the sysusers.d file makes
   (systemd-sysusers --root on an empty root shows the GID it picks);
 - udev accepts the files: `udevadm verify` where the installed systemd
   has it (254 and later), else (Debian 12's 252) udev's own rule parser
   through `udevadm test`, the files in a tmpfs over /etc/udev/rules.d in a
   private mount namespace, which reports each line it refuses or ignores
   (and the check is shown to catch a bad file);
 - every `groupadd` the README, the documentation and the Makefile tell a
   user to run makes a system group.

  python3 -m pytest -v tests/packaging/test_udev_rules.py
"""
import glob
import os
import re
import shutil
import subprocess

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
RULES = sorted(glob.glob(os.path.join(TOP, 'tools/udev/*.rules')))
SYSUSERS = os.path.join(TOP, 'tools/sysusers/lego-mindstorms.conf')
# Where systemd applies the uaccess tag (its own rule files).
SEAT_FILES = ('71-seat.rules', '73-seat-late.rules')


def rule_lines(path):
    """The rule lines of a file, continuation lines joined."""
    lines, cur = [], ''
    with open(path) as f:
        for raw in f:
            line = raw.rstrip('\n')
            if not cur and (not line.strip() or line.lstrip().startswith('#')):
                continue
            if line.endswith('\\'):
                cur += line[:-1]
                continue
            lines.append(cur + line)
            cur = ''
    return lines


def sysusers_groups():
    groups = []
    with open(SYSUSERS) as f:
        for line in f:
            fields = line.split()
            if fields and not fields[0].startswith('#'):
                groups.append(fields)
    return groups


def test_there_are_rules():
    names = [os.path.basename(r) for r in RULES]
    assert any('nxt' in n for n in names), names


def test_uaccess_rules_sort_before_the_seat_rules():
    users = [r for r in RULES if any('uaccess' in line for line in rule_lines(r))]
    assert users, 'no rule adds the uaccess tag'
    for path in users:
        name = os.path.basename(path)
        for seat in SEAT_FILES:
            # udev orders all rule files by name, whatever their directory.
            assert name < seat, '%s sorts after %s: its uaccess tag has no effect' % (name, seat)


def test_uaccess_lines_have_no_group():
    for path in RULES:
        for line in rule_lines(path):
            if re.search(r'TAG\+?="[^"]*\buaccess\b', line):
                assert not re.search(r'\bGROUP\s*:?=', line), \
                    '%s: uaccess with GROUP= on one line (systemd 258 ignores it whole): %s' \
                    % (os.path.basename(path), line)


def test_nxt_node_and_usb_device_get_both():
    """Each device the group lego gets also has the seat's access: the same
    match once with GROUP= and MODE=, once with the tag."""
    text = [line for r in RULES for line in rule_lines(r)]
    for subsystem in ('usbmisc', 'usb'):
        mine = [line for line in text if 'SUBSYSTEM=="%s"' % subsystem in line
                and '0694' in line and 'idProduct' in line]
        assert any('TAG+="uaccess"' in line for line in mine), subsystem
        grouped = [line for line in mine if 'GROUP="lego"' in line]
        assert grouped and all('MODE="0660"' in line for line in grouped), mine


def test_groups_of_the_rules_are_made_by_sysusers():
    named = set()
    for path in RULES:
        for line in rule_lines(path):
            named.update(re.findall(r'\bGROUP\s*:?=\s*"([^"]+)"', line))
            named.update(re.findall(r'\bchgrp\s+(\S+)', line))
    assert named == {'lego'}, named
    groups = {f[1]: f for f in sysusers_groups() if f[0] == 'g'}
    for name in named:
        assert name in groups, '%s: no "g %s" line in %s' % (name, name, SYSUSERS)
        # "-": systemd-sysusers picks a GID in the system range.
        assert groups[name][2] == '-', groups[name]


def test_systemd_sysusers_makes_a_system_group(tmp_path):
    if not shutil.which('systemd-sysusers'):
        pytest.skip('systemd-sysusers is not installed')
    root = tmp_path / 'root'
    (root / 'etc').mkdir(parents=True)
    r = subprocess.run(['systemd-sysusers', '--root', str(root), SYSUSERS],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    entries = {}
    with open(root / 'etc/group') as f:
        for line in f:
            name, _, gid, _ = line.rstrip('\n').split(':')
            entries[name] = int(gid)
    assert 'lego' in entries, entries
    sys_max = 999
    if os.path.exists('/etc/login.defs'):
        with open('/etc/login.defs') as f:
            m = re.search(r'^\s*SYS_GID_MAX\s+(\d+)', f.read(), re.M)
            if m:
                sys_max = int(m.group(1))
    assert 0 < entries['lego'] <= sys_max, 'lego has GID %d, not a system GID' % entries['lego']


def udevadm_has_verify():
    r = subprocess.run(['udevadm', 'verify', '--help'], capture_output=True, text=True)
    return r.returncode == 0


# udevadm test (systemd 252): the rule files in a tmpfs over
# /etc/udev/rules.d, and an /etc/group that has the group "lego", in a
# private mount namespace (a user namespace too when not root); udev's
# parser says "FILE:LINE message" for every line it refuses or ignores.
UDEVADM_TEST = r'''
set -e
group=$1
shift
mount -t tmpfs tmpfs /etc/udev/rules.d
cp "$@" /etc/udev/rules.d/
mount --bind "$group" /etc/group
udevadm test --action=add /sys/class/mem/null 2>&1
'''


def udev_rule_errors(paths, tmp_path):
    """What udev finds wrong in the rule files `paths` (an empty string if
    nothing)."""
    if not shutil.which('udevadm'):
        pytest.skip('udevadm not installed')
    if udevadm_has_verify():
        # The group need not exist on the machine that runs the tests.
        r = subprocess.run(['udevadm', 'verify', '--resolve-names=never'] + paths,
                           capture_output=True, text=True)
        return '' if r.returncode == 0 else r.stdout + r.stderr
    group = tmp_path / 'group'
    with open('/etc/group') as f:
        group.write_text(f.read() + 'lego:x:987:\n')
    unshare = ['unshare', '-m'] if os.getuid() == 0 else ['unshare', '-r', '-m']
    r = subprocess.run(unshare + ['sh', '-c', UDEVADM_TEST, 'sh', str(group)] + paths,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    names = '|'.join(re.escape(os.path.basename(p)) for p in paths)
    bad = re.findall(r'^/etc/udev/rules\.d/(?:%s):\d+ .*$' % names, r.stdout, re.M)
    # Each file was read.
    for p in paths:
        assert 'Reading rules file: /etc/udev/rules.d/' + os.path.basename(p) in r.stdout, r.stdout
    return '\n'.join(bad)


def test_udev_accepts_the_rules(tmp_path):
    errors = udev_rule_errors(RULES, tmp_path)
    assert not errors, errors


def test_udev_rule_check_finds_errors(tmp_path):
    """The check above can fail: an unknown key, a group that does not
    exist, a line that is not a key/value list."""
    bad = tmp_path / '99-bad.rules'
    bad.write_text('SUBSYSTEM=="usb", NOSUCHKEY="x"\n'
                   'KERNEL=="nxt*", GROUP="nosuchgroup", MODE="0660"\n'
                   'ACTION=="add" garbage\n'
                   'KERNEL=="fine", MODE="0660"\n')
    errors = udev_rule_errors([str(bad)], tmp_path)
    assert '99-bad.rules' in errors, errors
    if not udevadm_has_verify():
        lines = sorted(int(m) for m in re.findall(r'99-bad\.rules:(\d+) ', errors))
        assert lines == [1, 2, 3], errors


def test_docs_make_a_system_group():
    paths = [os.path.join(TOP, 'README.md'), os.path.join(TOP, 'Makefile'),
             os.path.join(TOP, 'tools/README.md')]
    paths += glob.glob(os.path.join(TOP, 'Documentation/**/*.rst'), recursive=True)
    found = 0
    for path in paths:
        if not os.path.exists(path):
            continue
        with open(path) as f:
            for n, line in enumerate(f, 1):
                for cmd in re.findall(r'groupadd[^\n;&|`]*', line):
                    found += 1
                    assert re.search(r'(--system|\s-r\b)', cmd), \
                        '%s:%d: %s makes a regular group' % (os.path.relpath(path, TOP), n, cmd)
    assert found, 'no groupadd in the documentation'
