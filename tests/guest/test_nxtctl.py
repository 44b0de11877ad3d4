"""tools/nxtctl against the emulated brick (tests/emulator/nxt_brick.py).

Every subcommand runs the binary that tests/build-modules.sh built into
$LEGO_BUILD/tools, on a brick plugged in through dummy_hcd, and the tests
check both what nxtctl prints and what the emulated firmware recorded.
"""
import glob
import os
import pty
import random
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import time

import pytest

import nxtdev as nxt

SERIAL = '001653C0FFEE'
SERIAL2 = '0016530D0E0F'
NXTCTL = os.path.join(os.environ.get('LEGO_BUILD', ''), 'tools', 'nxtctl')
DOC = os.path.join(nxt.TOP, 'Documentation', 'lego', 'nxtctl.rst')

COMMANDS = ['list', 'info', 'battery', 'keep-alive', 'tone', 'play', 'stop-sound', 'motor',
            'motor-state', 'reset-motor', 'sensor-type', 'sensor', 'reset-sensor', 'ultrasonic',
            'mailbox-send', 'mailbox-read', 'start', 'stop', 'current', 'name', 'raw', 'upload',
            'download', 'ls', 'rm', 'release', 'claim', 'connect', 'attach', 'disconnect',
            'trace', 'help']


@pytest.fixture
def ctl(brick):
    """Run nxtctl on the brick: ctl(args...) -> CompletedProcess."""
    assert os.access(NXTCTL, os.X_OK), 'nxtctl not built: ' + NXTCTL
    def run(*args, text=True, timeout=60):
        return subprocess.run([NXTCTL, '-d', brick.node] + [str(a) for a in args],
                              capture_output=True, text=text, timeout=timeout)
    yield run
    # No command may leave a file handle open on the brick.
    assert brick.fw.handles == {}, brick.fw.handles


def ok(p):
    assert p.returncode == 0, (p.args, p.returncode, p.stdout, p.stderr)
    assert p.stderr in ('', b'')
    return p.stdout


def fails(p, code, *words):
    assert p.returncode == code, (p.args, p.returncode, p.stdout, p.stderr)
    assert p.stderr.startswith('nxtctl: '), p.stderr
    for w in words:
        assert w in p.stderr, (w, p.stderr)
    return p.stderr


def fields(out):
    return dict(line.split(': ', 1) for line in out.splitlines())


def wait_program(ctl, name, timeout=5.0):
    """Poll `current` until `name` runs (None: none); the emulated firmware
    applies a start or stop only when it handles a later command."""
    def check():
        p = ctl('current')
        return p.stdout == name + '\n' if name else p.returncode == 1
    return wait_for(check, timeout)


def wait_for(pred, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.02)
    return pred()


# ---- command line ----

def test_help_lists_every_command_and_matches_the_doc():
    p = subprocess.run([NXTCTL, '--help'], capture_output=True, text=True)
    out = ok(p)
    listed = [line.split()[0] for line in out.split('Commands:\n')[1].split('\n\n')[0].splitlines()]
    assert listed == COMMANDS
    with open(DOC) as f:
        doc = f.read()
    for c in COMMANDS:
        sub = subprocess.run([NXTCTL, c, '--help'], capture_output=True, text=True)
        via_help = subprocess.run([NXTCTL, 'help', c], capture_output=True, text=True)
        assert ok(sub) == ok(via_help)
        assert sub.stdout.startswith('usage: nxtctl [-d DEVICE] [-t TIMEOUT_MS] %s' % c)
        # The page documents each command with the same synopsis.
        synopsis = sub.stdout.splitlines()[0].split('] ', 2)[2]
        assert synopsis in doc, synopsis
    for code in ('0 ', '1 ', '2 ', '3 '):
        assert re.search(r'^``%s``|^%s' % (code.strip(), code), doc, re.M), code


@pytest.mark.parametrize('args,words', [
    ([], ['no command given']),
    (['bogus'], ["unknown command 'bogus'"]),
    (['-t', '0', 'battery'], ['timeout']),
    (['-x', 'battery'], ["'-x'"]),
    (['help', 'bogus'], ["unknown command 'bogus'"]),
    (['tone', '100', '50'], ['FREQ_HZ', '200 to 14000']),
    (['tone', '440'], ['missing arguments']),
    (['motor', 'D', '50'], ['motor port must be A, B or C']),
    (['motor', 'A', '101'], ['POWER']),
    (['motor', 'A', '50', '--tacho-limit'], ['needs a value']),
    (['motor', 'A', '50', '--fast'], ["unknown option '--fast'"]),
    (['sensor', '5'], ['sensor port must be 1, 2, 3 or 4']),
    (['sensor-type', '1', 'laser'], ["unknown sensor type 'laser'"]),
    (['sensor-type', '1', 'touch', 'loud'], ["unknown sensor mode 'loud'"]),
    (['mailbox-send', '10', 'hi'], ['BOX', '0 to 9']),
    (['mailbox-send', '1', 'x' * 59], ['at most 58']),
    (['start', 'a-very-long-program-name.rxe'], ['1 to 19 characters']),
    (['name', 'SixteenCharsLong'], ['1 to 15 characters']),
    (['raw', '0g'], ['not hex']),
    (['raw', '001'], ['whole bytes']),
    (['raw', '00'], ['at least 2 bytes']),
    (['raw'] + ['00'] * 65, ['at most 64 bytes']),
    (['battery', 'extra'], ['too many arguments']),
    (['-d'], ["option '-d' needs a value"]),
    (['--timeout=abc', 'battery'], ['timeout', "'abc'"]),
    (['--version=1'], ["'--version=1'"]),
    (['motor', 'A', '50', '--brake=yes'], ["option '--brake' takes no value"]),
    (['motor', 'A', '50', '--tacho-limit=x'], ['--tacho-limit', "'x'"]),
    (['motor', 'A', '50', '--wait'], ['--wait needs', '--tacho-limit']),
    (['motor', 'A', '0', '--tacho-limit=90', '--wait'], ['--wait needs']),
    (['motor', 'A', 'stop', '--wait'], ['--wait is for a move']),
    (['motor', 'A', '50', '--tacho-limit=90', '--wait', '--wait-timeout=0'],
     ['--wait-timeout']),
    (['motor', 'A', '-x'], ["unknown option '-x'"]),
    (['mailbox-send', '1', '-hello'], ["unknown option '-h'"]),
    (['release', 'extra'], ['too many arguments']),
    (['claim', '--serial'], ["option '--serial' needs a value"]),
    (['claim', '--serial=001653C0FFEE'], ['-d and --serial exclude each other']),
])
def test_usage_errors_exit_2(args, words):
    # Checked before the device is opened: no brick needed.
    p = subprocess.run([NXTCTL, '-d', '/dev/nxt-none'] + args, capture_output=True, text=True)
    fails(p, 2, *words)
    assert p.stdout == ''


def test_version():
    with open(os.path.join(nxt.TOP, 'dkms.conf')) as f:
        version = re.search(r'^PACKAGE_VERSION="([^"]+)"', f.read(), re.M).group(1)
    for opt in ('--version', '-V'):
        p = subprocess.run([NXTCTL, opt], capture_output=True, text=True)
        assert ok(p) == 'nxtctl %s\n' % version


def test_options_after_the_command_and_help_forms():
    p = subprocess.run([NXTCTL, 'battery', '--help'], capture_output=True, text=True)
    assert ok(p).startswith('usage: nxtctl [-d DEVICE] [-t TIMEOUT_MS] battery\n')
    assert subprocess.run([NXTCTL, 'battery', '-h'], capture_output=True, text=True).stdout == p.stdout
    # An abbreviated --help reaches the command's own parser.
    assert ok(subprocess.run([NXTCTL, 'battery', '--he'], capture_output=True,
                             text=True)) == p.stdout
    out = ok(subprocess.run([NXTCTL, '-h'], capture_output=True, text=True))
    assert '--device=DEVICE' in out and '--version' in out


def test_no_such_device_exits_3():
    p = subprocess.run([NXTCTL, '-d', '/dev/nxt99', 'battery'], capture_output=True, text=True)
    fails(p, 3, 'cannot open /dev/nxt99', 'No such file or directory')
    p = subprocess.run([NXTCTL, '-d', '/dev/null', 'battery'], capture_output=True, text=True)
    fails(p, 3, '/dev/null', 'not an NXT brick')


# ---- the brick ----

def test_list(brick):
    out = ok(subprocess.run([NXTCTL, 'list'], capture_output=True, text=True))
    rows = [line.split('\t') for line in out.splitlines()]
    assert [brick.node, 'NXT', '00:16:53:c0:ff:ee', '1.29'] in rows, rows


def test_device_from_the_environment(brick):
    env = dict(os.environ, NXT_DEVICE=brick.node)
    out = subprocess.run([NXTCTL, 'battery'], capture_output=True, text=True, env=env)
    assert int(ok(out)) == brick.fw.battery_mv


def test_device_and_timeout_option_forms(brick):
    node = brick.node
    for args in (['-d', node, 'battery'], ['-d' + node, 'battery'],
                 ['--device=' + node, 'battery'], ['--device', node, 'battery'],
                 ['--dev=' + node, 'battery'],
                 ['battery', '-d', node], ['battery', '--device=' + node],
                 ['-d', '/dev/nxt-none', 'battery', '-d', node],
                 ['-t300', '-d', node, 'battery'], ['--timeout=300', '-d', node, 'battery'],
                 ['-d', node, 'battery', '--timeout', '300']):
        p = subprocess.run([NXTCTL] + args, capture_output=True, text=True)
        assert int(ok(p)) == brick.fw.battery_mv, args
    # The last -d wins; a bad one after the command is used.
    p = subprocess.run([NXTCTL, '-d', node, 'battery', '-d', '/dev/nxt99'],
                       capture_output=True, text=True)
    fails(p, 3, 'cannot open /dev/nxt99')


def test_option_value_forms(brick, ctl):
    ok(ctl('motor', 'A', 40, '--tacho-limit=90'))
    m = brick.fw.motors[0]
    assert (m.power, m.limit) == (40, 90)
    # The emulated firmware moves its motors when it handles a command.
    assert wait_for(lambda: fields(ok(ctl('motor-state', 'A')))['run_state'] == 'idle', 10.0)
    # A negative POWER is a value, not an option; so is --turn-ratio's.
    ok(ctl('motor', 'all', -20, '--sync', '--turn-ratio=-50'))
    assert [(x.power, x.regmode, x.turn) for x in brick.fw.motors] == [(-20, 2, -50)] * 3
    ok(ctl('motor', '--sync', '--turn-ratio', '-40', 'all', '-25'))
    assert [(x.power, x.turn) for x in brick.fw.motors] == [(-25, -40)] * 3
    ok(ctl('motor', 'all', 'stop'))
    ok(ctl('sensor-type', 1, 'touch', 'transitions', '--slope=7'))
    assert brick.fw.inputs[0].mode == 0x47
    ok(ctl('sensor-type', 1, 'touch'))
    # "--" ends the options: a message that starts with a dash.
    ok(ctl('start', 'Demo.rxe'))
    assert wait_program(ctl, 'Demo.rxe')
    try:
        ok(ctl('mailbox-send', 2, '--', '-x-'))
        assert brick.fw.program_receive(2) == b'-x-\0'
    finally:
        ok(ctl('stop'))
        assert wait_program(ctl, None)


def test_info(brick, ctl):
    brick.fw.battery_mv = 7654
    info = fields(ok(ctl('info')))
    assert info == {
        'name': 'NXT',
        'bt_address': '00:16:53:c0:ff:ee',
        'firmware': '1.29',
        'protocol': '1.124',
        'battery_mv': '7654',
        'free_flash': str(brick.fw.free_flash),
    }


def test_battery_and_keep_alive(brick, ctl):
    brick.fw.battery_mv = 6999
    assert ok(ctl('battery')) == '6999\n'
    brick.fw.last_keep_alive = 0
    assert ok(ctl('keep-alive')) == '600000\n'
    assert brick.fw.last_keep_alive > 0


def test_name(brick, ctl):
    try:
        ok(ctl('name', 'Robby'))
        assert brick.fw.name == b'Robby'
        assert fields(ok(ctl('info')))['name'] == 'Robby'
    finally:
        ok(ctl('name', 'NXT'))
    assert brick.fw.name == b'NXT'


def test_tone_play_and_stop_sound(brick, ctl):
    ok(ctl('tone', 440, 200))
    assert brick.fw.sound[:2] == ('tone', 440)
    ok(ctl('play', 'Woops.rso', '--loop'))
    assert brick.fw.sound == ('file', 'Woops.rso', 1)
    ok(ctl('stop-sound'))
    assert brick.fw.sound is None
    ok(ctl('play', 'Woops.rso'))
    assert brick.fw.sound == ('file', 'Woops.rso', 0)
    ok(ctl('stop-sound'))
    # A missing sound file: the brick answers "out of range".
    fails(ctl('play', 'Missing.rso'), 1, 'PlaySoundFile', 'out of range', '0xc0')
    assert brick.fw.sound is None


def test_motor_run_and_state(brick, ctl):
    # Both counts from zero, whatever earlier tests turned.
    ok(ctl('reset-motor', 'A'))
    ok(ctl('reset-motor', 'A', '--relative'))
    ok(ctl('motor', 'A', 50, '--tacho-limit', 360))
    m = brick.fw.motors[0]
    assert (m.power, m.mode, m.regmode, m.limit) == (50, 0x01, 0, 360)
    # 50 power turns 500 degrees a second in the emulator: done in 0.72 s.
    assert wait_for(lambda: fields(ok(ctl('motor-state', 'A')))['run_state'] == 'idle', 10.0)
    st = fields(ok(ctl('motor-state', 'a')))
    assert st['port'] == 'A'
    assert st['power'] == '50'
    assert st['tacho_limit'] == '360'
    assert st['tacho_count'] == '360'
    assert st['rotation_count'] == '360'
    assert st['run_state'] == 'idle'
    ok(ctl('reset-motor', 'A'))
    assert fields(ok(ctl('motor-state', 'A')))['rotation_count'] == '0'
    assert fields(ok(ctl('motor-state', 'A')))['block_tacho_count'] == '360'
    ok(ctl('reset-motor', 'A', '--relative'))
    assert fields(ok(ctl('motor-state', 'A')))['block_tacho_count'] == '0'

    ok(ctl('motor', 'B', -30, '--brake', '--regulated'))
    m = brick.fw.motors[1]
    assert (m.power, m.mode, m.regmode, m.runstate) == (-30, 0x07, 1, 0x20)
    st = fields(ok(ctl('motor-state', 'B')))
    assert st['mode'] == 'on brake regulated' and st['regulation'] == 'speed'
    assert st['run_state'] == 'running'
    time.sleep(0.2)
    assert int(fields(ok(ctl('motor-state', 'B')))['tacho_count']) < 0
    ok(ctl('motor', 'B', 'brake'))
    assert (m.power, m.mode, m.runstate) == (0, 0x07, 0x20)
    ok(ctl('motor', 'B', 'stop'))
    assert (m.power, m.mode, m.runstate) == (0, 0, 0)
    assert fields(ok(ctl('motor-state', 'B')))['mode'] == 'off'

    ok(ctl('motor', 'all', 20, '--sync', '--turn-ratio', -50))
    assert [(x.power, x.regmode, x.turn) for x in brick.fw.motors] == [(20, 2, -50)] * 3
    ok(ctl('motor', 'all', 'stop'))
    assert not any(x.running() for x in brick.fw.motors)


def test_motor_wait(brick, ctl):
    m = brick.fw.motors[0]
    ok(ctl('reset-motor', 'A'))
    # Without --wait the command returns while the motor runs.
    ok(ctl('motor', 'A', 50, '--tacho-limit=360'))
    assert m.running()
    # The emulated firmware moves its motors when it handles a command.
    assert wait_for(lambda: fields(ok(ctl('motor-state', 'A')))['run_state'] == 'idle', 10.0)
    ok(ctl('reset-motor', 'A'))
    # 50 power turns 500 degrees a second in the emulator: 0.72 s.
    t0 = time.monotonic()
    ok(ctl('motor', 'A', 50, '--tacho-limit=360', '--wait'))
    took = time.monotonic() - t0
    assert not m.running() and m.runstate == 0
    assert round(m.tacho) == 360
    assert 0.6 < took < 5.0, took
    st = fields(ok(ctl('motor-state', 'A')))
    assert (st['run_state'], st['tacho_count']) == ('idle', '360')
    # Backwards, and all three motors at once.
    ok(ctl('motor', 'all', -100, '--tacho-limit', '200', '--wait'))
    assert [(x.running(), round(x.tacho)) for x in brick.fw.motors] == [(False, -200)] * 3


def test_motor_wait_timeout(brick, ctl):
    m = brick.fw.motors[1]
    try:
        t0 = time.monotonic()
        p = ctl('motor', 'B', 10, '--tacho-limit=100000', '--wait', '--wait-timeout=400')
        took = time.monotonic() - t0
        fails(p, 3, 'motor B', 'Connection timed out', 'still running after 400 ms',
              'of 100000')
        assert 0.35 < took < 5.0, took
        assert m.running()          # --wait does not stop the motor
    finally:
        ok(ctl('motor', 'B', 'stop'))
    assert not m.running()


def test_sensor_type_and_read(brick, ctl):
    ok(ctl('sensor-type', 1, 'touch', 'bool'))
    p = brick.fw.inputs[0]
    assert (p.type, p.mode) == (0x01, 0x20)
    brick.fw.set_touch(0, True)
    assert wait_for(lambda: fields(ok(ctl('sensor', 1)))['valid'] == '1')
    v = fields(ok(ctl('sensor', 1)))
    assert v['type'] == 'touch' and v['mode'] == 'bool'
    assert (v['raw'], v['scaled']) == ('183', '1')
    brick.fw.set_touch(0, False)
    v = fields(ok(ctl('sensor', 1)))
    assert (v['raw'], v['scaled']) == ('1023', '0')

    ok(ctl('sensor-type', 3, 'light-active', 'percent'))
    assert (brick.fw.inputs[2].type, brick.fw.inputs[2].mode) == (0x05, 0x80)
    assert wait_for(lambda: fields(ok(ctl('sensor', 3)))['valid'] == '1')
    v = fields(ok(ctl('sensor', 3)))
    assert v['type'] == 'light-active' and v['raw'] == '520'
    assert v['scaled'] == str((1023 - 520) * 100 // 1023)

    ok(ctl('sensor-type', 2, 'sound-dba'))
    assert (brick.fw.inputs[1].type, brick.fw.inputs[1].mode) == (0x08, 0x00)
    ok(ctl('sensor-type', 1, 'touch', 'transitions', '--slope', 3))
    assert brick.fw.inputs[0].mode == 0x43
    for pressed in (True, False, True, False):
        brick.fw.set_touch(0, pressed)
    assert int(fields(ok(ctl('sensor', 1)))['scaled']) > 0
    ok(ctl('reset-sensor', 1))
    assert fields(ok(ctl('sensor', 1)))['scaled'] == '0'


def test_ultrasonic(brick, ctl):
    brick.fw.ultrasonic.distance = 42
    ok(ctl('sensor-type', 4, 'none'))
    assert ok(ctl('ultrasonic', 4)) == '42\n'
    assert brick.fw.inputs[3].type == 0x0b
    brick.fw.ultrasonic.distance = 7
    assert ok(ctl('ultrasonic', 4)) == '7\n'
    # Nothing answers on port 1 (a touch sensor): a bus error.
    fails(ctl('ultrasonic', 1), 1, 'communication bus error')
    ok(ctl('sensor-type', 1, 'touch'))


# ---- programs and mailboxes ----

def test_upload_start_current_stop(brick, ctl, tmp_path):
    prog = tmp_path / 'Hello.rxe'
    data = bytes(random.Random(1).randrange(256) for _ in range(300))
    prog.write_bytes(data)
    try:
        ok(ctl('upload', prog))
        f = brick.fw.files['Hello.rxe']
        assert (f.kind, bytes(f.data)) == ('linear', data)
        ok(ctl('start', 'Hello.rxe'))
        assert wait_program(ctl, 'Hello.rxe')
        assert ok(ctl('current')) == 'Hello.rxe\n'
        assert brick.fw.program == 'Hello.rxe'
        ok(ctl('stop'))
        assert wait_program(ctl, None)
        assert brick.fw.program is None
        fails(ctl('current'), 1, 'GetCurrentProgramName', 'no program running')
        fails(ctl('stop'), 1, 'StopProgram', 'no program running', '0xec')
        fails(ctl('start', 'Nope.rxe'), 1, 'StartProgram', 'out of range')
    finally:
        brick.fw.files.pop('Hello.rxe', None)


def test_mailboxes_both_ways(brick, ctl):
    fails(ctl('mailbox-send', 0, 'nobody'), 1, 'no program running')
    ok(ctl('start', 'Demo.rxe'))
    assert wait_program(ctl, 'Demo.rxe')
    try:
        ok(ctl('mailbox-send', 3, 'hello brick'))
        assert brick.fw.program_receive(3) == b'hello brick\0'
        ok(ctl('mailbox-send', 0, 'x' * 58))
        assert brick.fw.program_receive(0) == b'x' * 58 + b'\0'

        brick.fw.program_send(12, b'pong')
        assert ok(ctl('mailbox-read', 12)) == 'pong\n'
        assert len(brick.fw.mailboxes[12]) == 1      # still queued
        assert ok(ctl('mailbox-read', 12, '--remove')) == 'pong\n'
        assert len(brick.fw.mailboxes[12]) == 0
        fails(ctl('mailbox-read', 12), 1, 'MessageRead', 'mailbox empty', '0x40')
    finally:
        ok(ctl('stop'))
        assert wait_program(ctl, None)


# ---- files ----

@pytest.mark.parametrize('size', [0, 57, 58, 59, 61, 122, 174, 1000, 4099])
def test_upload_download_round_trip(brick, ctl, tmp_path, size):
    data = bytes(random.Random(size).randrange(256) for _ in range(size))
    src = tmp_path / 'src.bin'
    src.write_bytes(data)
    try:
        ok(ctl('upload', src, 'round.dat'))
        assert bytes(brick.fw.files['round.dat'].data) == data
        dst = tmp_path / 'dst.bin'
        ok(ctl('download', 'round.dat', dst))
        assert dst.read_bytes() == data
        # To standard output, byte for byte.
        assert ctl('download', 'round.dat', '-', text=False).stdout == data
    finally:
        brick.fw.files.pop('round.dat', None)


def run_on_tty(args, cwd=None):
    """nxtctl with its standard error on a pseudo-terminal: (exit code,
    standard output, what the terminal got)."""
    master, slave = pty.openpty()
    try:
        p = subprocess.Popen([NXTCTL] + [str(a) for a in args], stdout=subprocess.PIPE,
                             stderr=slave, cwd=cwd)
        os.close(slave)
        out = p.stdout.read()
        got = b''
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:          # EIO: the last writer has gone
                break
            if not chunk:
                break
            got += chunk
        p.wait(60)
        return p.returncode, out, got.decode()
    finally:
        os.close(master)


def test_progress_bar_only_on_a_terminal(brick, ctl, tmp_path):
    data = bytes(random.Random(7).randrange(256) for _ in range(1000))
    src = tmp_path / 'bar.bin'
    src.write_bytes(data)
    try:
        rc, out, tty = run_on_tty(['-d', brick.node, 'upload', src])
        assert rc == 0 and out == b''
        assert bytes(brick.fw.files['bar.bin'].data) == data
        assert re.search(r'upload bar\.bin \[#{30}\] 100%  1000/1000 bytes\r?\n$', tty), tty
        assert '  0%  0/1000 bytes' in tty and tty.count('\r') >= 10, tty
        dst = tmp_path / 'back.bin'
        rc, out, tty = run_on_tty(['-d', brick.node, 'download', 'bar.bin', dst])
        assert rc == 0 and dst.read_bytes() == data
        assert re.search(r'download bar\.bin \[#{30}\] 100%  1000/1000 bytes\r?\n$', tty), tty
        # To standard output: the data there, the bar on the terminal.
        rc, out, tty = run_on_tty(['-d', brick.node, 'download', 'bar.bin', '-'])
        assert rc == 0 and out == data and '100%' in tty
        # Not a terminal: nothing on standard error (ok() checks).
        ok(ctl('download', 'bar.bin', dst))
        # An error before the transfer: no bar, the message alone.
        rc, out, tty = run_on_tty(['-d', brick.node, 'upload', src])
        assert rc == 1 and tty.startswith('nxtctl: OpenWrite'), tty
        # An error midway ends the bar's line before its message.
        break_reads_after(brick, 'bar.bin', 3)
        rc, out, tty = run_on_tty(['-d', brick.node, 'download', 'bar.bin', dst])
        assert rc == 1
        assert re.search(r'\] +17%  174/1000 bytes\r?\nnxtctl: Read: end of file', tty), tty
        assert dst.read_bytes() == data
    finally:
        brick.fw.__dict__.pop('handle', None)
        brick.fw.files.pop('bar.bin', None)


def break_reads_after(brick, name, n):
    """Truncate the brick's file `name` once `n` Read commands went through:
    the next Read answers "end of file", as a transfer failing midway."""
    orig = brick.fw.handle
    count = [0]

    def handle(packet):
        packet = bytes(packet)
        if len(packet) > 1 and packet[0] == 0x01 and packet[1] == 0x82:
            count[0] += 1
            if count[0] == n + 1:
                del brick.fw.files[name].data[10:]
        return orig(packet)
    brick.fw.handle = handle
    return count


def test_download_failure_keeps_the_existing_file(brick, ctl, tmp_path):
    data = bytes(random.Random(3).randrange(256) for _ in range(500))
    src = tmp_path / 'src.bin'
    src.write_bytes(data)
    ok(ctl('upload', src, 'fail.dat'))
    out = tmp_path / 'out'
    out.mkdir()
    dst = out / 'dst.bin'
    dst.write_bytes(b'precious')
    os.chmod(dst, 0o640)
    try:
        count = break_reads_after(brick, 'fail.dat', 2)
        fails(ctl('download', 'fail.dat', dst), 1, 'Read', 'end of file')
        assert count[0] == 3
        assert dst.read_bytes() == b'precious'
        assert os.listdir(out) == ['dst.bin']       # no temporary file left
        # No existing file: none is created.
        del brick.fw.handle
        brick.fw.files['fail.dat'].data[:] = data
        count = break_reads_after(brick, 'fail.dat', 1)
        fails(ctl('download', 'fail.dat', out / 'new.bin'), 1, 'Read', 'end of file')
        assert os.listdir(out) == ['dst.bin']
        # A transport error midway (a brick that stops answering) too.
        del brick.fw.handle
        brick.fw.files['fail.dat'].data[:] = data
        orig = brick.fw.handle

        def mute(packet):
            packet = bytes(packet)
            if packet[:2] == b'\x01\x82' and mute.reads:
                return None
            mute.reads += packet[:2] == b'\x01\x82'
            return orig(packet)
        mute.reads = 0
        brick.fw.handle = mute
        p = subprocess.run([NXTCTL, '-d', brick.node, '-t', '300', 'download', 'fail.dat', dst],
                           capture_output=True, text=True, timeout=60)
        fails(p, 3, 'Read', 'Connection timed out')
        assert dst.read_bytes() == b'precious'
        assert os.listdir(out) == ['dst.bin']
        del brick.fw.handle
        # A download that works replaces the file, and keeps its mode.
        ok(ctl('download', 'fail.dat', dst))
        assert dst.read_bytes() == data
        assert stat.S_IMODE(os.stat(dst).st_mode) == 0o640
        assert os.listdir(out) == ['dst.bin']
        # A new file gets 0666 less the umask.
        old = os.umask(0o027)
        try:
            ok(ctl('download', 'fail.dat', out / 'fresh.bin'))
        finally:
            os.umask(old)
        assert stat.S_IMODE(os.stat(out / 'fresh.bin').st_mode) == 0o640
    finally:
        brick.fw.__dict__.pop('handle', None)
        brick.fw.files.pop('fail.dat', None)


def test_download_default_name(brick, ctl, tmp_path):
    p = subprocess.run([NXTCTL, '-d', brick.node, 'download', 'Woops.rso'], cwd=tmp_path,
                       capture_output=True, text=True)
    ok(p)
    assert (tmp_path / 'Woops.rso').read_bytes() == bytes(brick.fw.files['Woops.rso'].data)


def test_upload_existing_needs_force(brick, ctl, tmp_path):
    src = tmp_path / 'f.txt'
    src.write_bytes(b'first')
    try:
        ok(ctl('upload', src))
        src.write_bytes(b'second version')
        fails(ctl('upload', src), 1, 'OpenWrite', 'file exists', '--force')
        assert bytes(brick.fw.files['f.txt'].data) == b'first'
        ok(ctl('upload', src, '--force'))
        assert bytes(brick.fw.files['f.txt'].data) == b'second version'
    finally:
        brick.fw.files.pop('f.txt', None)


def test_upload_errors(brick, ctl, tmp_path):
    big = tmp_path / 'big.bin'
    big.write_bytes(bytes(brick.fw.free_flash + 1))
    fails(ctl('upload', big), 1, 'OpenWrite', 'no space')
    assert 'big.bin' not in brick.fw.files
    fails(ctl('upload', tmp_path / 'missing.bin'), 3, 'cannot open', 'No such file')
    fails(ctl('upload', big, 'bad\x01name'), 2, 'printable ASCII')


def test_download_missing_file(brick, ctl, tmp_path):
    dst = tmp_path / 'out'
    fails(ctl('download', 'Nothing.rxe', dst), 1, 'OpenRead', 'file not found', '0x87')
    assert not dst.exists()
    fails(ctl('download', 'Woops.rso', tmp_path / 'no' / 'dir'), 3, 'cannot create')


def test_ls(brick, ctl):
    rows = [line.split() for line in ok(ctl('ls')).splitlines()]
    want = sorted([str(f.size), n] for n, f in brick.fw.files.items())
    assert sorted(rows) == want
    assert ['256', 'Demo.rxe'] in rows and ['100', 'Woops.rso'] in rows
    assert [line.split() for line in ok(ctl('ls', '*.rso')).splitlines()] == [['100', 'Woops.rso']]
    assert [line.split() for line in ok(ctl('ls', 'Demo.*')).splitlines()] == [['256', 'Demo.rxe']]
    assert ok(ctl('ls', 'Nothing.*')) == ''


def test_rm(brick, ctl, tmp_path):
    src = tmp_path / 'gone.txt'
    src.write_bytes(b'bye')
    ok(ctl('upload', src))
    assert 'gone.txt' in brick.fw.files
    free = brick.fw.free_flash
    ok(ctl('rm', 'gone.txt'))
    assert 'gone.txt' not in brick.fw.files
    assert brick.fw.free_flash > free
    fails(ctl('rm', 'gone.txt'), 1, 'Delete gone.txt', 'file not found')


# ---- raw telegrams ----

def test_raw(brick, ctl):
    assert ok(ctl('raw', '01', '88')) == '02 88 00 7c 01 1d 01\n'
    assert ok(ctl('raw', '0x000b')) == '02 0b 00 %02x %02x\n' % (
        brick.fw.battery_mv & 0xff, brick.fw.battery_mv >> 8)
    # No reply asked for: nothing printed, but the brick played the tone.
    assert ok(ctl('raw', *'80 03 e8 03 64 00'.split())) == ''
    assert wait_for(lambda: brick.fw.sound and brick.fw.sound[:2] == ('tone', 1000))
    # An error status: the reply is printed, the status named, exit 1.
    p = ctl('raw', '0001')
    assert p.stdout == '02 01 ec\n'
    fails(p, 1, 'no program running')


# ---- transport errors ----

@pytest.mark.parametrize('mode,words', [
    ('noreply', ['Connection timed out', 'the brick did not answer within 300 ms']),
    ('garbage', ['Protocol error']),
])
def test_transport_errors_exit_3(mode, words):
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile=mode)
    b.plug()
    try:
        p = subprocess.run([NXTCTL, '-d', b.node, '-t', '300', 'battery'],
                           capture_output=True, text=True, timeout=60)
        fails(p, 3, 'GetBatteryLevel', *words)
        p = subprocess.run([NXTCTL, '-d', b.node, '-t', '300', 'ls'],
                           capture_output=True, text=True, timeout=60)
        fails(p, 3, 'FindFirst', *words)
    finally:
        b.unplug()
        assert b.wait_gone()


# ---- release and claim: handing the brick to libusb programs ----

def usb_node(serial):
    """/dev/bus/usb/BBB/DDD of the emulated brick with this serial."""
    for d in glob.glob('/sys/bus/usb/devices/*'):
        try:
            with open(d + '/serial') as f:
                if f.read().strip() != serial:
                    continue
            with open(d + '/busnum') as f:
                bus = int(f.read())
            with open(d + '/devnum') as f:
                dev = int(f.read())
        except OSError:
            continue
        return '/dev/bus/usb/%03d/%03d' % (bus, dev), d
    return None, None


def driver_of(usbdir):
    """The driver bound to the brick's interface 0, or None."""
    link = os.path.join(usbdir, os.path.basename(usbdir) + ':1.0', 'driver')
    try:
        return os.path.basename(os.readlink(link))
    except FileNotFoundError:      # none, or unbound right now
        return None


LIBUSB_PROGRAM = r"""
import sys
import usb.core
serial = sys.argv[1]


def is_it(d):
    try:
        return d.serial_number == serial
    except (ValueError, usb.core.USBError):
        return False        # a device going away: not ours


dev = usb.core.find(idVendor=0x0694, idProduct=0x0002, custom_match=is_it)
if dev is None:
    sys.exit('no brick %s through libusb' % serial)
dev.set_configuration()
dev.write(0x01, b'\x00\x0b', timeout=2000)
reply = bytes(dev.read(0x82, 64, timeout=2000))
if reply[:3] != b'\x02\x0b\x00':
    sys.exit('GetBatteryLevel reply %s' % reply.hex())
print(reply[3] | reply[4] << 8, flush=True)
sys.stdin.read()            # holds the interface until told to go
"""


class LibusbProgram:
    """GetBatteryLevel through pyusb in a process of its own, as a libusb
    program would: the endpoints 0x01 OUT and 0x82 IN of interface 0, which
    it holds until close(). Its own process, so its own libusb context: a
    context that lives on in the test process keeps the device list of the
    moment it started (libusb learns of hot-plugs from udevd, which the
    test VM does not run) and would find a brick of an earlier test."""

    def __init__(self, serial=SERIAL):
        self.proc = subprocess.Popen([sys.executable, '-c', LIBUSB_PROGRAM, serial],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        if not line:
            self.proc.wait(30)
            raise AssertionError('libusb program: exit %d: %s' % (self.proc.returncode,
                                                                  self.proc.stderr.read()))
        self.mv = int(line)

    def close(self):
        self.proc.stdin.close()
        assert self.proc.wait(30) == 0, self.proc.stderr.read()


def test_release_and_claim(brick, ctl):
    node, usbdir = usb_node(SERIAL)
    assert node and os.path.exists(node), 'no raw USB node for the brick'
    old = brick.node
    # Bound: a libusb program cannot have the brick.
    assert driver_of(usbdir) == 'lego_nxt_usb'
    try:
        out = ok(ctl('release'))
        assert out == '%s %s: released\n' % (SERIAL, node)
        assert wait_for(lambda: not os.path.exists(old), 5.0), 'the node outlived release'
        assert driver_of(usbdir) is None
        fails(subprocess.run([NXTCTL, '-d', old, 'battery'], capture_output=True, text=True),
              3, 'cannot open ' + old)
        # A libusb program talks to the brick.
        brick.fw.battery_mv = 7111
        prog = LibusbProgram()
        assert prog.mv == 7111
        try:
            # Releasing again is no error; claiming while the program
            # holds the interface is.
            p = subprocess.run([NXTCTL, '-d', node, 'release'], capture_output=True, text=True)
            assert ok(p) == '%s %s: released already, claimed by usbfs\n' % (SERIAL, node)
            p = subprocess.run([NXTCTL, 'claim'], capture_output=True, text=True)
            fails(p, 3, 'claim', node, 'Device or resource busy', 'usbfs')
        finally:
            prog.close()
        assert wait_for(lambda: driver_of(usbdir) is None)
        # claim with no device: the only released NXT.
        p = subprocess.run([NXTCTL, 'claim'], capture_output=True, text=True)
        m = re.fullmatch(r'%s %s: claimed as (/dev/nxt\d+)\n' % (SERIAL, node), ok(p))
        assert m, p.stdout
        brick.node = m.group(1)
        assert os.path.exists(brick.node) and driver_of(usbdir) == 'lego_nxt_usb'
        assert brick.node == nxt.node_of(SERIAL)
        assert int(ok(ctl('battery'))) == 7111
        # Claiming a bound brick says where it is.
        p = subprocess.run([NXTCTL, '-d', node, 'claim'], capture_output=True, text=True)
        assert ok(p) == '%s %s: claimed as %s\n' % (SERIAL, node, brick.node)
        # The other spellings: release by raw node, claim by serial.
        p = subprocess.run([NXTCTL, 'release', '--device=' + node], capture_output=True,
                           text=True)
        assert ok(p) == '%s %s: released\n' % (SERIAL, node)
        p = subprocess.run([NXTCTL, 'claim', '--serial=' + SERIAL.lower()],
                           capture_output=True, text=True)
        brick.node = re.search(r'claimed as (\S+)', ok(p)).group(1)
        p = subprocess.run([NXTCTL, 'release', '--serial', SERIAL], capture_output=True,
                           text=True)
        ok(p)
        p = subprocess.run([NXTCTL, 'claim', '-d', node], capture_output=True, text=True)
        brick.node = re.search(r'claimed as (\S+)', ok(p)).group(1)
        fails(subprocess.run([NXTCTL, 'claim', '--serial=0016530BAD00'],
                             capture_output=True, text=True), 3, 'no released NXT brick with serial')
    finally:
        if driver_of(usbdir) != 'lego_nxt_usb':
            with open(nxt.DRIVER + '/bind', 'w') as f:
                f.write(os.path.basename(usbdir) + ':1.0')
        brick.node = nxt.node_of(SERIAL)
    assert int(ok(ctl('battery'))) == 7111


def test_release_and_claim_without_root(brick, tmp_path):
    """Write access to the raw USB node (the udev rules give it to the
    group lego and to the user at the seat) is all release and claim need."""
    node, usbdir = usb_node(SERIAL)
    nobody = 65534
    bindir = tempfile.mkdtemp(prefix='nxtctl-')
    os.chmod(bindir, 0o755)
    prog = os.path.join(bindir, 'nxtctl')
    shutil.copy(NXTCTL, prog)
    os.chmod(prog, 0o755)
    st = os.stat(node)

    def as_nobody(*args):
        return subprocess.run(['setpriv', '--reuid=%d' % nobody, '--regid=%d' % nobody,
                               '--clear-groups', prog] + list(args),
                              capture_output=True, text=True, timeout=60)
    try:
        os.chmod(node, 0o600)
        fails(as_nobody('-d', brick.node, 'release'), 3, 'cannot open ' + node,
              'Permission denied', 'group lego')
        assert driver_of(usbdir) == 'lego_nxt_usb'
        os.chown(node, st.st_uid, nobody)
        os.chmod(node, 0o660)
        assert ok(as_nobody('-d', brick.node, 'release')) == '%s %s: released\n' % (SERIAL, node)
        assert driver_of(usbdir) is None
        p = as_nobody('claim')
        brick.node = re.search(r'claimed as (\S+)', ok(p)).group(1)
        assert driver_of(usbdir) == 'lego_nxt_usb'
    finally:
        os.chown(node, st.st_uid, st.st_gid)
        os.chmod(node, stat.S_IMODE(st.st_mode))
        shutil.rmtree(bindir)
        if driver_of(usbdir) != 'lego_nxt_usb':
            with open(nxt.DRIVER + '/bind', 'w') as f:
                f.write(os.path.basename(usbdir) + ':1.0')
        brick.node = nxt.node_of(SERIAL)


# The rule Documentation/lego/nxtctl.rst gives for keeping the driver off
# chosen bricks for good.
UDEV_RULE = ('ACTION=="bind", SUBSYSTEM=="usb", ENV{DEVTYPE}=="usb_interface", '
             'DRIVER=="lego_nxt_usb", ATTRS{serial}=="%s", '
             'RUN+="/bin/sh -c \'echo $kernel > /sys/bus/usb/drivers/lego_nxt_usb/unbind\'"\n')


def test_udev_rule_keeps_the_driver_off_a_brick(brick):
    import signal
    udevd = '/lib/systemd/systemd-udevd'
    if not os.access(udevd, os.X_OK):
        pytest.skip('no systemd-udevd')
    with open(DOC) as f:
        assert UDEV_RULE % '001653XXXXXX' in f.read(), 'the page shows another rule'
    rules = '/run/udev/rules.d'
    os.makedirs(rules, exist_ok=True)
    rule = os.path.join(rules, '70-nxt-libusb.rules')
    with open(rule, 'w') as f:
        f.write(UDEV_RULE % SERIAL2)
    log = open('/tmp/nxtctl-udevd.log', 'w+')
    daemon = subprocess.Popen([udevd, '--debug'], stdout=log, stderr=subprocess.STDOUT)
    other = nxt.Brick('dummy_udc.1', SERIAL2)
    try:
        time.sleep(3)          # udevd reads its rules before it listens
        other.fw.battery_mv = 6543
        other.emu.start()
        assert other.emu.wait_configured(15), 'brick not configured'
        node, usbdir = None, None
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            node, usbdir = usb_node(SERIAL2)
            if usbdir and os.path.isdir(os.path.join(usbdir, os.path.basename(usbdir) + ':1.0')) \
                    and driver_of(usbdir) is None:
                break
            time.sleep(0.1)
        if not usbdir or driver_of(usbdir) is not None:
            log.seek(0)
            lines = [x for x in log.read().splitlines() if 'bind' in x or 'RUN' in x or
                     '70-nxt' in x or 'rror' in x]
            raise AssertionError('the rule did not unbind the driver:\n' + '\n'.join(lines[-60:]))
        # Bound a moment: wait for the driver's own node to go too.
        assert wait_for(lambda: not nxt.interface_of(SERIAL2) and
                        len(glob.glob('/dev/nxt[0-9]*')) == 1, 10), glob.glob('/dev/nxt*')
        # The libusb program has it; the other brick stays with the driver.
        prog = LibusbProgram(SERIAL2)
        prog.close()
        assert prog.mv == 6543
        assert nxt.node_of(SERIAL, 1) == brick.node
        # claim cannot beat the rule: the driver is unbound again at once.
        subprocess.run([NXTCTL, 'claim', '--serial=' + SERIAL2], capture_output=True, text=True)
        assert wait_for(lambda: driver_of(usbdir) is None, 10)
    finally:
        other.unplug()
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(20)
        log.close()
        os.unlink(rule)
        assert wait_for(lambda: usb_node(SERIAL2)[1] is None, 10)
