"""tools/nxtctl against the emulated brick (tests/emulator/nxt_brick.py).

Every subcommand runs the binary that tests/build-modules.sh built into
$LEGO_BUILD/tools, on a brick plugged in through dummy_hcd, and the tests
check both what nxtctl prints and what the emulated firmware recorded.
"""
import os
import random
import re
import subprocess
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
            'download', 'ls', 'rm', 'help']


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
])
def test_usage_errors_exit_2(args, words):
    # Checked before the device is opened: no brick needed.
    p = subprocess.run([NXTCTL, '-d', '/dev/nxt-none'] + args, capture_output=True, text=True)
    fails(p, 2, *words)
    assert p.stdout == ''


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
    ok(ctl('reset-motor', 'A'))
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
