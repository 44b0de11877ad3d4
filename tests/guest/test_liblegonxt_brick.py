"""liblegonxt against the emulated brick: every direct and system command
the library builds, sent through /dev/nxtN (NXT_IOC_TRANSACT), its reply
checked (lnxt_reply_check()) and decoded by the library's parser, by the C
program tests/guest/lnxt_every.c; here its lines are compared with what the
emulated firmware (tests/emulator/nxt_brick.py) holds and did."""
import os
import re
import subprocess

import pytest

import nxtdev as nxt

SERIAL = '0016531B0C0D'
SERIAL_BOOT = '0016531B0C0E'

# Every builder of tools/liblegonxt/legonxt.h but BootCommand (its own test),
# and the status the emulated firmware answers it with here.
STATUS = {
    'get_battery_level': 0x00, 'keep_alive': 0x00, 'play_tone': 0x00,
    'play_sound_file': 0xc0,            # no such file
    'stop_sound_playback': 0x00,
    'start_program': 0xc0,              # no such file
    'stop_program': 0xec, 'get_current_program_name': 0xec,   # no program runs
    'message_write': 0xec, 'message_read': 0xec,
    'datalog_set_times': 0x00, 'datalog_read': 0x40,          # the log is empty
    'bt_get_contact_count': 0x00, 'bt_get_contact_name': 0x00,
    'bt_get_conn_count': 0x00, 'bt_get_conn_name': 0x00,
    'set_property': 0x00, 'get_property': 0x00,
    'set_output_state': 0x00, 'get_output_state': 0x00, 'reset_motor_position': 0x00,
    'update_reset_count': 0x00, 'set_input_mode': 0x00, 'get_input_values': 0x00,
    'reset_input_scaled_value': 0x00, 'set_input_mode_lowspeed': 0x00,
    'ls_write': 0x00, 'ls_get_status': 0x00, 'ls_read': 0x00,
    'get_versions': 0x00, 'set_brick_name': 0x00, 'get_device_info': 0x00,
    'get_bt_address': 0x00, 'open_write': 0x00, 'write': 0x00, 'close': 0x00,
    'open_write_linear': 0x00, 'open_write_data': 0x00, 'open_append_data': 0x00,
    'crop_data_file': 0x00, 'open_read': 0x00, 'read': 0x00, 'find_first': 0x00,
    'find_next': 0x00, 'delete': 0x00, 'find_first_module': 0x00, 'read_io_map': 0x00,
    'write_io_map': 0x00, 'find_next_module': 0x00, 'close_module_handle': 0x00,
    'poll_command_length': 0x00, 'poll_command': 0x00, 'delete_user_flash': 0x00,
    'bt_factory_reset': 0x00,
}
# While the port and the sensor get ready: pending, busy.
RETRY = {'ls_write': {0x20, 0xe0}, 'ls_get_status': {0x20, 0xe0}}


@pytest.fixture(scope='module')
def every(tmp_path_factory):
    """lnxt_every, built from the library's sources as the tools build it."""
    out = str(tmp_path_factory.mktemp('lnxt') / 'lnxt_every')
    lib = os.path.join(nxt.TOP, 'tools', 'liblegonxt')
    subprocess.run(['cc', '-O2', '-Wall', '-Wextra', '-Werror',
                    '-I', os.path.join(nxt.TOP, 'include', 'uapi'), '-I', lib,
                    os.path.join(nxt.TOP, 'tests', 'guest', 'lnxt_every.c'),
                    os.path.join(lib, 'legonxt.c'), '-o', out], check=True)
    return out


def run_every(every, node, *args):
    p = subprocess.run([every, node] + list(args), capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, (p.returncode, p.stdout, p.stderr)
    assert p.stderr == '', p.stderr
    return [ln.split() for ln in p.stdout.splitlines()]


def test_builders_are_all_covered():
    """The table above names a command for every builder of the header."""
    with open(os.path.join(nxt.TOP, 'tools', 'liblegonxt', 'legonxt.h')) as f:
        header = f.read()
    builders = set(re.findall(r'^(?:int|void) lnxt_(\w+)\(struct lnxt_msg \*m\b', header, re.M))
    with open(os.path.join(nxt.TOP, 'tests', 'guest', 'lnxt_every.c')) as f:
        used = set(re.findall(r'lnxt_(\w+)\(&m\b', f.read()))
    assert builders - {'no_reply'} <= used, builders - used
    assert 'boot_command' in used


def test_every_command(brick, every):
    lines = run_every(every, brick.node)
    got = {}
    for ln in lines:
        name, status = ln[0], int(ln[1], 16)
        if status in RETRY.get(name, ()):
            continue
        assert STATUS.get(name) == status, (name, hex(status), lines)
        got.setdefault(name, []).append(ln[2:])
    assert set(got) == set(STATUS), set(STATUS) ^ set(got)

    fw = brick.fw
    assert got['get_battery_level'] == [['mv=%d' % fw.battery_mv]]
    assert got['get_versions'][0][1] == 'firmware=1.29'
    assert got['get_device_info'] == [['name=every', SERIAL.lower()]]
    assert got['get_bt_address'] == [[SERIAL.lower()]]
    assert got['get_output_state'] == [['port=1', 'power=40', 'mode=1', 'limit=90']]
    assert got['get_input_values'] == [['port=0', 'type=1', 'mode=32']]
    assert got['get_property'] == [['value=2']] and fw.volume == 2
    # The ultrasonic sensor's distance register, one byte.
    assert got['ls_read'] == [['%02x' % fw.ultrasonic.distance]], got['ls_read']
    # The files: written, read back, found, the data file cropped, one deleted.
    assert got['read'] == [['0123456789'.encode().hex()]]
    assert got['open_read'] == [['size=10']]
    assert got['find_first'] == [['every.txt', 'size=10']]
    assert got['find_next'][0][0] in ('every.rxe', 'every.rdt')
    assert got['open_append_data'] == [['handle=0', 'room=12']]
    assert got['write'] == [['written=10'], ['written=4'], ['written=4']]
    assert got['find_first_module'][0][0].endswith('.mod')
    assert got['write_io_map'] == [['written=2']]
    # DeleteUserFlash came last but for BTFactoryReset: nothing left.
    assert fw.files == {} and fw.handles == {}


def test_boot_command(every):
    """BootCommand: "Yes", then the brick leaves for SAM-BA (the emulator
    unplugs it) and its node goes."""
    b = nxt.Brick('dummy_udc.1', SERIAL_BOOT)     # the module's brick is on .0
    b.plug()
    try:
        lines = run_every(every, b.node, 'boot')
        assert lines == [['boot_command', '00', b'Yes\0'.hex()]], lines
        assert b.wait_gone(10), 'the node outlived the reboot'
    finally:
        b.unplug()
