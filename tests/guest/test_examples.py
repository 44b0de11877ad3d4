"""The programs in examples/, run as a user runs them, against the emulated
EV3 sensors (tests/emulator/ev3_sensor.py) and NXT brick
(tests/emulator/nxt_brick.py); and nxt-python's own commands through
/dev/nxtN with the configuration line of Documentation/lego/nxt-python.rst.

Every check compares a program's output with what the emulator was told to
send, or what the emulated brick did, with values drawn at random."""
import os
import random
import re
import shutil
import subprocess
import sys
import time

import pytest

import ev3
import nxtdev
from ev3 import find_sensor, iio_device, read_attr, wait_attr_int, write_attr

TOP = nxtdev.TOP
EXAMPLES = os.path.join(TOP, 'examples')
TOOLS_PYTHON = os.path.join(TOP, 'tools', 'python')
RULE = os.path.join(TOP, 'tools', 'udev', '90-lego-ev3-sensors.rules')

SERIAL = '0016530E1A2B'                 # the module's brick (conftest: brick)
HOST = '00:16:53:0E:1A:2B'

# Python takes seconds to start under emulation; generous timeouts.
TIMEOUT = 120


def run(argv, stderr=subprocess.STDOUT, **kw):
    """Run a program; its stdout (stderr merged unless stderr=PIPE) when it
    exits with 0."""
    kw.setdefault('timeout', TIMEOUT)
    p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=stderr, text=True, **kw)
    assert p.returncode == 0, '%s exited with %d:\n%s%s' % (argv, p.returncode, p.stdout,
                                                          p.stderr or '')
    return p.stdout


def python_env(*paths, **extra):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(paths + tuple(
        p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p))
    env.update(extra)
    return env


@pytest.fixture(scope='module')
def built():
    """The C examples, built with their Makefile (O=, -Werror) by
    tests/build-modules.sh on the host into $LEGO_BUILD/examples: a compiler
    in the emulated guest takes twenty seconds for them."""
    out = os.path.join(os.environ['LEGO_BUILD'], 'examples')
    for prog in ('nxt-ioctl', 'iio-capture'):
        assert os.access(os.path.join(out, prog), os.X_OK), \
            '%s/%s not built (tests/build-modules.sh)' % (out, prog)
    return out


def apply_udev_rule(path):
    """The chmod of the shipped rule, as udev would run it (no udev here)."""
    with open(RULE) as f:
        rule = f.read()
    for cmd in re.findall(r'RUN\+="(/bin/chmod [^"]*)"', rule):
        subprocess.run(cmd.replace('/sys%p', path).split(), check=True)


# ---- NXT ----

def test_nxt_ioctl(built, brick):
    exe = [os.path.join(built, 'nxt-ioctl'), '-d', brick.node]
    fw = brick.fw
    old = fw.battery_mv
    fw.battery_mv = random.randint(6000, 9000)
    try:
        assert run(exe + ['battery']) == 'battery %d mV\n' % fw.battery_mv
    finally:
        fw.battery_mv = old

    hz = random.randint(200, 2000)
    fw.sound = None
    assert run(exe + ['tone', str(hz), '300']) == 'tone %d Hz 300 ms\n' % hz
    assert fw.sound is not None and fw.sound[:2] == ('tone', hz)

    fw.set_touch(0, True)
    assert run(exe + ['touch', '1']) == 'touch 1 pressed (raw %d)\n' % fw.inputs[0].raw
    fw.set_touch(0, False)
    assert run(exe + ['touch', '1']) == 'touch 1 released (raw %d)\n' % fw.inputs[0].raw

    degrees = random.randint(90, 400)
    out = run(exe + ['motor', 'B', '60', str(degrees)])
    assert out == 'motor B stopped at %d degrees\n' % degrees
    assert round(fw.motors[1].rotation) == degrees
    assert not fw.motors[1].running()

    # A brick that is not there: the program says so and fails.
    p = subprocess.run([exe[0], '-d', '/dev/nxt99', 'battery'], capture_output=True, text=True)
    assert p.returncode == 1 and '/dev/nxt99' in p.stderr


def test_nxt_python_example(brick):
    fw = brick.fw
    old = fw.battery_mv
    fw.battery_mv = random.randint(6000, 9000)
    fw.set_touch(0, True)
    fw.sound = None
    try:
        out = run([sys.executable, os.path.join(EXAMPLES, 'nxt-python-hello.py'),
                   '--filename', brick.node], env=python_env(TOOLS_PYTHON))
        assert out.splitlines() == [
            'brick NXT at %s, firmware 1.29, %d bytes free' % (HOST, fw.free_flash),
            'battery %d mV' % fw.battery_mv,
            'touch on port 1: pressed',
            'motor A at 180 degrees',
        ], out
    finally:
        fw.battery_mv = old
        fw.set_touch(0, False)
    assert fw.sound is not None and fw.sound[:2] == ('tone', 523)
    assert round(fw.motors[0].rotation) == 180
    assert not fw.motors[0].running()


def test_shell_session_nxt_part(brick):
    env = dict(os.environ)
    env['PATH'] = os.path.join(os.environ.get('LEGO_BUILD', ''), 'tools') + os.pathsep + \
        env.get('PATH', '')
    out = run(['sh', os.path.join(EXAMPLES, 'shell-session.sh')], env=env)
    lines = out.splitlines()
    assert lines[0].startswith('$ ls -l ') and brick.node in lines[0].split(), out
    assert any(s.startswith('c') and s.endswith(' ' + brick.node) for s in lines[1:-8]), out
    name = os.path.basename(brick.node)
    assert lines[-8:] == [
        '$ nxtctl -d %s info' % brick.node,
        '$ cd /sys/class/lego-nxt/%s' % name,
        '$ cat brick_name bt_address firmware_version battery_mv',
        'NXT', HOST.lower(), '1.29', str(brick.fw.battery_mv),   # bt_address: lower case
        '$ set +x',
    ], out


# ---- nxt-python's commands, with the backend named in .nxt-python.conf ----

def nxt_python_site(tmp_path):
    """nxt-python and lego-nxt-linux installed in one place, as pip or pipx
    install them: nxt-python's package with our module in nxt/backend/."""
    import nxt
    site = tmp_path / 'site'
    shutil.copytree(os.path.dirname(nxt.__file__), site / 'nxt',
                    ignore=shutil.ignore_patterns('__pycache__'))
    shutil.copy(os.path.join(TOOLS_PYTHON, 'nxt', 'backend', 'lego_nxt_linux.py'),
                site / 'nxt' / 'backend')
    shutil.copytree(os.path.join(TOOLS_PYTHON, 'lego_nxt_linux'), site / 'lego_nxt_linux',
                    ignore=shutil.ignore_patterns('__pycache__'))
    return str(site)


def command(name):
    path = shutil.which(name)
    assert path, '%s (installed with nxt-python) is not on PATH' % name
    return path


def test_nxt_test_command_with_config_file(brick, tmp_path):
    home = tmp_path / 'home'
    home.mkdir()
    (home / '.nxt-python.conf').write_text('[default]\nbackends = lego_nxt_linux\n')
    site = nxt_python_site(tmp_path)
    fw = brick.fw
    old = fw.battery_mv
    fw.battery_mv = random.randint(6000, 9000)
    try:
        out = run([command('nxt-test')], cwd=str(tmp_path),
                  env=python_env(site, HOME=str(home)))
    finally:
        fw.battery_mv, battery = old, fw.battery_mv
    for want in ['NXT brick name: NXT', 'Host address: %s' % HOST,
                 'Free user flash: %d' % fw.free_flash, 'Protocol version 1.124',
                 'Firmware version 1.29', 'Battery level %d mV' % battery,
                 'Play test sound...done.']:
        assert want in out.splitlines(), out
    assert fw.sound is not None and fw.sound[:2] == ('tone', 600)

    # Without the line, nxt-python's default backends (usb, then bluetooth)
    # cannot use the brick: it belongs to lego_nxt_usb.
    (home / '.nxt-python.conf').write_text('[default]\nname = NXT\n')
    p = subprocess.run([command('nxt-test'), '--no-sound'], cwd=str(tmp_path),
                       env=python_env(site, HOME=str(home)), capture_output=True,
                       text=True, timeout=TIMEOUT)
    assert p.returncode != 0 and 'NXT brick name' not in p.stdout
    assert brick.emu.wait_configured(10)        # the usb backend may reset it
    brick.node = nxtdev.node_of(SERIAL)
    assert brick.node


def test_nxt_push_through_module_runner(brick, tmp_path):
    """PYTHONPATH=tools/python: the runner makes the configured name work."""
    home = tmp_path / 'home'
    home.mkdir()
    (home / '.nxt-python.conf').write_text(
        '[default]\nbackends = lego_nxt_linux\nfilename = %s\n' % brick.node)
    data = bytes(random.randrange(256) for _ in range(random.randint(100, 400)))
    name = 'push%d.dat' % random.randint(0, 9999)
    (tmp_path / name).write_bytes(data)
    env = python_env(TOOLS_PYTHON, HOME=str(home))
    try:
        out = run([sys.executable, '-m', 'lego_nxt_linux', 'nxt-push', name],
                  cwd=str(tmp_path), env=env)
        assert 'Pushing %s (%d bytes)' % (name, len(data)) in out, out
        assert bytes(brick.fw.files[name].data) == data
    finally:
        brick.fw.files.pop(name, None)
    # Without the runner, nxt-python cannot import the name from PYTHONPATH.
    p = subprocess.run([command('nxt-push'), name], cwd=str(tmp_path), env=env,
                       capture_output=True, text=True, timeout=TIMEOUT)
    assert p.returncode != 0
    assert "No module named 'nxt.backend.lego_nxt_linux'" in p.stderr


# ---- EV3 ----

def on_sensor(line, emu, fn, tries=3):
    """fn(path of the sensor's directory), run again if the sensor
    reconnected meanwhile. On a loaded host the emulator, a thread of this
    process, can miss the driver's keep-alives for a second and start over
    as a real sensor does; the driver then drops the sensor ("too many line
    errors") and connects it again, in a new directory with new IIO and
    sysfs files. A failure with no new handshake within 20 s is a failure."""
    for attempt in range(tries):
        path = find_sensor(line.address, timeout=30)
        assert path, 'no sensor on %s' % line.address
        n = emu.handshakes
        try:
            return fn(path)
        except (AssertionError, OSError) as e:
            print('\n%s: %s' % (type(e).__name__, e))
            if attempt == tries - 1 or ev3.wait_handshakes(emu, n + 1, timeout=20) <= n:
                raise
            print('%s reconnected (handshake %d), trying again' % (line.address, n + 1))

def test_ev3dev2_color(line):
    from ev3dev2.sensor.lego import ColorSensor
    emu = line.plug('color')
    reflected = random.randint(1, 99)
    colour = random.randint(1, 7)
    emu.set_values(0, [reflected])      # COL-REFLECT
    emu.set_values(2, [colour])         # COL-COLOR

    def check(path):
        apply_udev_rule(path)
        out = run([sys.executable, os.path.join(EXAMPLES, 'ev3dev2-color.py'),
                   '--address', line.address, '--count', '2', '--interval', '0.1'])
        lines = [s for s in out.splitlines() if not s.startswith('Import warning')]
        assert lines[0] == 'sensor at %s' % line.address, out
        want = 'reflected %d %%  colour %d %s' % (reflected, colour, ColorSensor.COLORS[colour])
        assert lines[1:] == [want, want], out
        # The example switched modes through the class: the last was COL-COLOR.
        assert read_attr(path, 'mode') == 'COL-COLOR'
    on_sensor(line, emu, check)


def test_iio_capture(line, built):
    emu = line.plug('gyro', period_scale=10)    # GYRO-ANG at ~70 Hz, not 670
    angle = random.choice([-1, 1]) * random.randint(1, 179)
    rate = angle // 2 + 1
    emu.set_values(0, [angle])          # GYRO-ANG: angl0
    emu.set_values(1, [rate])           # GYRO-RATE
    on_sensor(line, emu, lambda path: check_iio_capture(line, built, angle, rate))


def check_iio_capture(line, built, angle, rate):
    dev = iio_device('lego-ev3-gyro')
    assert dev
    # Start in another mode: enabling the buffer switches to angl0's.
    write_attr(dev, 'mode', 'GYRO-RATE')
    assert wait_attr_int(dev, 'in_anglvel0_raw', rate) == rate
    scale = float(read_attr(dev, 'in_angl0_scale'))
    before = time.time()
    # The IIO device is found by its label, the sensor's address.
    # stdout only: libiio's local backend warns on stderr that the kfifo
    # buffer has no "high-speed" (mmap) mode, which the example does not need.
    out = run([os.path.join(built, 'iio-capture'), '-n', '40', line.address, 'angl0'],
              stderr=subprocess.PIPE)
    after = time.time()
    samples = [tuple(s.split()) for s in out.splitlines()]
    assert len(samples) == 40, out
    stamps = [int(t) for t, _, _ in samples]
    assert [int(r) for _, r, _ in samples] == [angle] * 40, out
    for _, _, value in samples:
        assert float(value) == pytest.approx(angle * scale, abs=1e-6)
    assert all(b > a for a, b in zip(stamps, stamps[1:])), 'timestamps not increasing'
    # CLOCK_REALTIME by default.
    assert before - 1 < stamps[0] / 1e9 <= stamps[-1] / 1e9 < after + 1
    assert read_attr(dev, 'mode') == 'GYRO-ANG'
    assert read_attr(dev, 'buffer/enable') == '0'   # libiio disabled it again


def test_shell_session_ev3_part(line):
    emu = line.plug('color')
    reflected = random.randint(1, 99)
    colour = random.randint(1, 7)
    emu.set_values(0, [reflected])
    emu.set_values(2, [colour])

    def check(path):
        assert wait_attr_int(path, 'value0', reflected) == reflected
        modes = read_attr(path, 'modes')
        out = run(['sh', os.path.join(EXAMPLES, 'shell-session.sh'), 'COL-COLOR'])
        want = [
            '$ cd %s' % path,
            '$ cat address driver_name modes mode',
            line.address, 'lego-ev3-color', modes, 'COL-REFLECT',
            '$ cat num_values decimals units value0',
            '1', '0', 'pct', str(reflected),
            '$ set +x',
            '$ echo COL-COLOR',
            '$ cat mode units value0',
            'COL-COLOR', 'col', str(colour),
            '$ set +x',
        ]
        # The NXT part follows while the module's brick is plugged in.
        assert out.splitlines()[:len(want)] == want, out
    on_sensor(line, emu, check)
