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
   user to run makes a system group;
 - 90-lego-ev3-iiod.rules restarts iiod.service, when it is enabled, as a
   sensor's IIO device (and no other) comes or goes;
 - an EV3 sensor's IIO node gets the group and the seat's access, and the
   rules' commands, run on a copy of a sensor's sysfs directories, make
   every attribute the driver lets userspace write (DEVICE_ATTR_RW/WO,
   BIN_ATTR_RW, IIO_DEVICE_ATTR_RW in drivers/lego/ev3, and the IIO
   buffer's) writable for the group.

  python3 -m pytest -v tests/packaging/test_udev_rules.py
"""
import glob
import grp
import os
import re
import shlex
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
    for subsystem in ('lego-nxt', 'usb'):
        mine = [line for line in text if 'SUBSYSTEM=="%s"' % subsystem in line
                and '0694' in line and 'idProduct' in line]
        assert any('TAG+="uaccess"' in line for line in mine), subsystem
        grouped = [line for line in mine if 'GROUP="lego"' in line]
        assert grouped and all('MODE="0660"' in line for line in grouped), mine


def test_ev3_iio_node_gets_both():
    """/dev/iio:deviceN of a sensor (an IIO device under a tty): the group
    lego with 0660, and the uaccess tag, before the seat rules."""
    found = {}
    for path in RULES:
        for line in rule_lines(path):
            if 'SUBSYSTEM=="iio"' in line and 'KERNEL=="iio:device*"' in line:
                assert 'SUBSYSTEMS=="tty"' in line, \
                    'a rule for every IIO device, not only the sensors\': ' + line
                if 'TAG+="uaccess"' in line:
                    found['uaccess'] = os.path.basename(path)
                if 'GROUP="lego"' in line:
                    assert 'MODE="0660"' in line, line
                    found['group'] = os.path.basename(path)
    assert set(found) == {'uaccess', 'group'}, found
    assert all(name < SEAT_FILES[0] for name in found.values()), found


def driver_writable():
    """The attributes drivers/lego/ev3 lets userspace write: the lego-sensor
    class's and the IIO device's own."""
    out = {'lego-sensor': set(), 'iio': set()}
    for src in glob.glob(os.path.join(TOP, 'drivers/lego/ev3/*.c')):
        with open(src) as f:
            text = f.read()
        for kind, name in re.findall(r'\b(DEVICE_ATTR_(?:RW|WO)|BIN_ATTR_(?:RW|WO)|'
                                     r'IIO_DEVICE_ATTR_(?:RW|WO))\((\w+)', text):
            out['iio' if kind.startswith('IIO') else 'lego-sensor'].add(name)
    return out


def run_commands(subsystem):
    """The RUN commands of the rules for SUBSYSTEM, as argv lists."""
    cmds = []
    for path in RULES:
        for line in rule_lines(path):
            if 'SUBSYSTEM=="%s"' % subsystem in line:
                cmds += re.findall(r'RUN\+="([^"]*)"', line)
    return cmds


def apply_run(subsystem, sysdir, group):
    for cmd in run_commands(subsystem):
        # udev: %p the device path under /sys, $$ a $.
        cmd = cmd.replace('/sys%p', str(sysdir)).replace('$$', '$')
        argv = [group if a == 'lego' else a for a in shlex.split(cmd)]
        if argv[:2] == ['/bin/sh', '-c']:
            argv[2] = argv[2].replace('chgrp lego ', 'chgrp %s ' % group)
        subprocess.run(argv, check=True, capture_output=True)


def fake_sysfs(root, files):
    for name in files:
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text('')
        os.chmod(p, 0o644 if not name.endswith(('command', '_en')) else 0o200)
    return root


def group_writable(path, gid):
    st = os.stat(path)
    return st.st_gid == gid and st.st_mode & 0o020


def test_rules_open_every_writable_sensor_attribute(tmp_path):
    """Each attribute the driver lets root write is group-writable after the
    rules' commands, and nothing read-only becomes writable."""
    writable = driver_writable()
    assert {'mode', 'direct'} <= writable['lego-sensor'], writable
    assert 'mode' in writable['iio'], writable
    # The group of the files: ours (chgrp to a group one is in needs no root).
    gid = os.getgid()
    group = grp.getgrgid(gid).gr_name

    sensor = fake_sysfs(tmp_path / 'sensor0', sorted(writable['lego-sensor']) +
                        ['address', 'value0', 'modes'])
    apply_run('lego-sensor', sensor, group)
    for name in writable['lego-sensor']:
        assert group_writable(sensor / name, gid), 'lego-sensor attribute %s: not for the group' % name
    for name in ('address', 'value0', 'modes'):
        assert not os.stat(sensor / name).st_mode & 0o022, name

    # The IIO buffer's attributes, in the old layout and the buffer0/ one.
    buffer = ['buffer/enable', 'buffer/length', 'buffer/watermark',
              'scan_elements/in_anglvel0_en', 'scan_elements/in_timestamp_en',
              'buffer0/enable', 'buffer0/length', 'buffer0/watermark',
              'buffer0/in_anglvel0_en']
    readonly = ['modes', 'name', 'in_anglvel0_raw', 'scan_elements/in_anglvel0_index']
    iio = fake_sysfs(tmp_path / 'iio:device0', sorted(writable['iio']) + buffer + readonly)
    apply_run('iio', iio, group)
    for name in sorted(writable['iio']) + buffer:
        assert group_writable(iio / name, gid), 'IIO attribute %s: not for the group' % name
    for name in readonly:
        assert not os.stat(iio / name).st_mode & 0o022, name


IIOD_RULES = os.path.join(TOP, 'tools/udev/90-lego-ev3-iiod.rules')


def rule_keys(line):
    """[(key, operator, value)] of a rule line."""
    return re.findall(r'([A-Z_]+(?:\{[^}]*\})?)\s*(==|!=|\+=|:=|=)\s*"([^"]*)"', line)


def iiod_rule_fires(action, subsystem, devpath):
    """Whether 90-lego-ev3-iiod.rules reaches its RUN for an event: each
    line "KEY!="VALUE", GOTO=end" skips it when KEY matches VALUE (udev's
    patterns: fnmatch, | between alternatives)."""
    from fnmatch import fnmatchcase
    event = {'ACTION': action, 'SUBSYSTEM': subsystem, 'DEVPATH': devpath}
    for line in rule_lines(IIOD_RULES):
        keys = rule_keys(line)
        if keys[0][0] == 'LABEL':
            continue
        if any(k == 'RUN' for k, _, _ in keys):
            return True
        (key, op, value), (goto, _, _) = keys
        assert op == '!=' and goto == 'GOTO', line
        if not any(fnmatchcase(event[key], alt) for alt in value.split('|')):
            return False
    return False


@pytest.mark.parametrize('action,devpath,fires', [
    ('add', '/devices/platform/soc/fe201000.serial/tty/ttyAMA0/iio:device0', True),
    ('remove', '/devices/platform/soc/fe201000.serial/tty/ttyAMA0/iio:device0', True),
    ('add', '/devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1:1.0/ttyUSB0/tty/ttyUSB0/'
     'iio:device2', True),
    ('remove', '/devices/virtual/tty/ttyNM0/iio:device1', True),
    ('change', '/devices/virtual/tty/ttyNM0/iio:device1', False),
    ('bind', '/devices/virtual/tty/ttyNM0/iio:device1', False),
    # Another driver's IIO device (an I2C IMU): iiod is not restarted for it.
    ('add', '/devices/platform/soc/fe804000.i2c/i2c-1/1-0068/iio:device0', False),
    ('add', '/devices/platform/soc/fe804000.i2c/i2c-1/1-0068/trigger0', False),
])
def test_iiod_rule_fires_for_sensors_only(action, devpath, fires):
    assert iiod_rule_fires(action, 'iio', devpath) == fires
    assert not iiod_rule_fires(action, 'tty', devpath)


FAKE_SYSTEMCTL = """#!/bin/sh
echo "$*" >> "$SYSTEMCTL_LOG"
case "$*" in
*is-enabled*) exit "$IIOD_ENABLED_STATUS" ;;
esac
exit 0
"""


@pytest.mark.parametrize('enabled', [True, False])
def test_iiod_rule_restarts_an_enabled_iiod(tmp_path, enabled):
    """The rule's RUN command, with a systemctl that logs its arguments:
    iiod.service is restarted without waiting for the job (udev must not
    block) if it is enabled, else left alone; the command succeeds
    either way."""
    cmds = [c for line in rule_lines(IIOD_RULES) for c in re.findall(r'RUN\+="([^"]*)"', line)]
    assert len(cmds) == 1, cmds
    fake = tmp_path / 'systemctl'
    fake.write_text(FAKE_SYSTEMCTL)
    os.chmod(fake, 0o755)
    # systemctl by its full path: udev gives the command no PATH.
    assert cmds[0].count('/bin/systemctl ') == 2, cmds
    argv = shlex.split(cmds[0].replace('$$', '$').replace('/bin/systemctl ', '%s ' % fake))
    assert argv[:2] == ['/bin/sh', '-c'], argv
    log = tmp_path / 'log'
    # What udev gives it: the device's properties, no PATH.
    env = {'ACTION': 'add', 'SUBSYSTEM': 'iio',
           'DEVPATH': '/devices/virtual/tty/ttyNM0/iio:device0',
           'SYSTEMCTL_LOG': str(log), 'IIOD_ENABLED_STATUS': '0' if enabled else '1'}
    r = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stdout + r.stderr
    calls = log.read_text().splitlines()
    assert calls[0] == '-q is-enabled iiod.service', calls
    if enabled:
        assert calls[1:] == ['--no-block restart iiod.service'], calls
    else:
        assert calls[1:] == [], calls


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
