"""lego-ev3-attach, its systemd unit and its udev rule.

The helper attaches the discipline to a null-modem tty (ttyNM0, ttyNM2...)
and the emulator plays a sensor on the other end, as in test_ev3_sensors.py.
The udev rule is checked with `udevadm test` on the VM's 8250 ports: no udev
daemon runs in the VM. The unit is checked on the host
(tests/packaging/test_systemd_unit.py).
"""
import fcntl
import os
import re
import shutil
import signal
import struct
import subprocess
import termios
import time

import pytest

from conftest import loaded, module_path, pid_alive
from ev3 import (CLASS, N_LEGOEV3, Line, SerialLine, find_sensor, glob, read_attr,
                 wait_gone)

TOP = os.path.join(os.path.dirname(__file__), '..', '..')
RULES = os.path.join(TOP, 'tools/udev/90-lego-ev3-attach.rules')

# Exit codes, as documented in lego-ev3-attach --help and ev3-attach.rst.
EXIT_USAGE, EXIT_NOTTY, EXIT_NOLDISC, EXIT_BUSY = 2, 3, 4, 6


def tool():
    path = os.path.join(os.environ['LEGO_BUILD'], 'tools/lego-ev3-attach')
    assert os.access(path, os.X_OK), path + ' not built (tests/build-modules.sh)'
    return path


def run(*args, timeout=30):
    return subprocess.run([tool(), *args], capture_output=True, text=True, timeout=timeout)


def ldisc(tty):
    fd = os.open(tty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        return struct.unpack('i', fcntl.ioctl(fd, termios.TIOCGETD, b'\0' * 4))[0]
    finally:
        os.close(fd)


def wait_ldisc(tty, want, timeout=10.0, proc=None):
    deadline = time.monotonic() + timeout
    got = ldisc(tty)
    while got != want and time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            break
        time.sleep(0.05)
        got = ldisc(tty)
    return got


def get_label(tty):
    LEGO_EV3_GET_PORT_LABEL = (2 << 30) | (16 << 16) | (0xE3 << 8) | 0x02
    fd = os.open(tty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        buf = fcntl.ioctl(fd, LEGO_EV3_GET_PORT_LABEL, b'\0' * 16)
    finally:
        os.close(fd)
    return buf.split(b'\0')[0].decode()


def wait_label(tty, want, timeout=5.0):
    """The label, once `want` (the helper sets it just after attaching)."""
    deadline = time.monotonic() + timeout
    got = get_label(tty)
    while got != want and time.monotonic() < deadline:
        time.sleep(0.02)
        got = get_label(tty)
    return got


def wait_exit(proc, timeout=10.0):
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        return None


def wait_pid_gone(pid, timeout=10.0):
    deadline = time.monotonic() + timeout
    while pid_alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not pid_alive(pid)


def sensors_on(tty_name):
    out = []
    for d in glob.glob(CLASS + '/sensor*'):
        try:
            if read_attr(d, 'address').split(':')[0] == tty_name:
                out.append(d)
        except OSError:
            pass
    return out


@pytest.fixture
def procs():
    """Popen objects killed at the end of a test if still running."""
    started = []
    yield started
    for p in started:
        if p.poll() is None:
            p.kill()
            p.wait()


@pytest.fixture
def nm(ev3_module):
    lines = []

    def make(pair):
        ln = Line(pair)
        lines.append(ln)
        return ln
    yield make
    for ln in lines:
        if ln.emu:
            ln.emu.stop()
        if ldisc(ln.host) == N_LEGOEV3:
            subprocess.run([tool(), '--detach', ln.host], check=False)
        assert not sensors_on(ln.address) or all(
            wait_gone(d, 5) for d in sensors_on(ln.address)), 'sensor left behind'


def start(procs, *args):
    p = subprocess.Popen([tool(), *args], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    procs.append(p)
    return p


def test_attach_with_label_then_sigterm(nm, procs):
    ln = nm(0)
    # A bare tty name is looked up in /dev.
    p = start(procs, '--foreground', '--label', 'in1', os.path.basename(ln.host))
    assert wait_ldisc(ln.host, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
    assert wait_label(ln.host, 'in1') == 'in1'
    emu = ln.plug('color')
    path = find_sensor('ttyNM0:in1', timeout=15)
    assert path, 'no sensor ttyNM0:in1 (emulator events: %s)' % emu.events
    assert read_attr(path, 'driver_name') == 'lego-ev3-color'
    assert p.poll() is None

    p.send_signal(signal.SIGTERM)
    assert wait_exit(p) == 0, p.communicate()
    assert wait_gone(path, 5), 'sensor still there after SIGTERM'
    # N_TTY is back: the discipline is not left behind.
    assert ldisc(ln.host) == 0


def test_sigint_and_default_address(nm, procs):
    ln = nm(1)
    p = start(procs, ln.host)        # foreground is the default
    assert wait_ldisc(ln.host, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
    # No --label: the driver's default, the bare tty name.
    assert get_label(ln.host) == ''
    ln.plug('us')
    path = find_sensor(ln.address, timeout=15)
    assert path, 'no sensor at %s' % ln.address
    p.send_signal(signal.SIGINT)
    assert wait_exit(p) == 0, p.communicate()
    assert wait_gone(path, 5)
    assert ldisc(ln.host) == 0


def test_daemon_pidfile_and_detach(nm, tmp_path):
    ln = nm(2)
    pidfile = tmp_path / 'attach.pid'
    r = run('--daemon', '--pidfile', str(pidfile), '--label', 'in4', ln.host)
    assert r.returncode == 0, r.stderr
    # The parent returns once the daemon has written its pidfile.
    pid = int(pidfile.read_text())
    assert pid_alive(pid)
    try:
        assert ldisc(ln.host) == N_LEGOEV3
        ln.plug('gyro')
        path = find_sensor(ln.address + ':in4', timeout=15)
        assert path, 'no sensor from the daemon'

        # --detach puts N_TTY back; the daemon sees it and exits.
        r = run('--detach', ln.host)
        assert r.returncode == 0, r.stderr
        assert ldisc(ln.host) == 0
        assert wait_gone(path, 5), 'sensor still there after --detach'
        assert wait_pid_gone(pid), 'the daemon did not exit after --detach'
        assert not pidfile.exists(), 'pidfile left behind'
    finally:
        if pid_alive(pid):
            os.kill(pid, signal.SIGKILL)

    # --detach of a tty without the discipline: nothing to do, no error.
    r = run('--detach', ln.host)
    assert r.returncode == 0 and 'not attached' in r.stderr


def test_daemon_wait_returns_with_the_sensor(nm, tmp_path):
    """--daemon --wait returns once the sensor is there, and prints its
    directory: the next command reads it without racing the handshake."""
    ln = nm(3)
    pidfile = tmp_path / 'attach.pid'
    p = subprocess.Popen([tool(), '--daemon', '--wait=60', '--pidfile', str(pidfile),
                          '--label=in2', ln.host], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    pid = None
    try:
        # Still waiting: no sensor yet, the daemon attached.
        assert wait_for_file(pidfile, 10), 'no pidfile'
        pid = int(pidfile.read_text())
        time.sleep(1.0)
        assert p.poll() is None, ('--wait returned without a sensor', p.communicate())
        ln.plug('color')
        out, err = p.communicate(timeout=70)
        assert p.returncode == 0, (p.returncode, err)
        path = out.strip()
        assert re.fullmatch(CLASS + r'/sensor\d+', path), out
        assert read_attr(path, 'address') == ln.address + ':in2'
        assert read_attr(path, 'driver_name') == 'lego-ev3-color'
    finally:
        if p.poll() is None:
            p.kill()
        if pid and pid_alive(pid):
            run('--detach', ln.host)
            assert wait_pid_gone(pid), 'the daemon did not exit after --detach'


def test_daemon_wait_times_out_and_stays(nm, tmp_path):
    ln = nm(3)
    pidfile = tmp_path / 'attach.pid'
    t0 = time.monotonic()
    r = run('--daemon', '-w2', '--pidfile', str(pidfile), ln.host, timeout=60)
    took = time.monotonic() - t0
    pid = int(pidfile.read_text())
    try:
        assert r.returncode == 8, (r.returncode, r.stderr)
        assert 'no sensor on %s after 2 s' % ln.address in r.stderr, r.stderr
        assert r.stdout == ''
        assert 2 <= took, took
        # The daemon holds the tty still.
        assert pid_alive(pid) and ldisc(ln.host) == N_LEGOEV3
    finally:
        run('--detach', ln.host)
        assert wait_pid_gone(pid), 'the daemon did not exit after --detach'


def wait_for_file(path, timeout):
    deadline = time.monotonic() + timeout
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    return path.exists()


def test_attach_on_8250(ev3_module, procs):
    """On a real UART: the helper's termios and the discipline's speed
    changes on an 8250, the emulator on the other port of the pair."""
    pair = os.environ.get('LEGO_SERIAL_PAIR', '').split()
    if len(pair) != 2:
        pytest.skip('the VM was started with --no-serial-pair')
    ln = SerialLine(*pair)
    p = start(procs, '--label', 'in2', '/dev/' + pair[0])
    try:
        assert wait_ldisc(ln.host, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
        assert wait_label(ln.host, 'in2') == 'in2'
        emu = ln.plug('gyro')
        path = find_sensor(pair[0] + ':in2', timeout=15)
        assert path, 'no sensor on %s (emulator events: %s)' % (pair[0], emu.events)
        p.terminate()
        assert wait_exit(p) == 0, p.communicate()
        assert wait_gone(path, 5)
        assert ldisc(ln.host) == 0
    finally:
        ln.close()


def test_hangup_exits_7(ev3_module, procs):
    """A hangup (what unplugging a USB-serial adapter does) ends the helper
    with status 7: closing a pty's master hangs up its slave."""
    master, slave = os.openpty()
    name = os.ttyname(slave)
    try:
        p = start(procs, name)
        assert wait_ldisc(name, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
    finally:
        os.close(slave)
        os.close(master)
    assert wait_exit(p) == 7, p.communicate()
    assert 'hung up' in p.stderr.read()


def test_second_attach_is_refused(nm, procs):
    ln = nm(3)
    p = start(procs, ln.host)
    assert wait_ldisc(ln.host, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
    r = run(ln.host)
    assert r.returncode == EXIT_BUSY, (r.returncode, r.stderr)
    assert 'already attached' in r.stderr
    # The refused second instance did not take the discipline away.
    assert ldisc(ln.host) == N_LEGOEV3 and p.poll() is None
    p.terminate()
    assert wait_exit(p) == 0


def test_ldattach_alternative(nm, procs):
    ldattach = shutil.which('ldattach')
    if not ldattach:
        pytest.skip('ldattach (util-linux) not installed')
    ln = nm(0)
    # -d: stay in the foreground.
    p = subprocess.Popen([ldattach, '-d', str(N_LEGOEV3), ln.host],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    procs.append(p)
    assert wait_ldisc(ln.host, N_LEGOEV3, proc=p) == N_LEGOEV3, p.communicate()
    ln.plug('ir')
    path = find_sensor(ln.address, timeout=15)
    assert path, 'no sensor with ldattach'
    p.terminate()
    p.wait(10)
    assert wait_gone(path, 5)


@pytest.mark.parametrize('arg,code,text', [
    ('/dev/null', EXIT_NOTTY, 'not a tty'),
    ('/etc/hostname', EXIT_NOTTY, 'not a tty'),     # read-only in the VM
    ('/tmp', EXIT_NOTTY, 'not a tty'),
    ('/dev/ttyNOSUCH', EXIT_NOTTY, 'no such device'),
    ('ttyNOSUCH', EXIT_NOTTY, '/dev/ttyNOSUCH: no such device'),
])
def test_bad_tty(ev3_module, arg, code, text):
    r = run(arg)
    assert r.returncode == code, (r.returncode, r.stderr)
    assert text in r.stderr


@pytest.mark.parametrize('what', ['file', 'dir'])
def test_not_a_tty_writable(ev3_module, tmp_path, what):
    path = tmp_path / 'x'
    if what == 'file':
        path.write_text('')
    else:
        path.mkdir()
    r = run(str(path))
    assert r.returncode == EXIT_NOTTY, (r.returncode, r.stderr)
    assert 'not a tty' in r.stderr


@pytest.mark.parametrize('args', [
    ['--label', 'in 1', 'ttyNM0'],
    ['--label', 'x' * 16, 'ttyNM0'],
    ['--label', 'in1', '--detach', 'ttyNM0'],
    [],
    ['ttyNM0', 'ttyNM1'],
    ['--bogus', 'ttyNM0'],
    ['--label=in 1', 'ttyNM0'],
    ['--ldisc=-1', 'ttyNM0'],
    ['--detach', '--daemon', 'ttyNM0'],
    ['--wait', 'ttyNM0'],
    ['--daemon', '--wait=0', 'ttyNM0'],
    ['--daemon', '--wait=x', 'ttyNM0'],
    ['--detach', '--wait', 'ttyNM0'],
    ['--label'],
])
def test_usage_errors(ev3_module, args):
    r = run(*args)
    assert r.returncode == EXIT_USAGE, (r.returncode, r.stderr)
    assert r.stderr.strip()
    assert ldisc('/dev/ttyNM0') == 0


def test_help():
    r = run('--help')
    assert r.returncode == 0
    assert 'Exit codes' in r.stdout and '--detach' in r.stdout
    for opt in ('--label=NAME', '--pidfile=FILE', '--ldisc=NUM', '--version'):
        assert opt in r.stdout
    assert r.stderr == ''


def test_version():
    with open(os.path.join(TOP, 'dkms.conf')) as f:
        ver = re.search(r'^PACKAGE_VERSION="([^"]+)"', f.read(), re.M).group(1)
    for opt in ('--version', '-V'):
        r = run(opt)
        assert r.returncode == 0, r.stderr
        assert r.stdout == 'lego-ev3-attach %s\n' % ver


def test_usage_error_points_to_help(ev3_module):
    """A usage error says what is wrong and where to look, not the whole
    help."""
    r = run('ttyNM0', 'ttyNM1')
    assert r.returncode == EXIT_USAGE
    assert 'one TTY only' in r.stderr and "--help' for more" in r.stderr
    assert 'Exit codes' not in r.stderr
    r = run()
    assert r.returncode == EXIT_USAGE and 'no TTY given' in r.stderr


def test_option_forms(nm, tmp_path):
    """--opt=value, -ovalue and -o value all work: a daemon started with
    --pidfile=FILE and -lNAME, detached with -D."""
    ln = nm(1)
    pidfile = tmp_path / 'attach.pid'
    r = run('-d', '--pidfile=%s' % pidfile, '-lin5', '--ldisc=%d' % N_LEGOEV3, ln.host)
    assert r.returncode == 0, r.stderr
    pid = int(pidfile.read_text())
    try:
        assert ldisc(ln.host) == N_LEGOEV3
        assert wait_label(ln.host, 'in5') == 'in5'
        r = run('-D', ln.host)
        assert r.returncode == 0, r.stderr
        assert ldisc(ln.host) == 0
        assert wait_pid_gone(pid), 'the daemon did not exit after -D'
    finally:
        if pid_alive(pid):
            os.kill(pid, signal.SIGKILL)
    # --ldisc=NUM is checked like --ldisc NUM.
    r = run('--ldisc=x', ln.host)
    assert r.returncode == EXIT_USAGE and 'bad line discipline number' in r.stderr


def test_module_not_loaded(nm):
    nm(0)       # loads the null modem; nothing attached
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    try:
        r = run('/dev/ttyNM0')
        if loaded('lego_ev3_uart'):
            pytest.fail('the kernel loaded tty-ldisc-29 on demand here: '
                        'this test needs it not to')
        assert r.returncode == EXIT_NOLDISC, (r.returncode, r.stderr)
        assert 'line discipline 29 not available' in r.stderr
        assert 'modprobe lego_ev3_uart' in r.stderr
        assert ldisc('/dev/ttyNM0') == 0
    finally:
        if not loaded('lego_ev3_uart'):
            subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)


def test_module_declares_ldisc_alias():
    # request_module("tty-ldisc-29") finds the module by this alias.
    ko = module_path('lego_ev3_uart')
    r = subprocess.run(['modinfo', '-F', 'alias', ko], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert 'tty-ldisc-%d' % N_LEGOEV3 in r.stdout.split()


# --- udev rule ----------------------------------------------------------

UDEV_DIR = '/run/udev/rules.d'


@pytest.fixture
def udev_rules():
    if not shutil.which('udevadm'):
        pytest.skip('udevadm not installed')
    assert os.path.ismount('/run') or os.environ.get('LEGO_IN_VM') == '1'
    os.makedirs(UDEV_DIR, exist_ok=True)
    made = []

    def add(name, text):
        path = os.path.join(UDEV_DIR, name)
        with open(path, 'w') as f:
            f.write(text)
        made.append(path)
    add('90-lego-ev3-attach.rules', open(RULES).read())
    yield add
    for path in made:
        os.unlink(path)


def udev_props(tty):
    r = subprocess.run(['udevadm', 'test', '--action=add', '/sys/class/tty/' + tty],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    props = {}
    for line in r.stdout.splitlines():
        m = re.match(r'^([A-Z0-9_]+)=(.*)$', line)
        if m:
            props[m.group(1)] = m.group(2)
    return props, r.stdout + r.stderr


def serial_pair():
    pair = os.environ.get('LEGO_SERIAL_PAIR', '').split()
    if len(pair) != 2:
        pytest.skip('the VM was started with --no-serial-pair')
    return pair


def test_udev_marked_by_name_wants_the_unit(udev_rules):
    a, b = serial_pair()
    udev_rules('80-lego-ev3-local.rules',
               'SUBSYSTEM=="tty", KERNEL=="%s", ENV{LEGO_EV3_SENSOR}="1"\n' % a)
    props, out = udev_props(a)
    assert 'lego-ev3-sensor@%s.service' % a in props.get('SYSTEMD_WANTS', '').split(), out
    assert 'systemd' in props.get('TAGS', '').strip(':').split(':'), out
    # The other port is not marked: no unit for it.
    props, out = udev_props(b)
    assert 'lego-ev3-sensor@' not in props.get('SYSTEMD_WANTS', ''), out


def test_udev_marked_by_devpath(udev_rules):
    a, b = serial_pair()
    devpath = os.path.realpath('/sys/class/tty/' + b)[len('/sys'):]
    udev_rules('80-lego-ev3-local.rules',
               'SUBSYSTEM=="tty", DEVPATH=="%s", ENV{LEGO_EV3_SENSOR}="1"\n' % devpath)
    props, out = udev_props(b)
    assert 'lego-ev3-sensor@%s.service' % b in props.get('SYSTEMD_WANTS', '').split(), out
    props, out = udev_props(a)
    assert 'lego-ev3-sensor@' not in props.get('SYSTEMD_WANTS', ''), out


def test_udev_unmarked_is_left_alone(udev_rules):
    a, _ = serial_pair()
    # A marking rule that sorts after the attach rule comes too late.
    udev_rules('95-lego-ev3-late.rules',
               'SUBSYSTEM=="tty", KERNEL=="%s", ENV{LEGO_EV3_SENSOR}="1"\n' % a)
    props, out = udev_props(a)
    assert props.get('LEGO_EV3_SENSOR') == '1', out
    assert 'lego-ev3-sensor@' not in props.get('SYSTEMD_WANTS', ''), out


