"""lego_nxt_usb against the emulated brick (tests/emulator/nxt_brick.py).

The brick is a raw-gadget device on dummy_hcd, so the driver binds it as it
binds a real one: the tests go through /dev/nxtN, its ioctls and sysfs.
"""
import ctypes
import errno
import glob
import os
import re
import select
import shutil
import signal
import stat
import struct
import subprocess
import threading
import time

import pytest

import conftest
import nxtdev as nxt
from conftest import module_path

SERIAL = '001653A0B1C2'
SERIAL2 = '0016530D0E0F'
STALL_ROUNDS = 30
# The driver's attributes (Documentation/ABI/testing/sysfs-class-lego-nxt).
SYSFS_ATTRS = ('battery_mv', 'firmware_version', 'protocol_version', 'brick_name',
               'bt_address', 'free_flash')
VERSIONS_REPLY = b'\x02\x88\x00\x7c\x01\x1d\x01'     # firmware 1.29


@pytest.fixture
def fd(brick):
    f = brick.open()
    yield f
    os.close(f)


def test_alias_matches_only_interface_0():
    out = subprocess.run(['modinfo', '-F', 'alias', module_path('lego_nxt_usb')],
                         capture_output=True, text=True, check=True).stdout.split()
    assert len(out) == 1
    assert out[0].startswith('usb:v0694p0002d')
    assert re.search(r'in00\*?$', out[0]), out[0]


def test_uapi_layout_matches_the_header():
    c = nxt.uapi_layout()
    assert c.pop('transaction') == nxt.struct_size('transaction') == 136
    assert (c.pop('transaction.reply'), c.pop('transaction.length'),
            c.pop('transaction.reply_length')) == (64, 128, 132)
    for name in ('TRANSACT', 'SET_TIMEOUT', 'GET_TIMEOUT', 'TTY_MINOR'):
        assert c.pop(name) == nxt.ioctl_number(name), name
    # Telegrams only: nothing typed is left in the header.
    assert not c, c


def test_binds_interface_0_with_node_and_serial(brick):
    intf = brick.interface()
    assert intf.endswith(':1.0')
    assert nxt.attr(intf + '/..', 'serial') == SERIAL
    assert os.path.basename(brick.node).startswith('nxt')
    st = os.stat(brick.node)
    # The driver's own char device and class, whatever the link.
    node = nxt.node_dir(intf)
    assert node == os.path.realpath('/sys/class/lego-nxt/' + os.path.basename(brick.node))
    assert nxt.attr(node, 'dev') == '%d:%d' % (os.major(st.st_rdev), os.minor(st.st_rdev))
    assert os.path.realpath(os.path.join(node, 'device')) == intf
    # Nothing of the driver's is left on the USB interface.
    assert not os.path.exists(os.path.join(intf, 'battery_mv'))
    assert not os.path.exists(os.path.join(intf, 'usbmisc'))


def ask_brick_info(fd):
    """What a user of the brick asks that fills the sysfs attributes."""
    assert nxt.transact(fd, b'\x01\x88')[0] == 0
    assert nxt.transact(fd, b'\x01\x9b')[0] == 0
    nxt.ok(fd, 'GET_BATTERY_LEVEL')


def test_sysfs_attributes(brick, fd):
    intf = brick.interface()
    ask_brick_info(fd)
    assert nxt.attr(nxt.node_dir(intf), 'firmware_version') == '1.29'
    assert nxt.attr(nxt.node_dir(intf), 'protocol_version') == '1.124'
    assert nxt.attr(nxt.node_dir(intf), 'brick_name') == 'NXT'
    assert nxt.attr(nxt.node_dir(intf), 'bt_address') == '00:16:53:a0:b1:c2'
    assert int(nxt.attr(nxt.node_dir(intf), 'battery_mv')) == brick.fw.battery_mv
    assert int(nxt.attr(nxt.node_dir(intf), 'free_flash')) == brick.fw.free_flash
    # The last reading a user got, however old: a new one shows once a
    # user asks again, by any way (here write() and read()).
    old = brick.fw.battery_mv
    brick.fw.battery_mv = old - 100
    try:
        time.sleep(1.1)
        assert int(nxt.attr(nxt.node_dir(intf), 'battery_mv')) == old
        os.write(fd, b'\x00\x0b')
        assert os.read(fd, 64)[:3] == b'\x02\x0b\x00'
        assert int(nxt.attr(nxt.node_dir(intf), 'battery_mv')) == old - 100
    finally:
        brick.fw.battery_mv = old


def test_sysfs_name_follows_set_brick_name(brick, fd):
    intf = brick.interface()
    ask_brick_info(fd)
    assert nxt.attr(nxt.node_dir(intf), 'brick_name') == 'NXT'
    err, reply = nxt.transact(fd, b'\x01\x98' + b'Robby'.ljust(16, b'\0'))
    assert (err, reply) == (0, b'\x02\x98\x00')
    try:
        # Renamed: unknown until a user asks the brick again.
        for name in ('brick_name', 'bt_address', 'free_flash'):
            with pytest.raises(OSError) as e:
                nxt.attr(nxt.node_dir(intf), name)
            assert e.value.errno == errno.ENODATA, name
        assert nxt.attr(nxt.node_dir(intf), 'firmware_version') == '1.29'
        assert nxt.transact(fd, b'\x01\x9b')[0] == 0
        assert nxt.attr(nxt.node_dir(intf), 'brick_name') == 'Robby'
    finally:
        nxt.transact(fd, b'\x01\x98' + b'NXT'.ljust(16, b'\0'))
    assert nxt.transact(fd, b'\x01\x9b')[0] == 0
    assert nxt.attr(nxt.node_dir(intf), 'brick_name') == 'NXT'


def test_raw_write_read(fd):
    assert os.write(fd, b'\x00\x0b') == 2
    reply = os.read(fd, 64)
    assert reply[:3] == b'\x02\x0b\x00' and len(reply) == 5
    # No reply is asked for: nothing to read.
    assert os.write(fd, b'\x80\x03\xb8\x01\x10\x00') == 6
    with pytest.raises(OSError) as e:
        os.read(fd, 64)
    assert e.value.errno == errno.ENODATA


def test_raw_lengths_and_types(fd):
    for bad, err in ((b'\x00', errno.EINVAL), (b'\x00\x0b' + bytes(63), errno.EMSGSIZE),
                     (b'\x02\x0b', errno.EINVAL), (b'\x42\x0b', errno.EINVAL)):
        with pytest.raises(OSError) as e:
            os.write(fd, bad)
        assert e.value.errno == err, bad.hex()
    # 64 bytes is one packet: fine (MessageWrite of 59 bytes with its NUL).
    msg = b'\x80\x09\x00\x3b' + b'm' * 58 + b'\0'
    assert len(msg) == 63
    assert os.write(fd, msg + b'') == 63


def test_short_read_buffer_keeps_the_reply(fd):
    os.write(fd, b'\x01\x88')
    with pytest.raises(OSError) as e:
        os.read(fd, 4)
    assert e.value.errno == errno.EMSGSIZE
    assert os.read(fd, 64) == VERSIONS_REPLY


def test_unknown_opcode_reply(fd):
    os.write(fd, b'\x00\x30')
    assert os.read(fd, 64) == b'\x02\x30\xbe'


def test_poll_and_nonblock(brick):
    f = brick.open(os.O_RDWR | os.O_NONBLOCK)
    try:
        p = select.poll()
        p.register(f, select.POLLIN | select.POLLOUT)
        # Not at once if this open started the reader: it drains 20 ms.
        assert dict(p.poll(1000)).get(f, 0) & select.POLLOUT
        with pytest.raises(OSError) as e:
            os.read(f, 64)
        assert e.value.errno == errno.ENODATA
        os.write(f, b'\x00\x0b')
        ready = dict(p.poll(2000)).get(f, 0)
        assert ready & select.POLLIN
        assert os.read(f, 64)[:3] == b'\x02\x0b\x00'
    finally:
        os.close(f)


def test_replies_stay_with_their_file(brick):
    a, b = brick.open(), brick.open()
    try:
        os.write(a, b'\x01\x88')
        os.write(b, b'\x00\x0b')
        assert os.read(b, 64)[:2] == b'\x02\x0b'
        assert os.read(a, 64)[:2] == b'\x02\x88'
    finally:
        os.close(a)
        os.close(b)


def test_timeout_ioctls(fd):
    assert nxt.get_timeout(fd) == 1000
    assert nxt.set_timeout(fd, 250) == 0
    assert nxt.get_timeout(fd) == 250
    assert nxt.set_timeout(fd, 0) == errno.EINVAL
    assert nxt.set_timeout(fd, 60001) == errno.EINVAL
    assert nxt.get_timeout(fd) == 250


def test_unknown_ioctl_is_enotty(fd):
    _, err, _ = nxt.raw_ioctl(fd, nxt.iowr(0x7f, 4), bytes(4))
    assert err == errno.ENOTTY
    # NXT_IOC_TRANSACT's number with another size is not NXT_IOC_TRANSACT.
    _, err, _ = nxt.raw_ioctl(fd, nxt.iowr(0x00, 8), bytes(8))
    assert err == errno.ENOTTY


def test_transact_system_commands_and_file_upload(brick, fd):
    err, reply = nxt.transact(fd, b'\x01\x88')
    assert (err, reply) == (0, VERSIONS_REPLY)
    # A reply-less telegram gives an empty reply.
    assert nxt.transact(fd, b'\x80\x0d') == (0, b'')

    program = bytes(range(256)) * 2 + b'end'
    name = nxt.name20('upload.rxe')
    err, reply = nxt.transact(fd, b'\x01\x81' + name + struct.pack('<I', len(program)))
    assert err == 0 and reply[:3] == b'\x02\x81\x00', reply.hex()
    handle = reply[3]
    for i in range(0, len(program), 61):
        chunk = program[i:i + 61]
        err, reply = nxt.transact(fd, b'\x01\x83' + bytes([handle]) + chunk)
        assert err == 0 and reply[2] == 0 and struct.unpack_from('<H', reply, 4)[0] == len(chunk)
    assert nxt.transact(fd, b'\x01\x84' + bytes([handle]))[1][:3] == b'\x02\x84\x00'
    assert bytes(brick.fw.files['upload.rxe'].data) == program

    err, reply = nxt.transact(fd, b'\x01\x86' + nxt.name20('*.rxe'))
    assert err == 0 and reply[2] == 0
    found = {nxt.cstr(reply[4:24])}
    while True:
        err, reply = nxt.transact(fd, b'\x01\x87' + bytes([reply[3]]))
        if reply[2] != 0:
            assert reply[2] == 0x87     # the firmware's end of the search
            break
        found.add(nxt.cstr(reply[4:24]))
    assert 'upload.rxe' in found

    # Read it back, 58 bytes at a time (what fits a USB reply).
    err, reply = nxt.transact(fd, b'\x01\x80' + name)
    assert err == 0 and reply[2] == 0
    handle, size = reply[3], struct.unpack_from('<I', reply, 4)[0]
    assert size == len(program)
    data = b''
    while len(data) < size:
        n = min(58, size - len(data))
        err, reply = nxt.transact(fd, b'\x01\x82' + bytes([handle]) + struct.pack('<H', n))
        assert err == 0 and reply[2] == 0 and len(reply) == 6 + n
        data += reply[6:]
    nxt.transact(fd, b'\x01\x84' + bytes([handle]))
    assert data == program

    # Start it, see it run, stop it; then delete it. The firmware stops a
    # program a moment after it has answered StopProgram, and a running
    # program's file is busy (0x8B): wait until no program runs.
    assert nxt.ok(fd, 'START_PROGRAM', name=name)['status'] == 0
    assert nxt.cstr(wait_program(fd, True)['name']) == 'upload.rxe'
    nxt.ok(fd, 'STOP_PROGRAM')
    wait_program(fd, False)
    err, reply = nxt.transact(fd, b'\x01\x85' + name)
    assert err == 0 and reply[2] == 0
    assert 'upload.rxe' not in brick.fw.files


def wait_program(fd, running, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        err, out = nxt.command(fd, 'GET_CURRENT_PROGRAM_NAME')
        assert err == 0, errno.errorcode.get(err, err)
        if (out['status'] == 0) == running:
            return out
        time.sleep(0.05)
    raise AssertionError('program %s' % ('never started' if running else 'still running'))


def test_program_and_sound_commands(brick, fd):
    # No program: the brick's status comes back as data, and the call succeeds.
    err, out = nxt.command(fd, 'STOP_PROGRAM')
    assert (err, out['status']) == (0, nxt.STATUS_NO_PROGRAM)
    err, out = nxt.command(fd, 'GET_CURRENT_PROGRAM_NAME')
    assert (err, out['status'], out['name']) == (0, nxt.STATUS_NO_PROGRAM, bytes(20))
    # A missing program is the firmware's out-of-range status.
    err, out = nxt.command(fd, 'START_PROGRAM', name=nxt.name20('nothere.rxe'))
    assert (err, out['status']) == (0, nxt.STATUS_OUT_OF_RANGE)

    nxt.ok(fd, 'START_PROGRAM', name=nxt.name20('Demo.rxe'))
    assert nxt.cstr(wait_program(fd, True)['name']) == 'Demo.rxe'

    nxt.ok(fd, 'PLAY_TONE', frequency=440, duration=200)
    assert brick.fw.sound[:2] == ('tone', 440)
    nxt.ok(fd, 'PLAY_SOUND_FILE', name=nxt.name20('Woops.rso'), loop=1)
    assert brick.fw.sound == ('file', 'Woops.rso', 1)
    nxt.ok(fd, 'STOP_SOUND_PLAYBACK')
    assert brick.fw.sound is None
    err, out = nxt.command(fd, 'PLAY_SOUND_FILE', name=nxt.name20('none.rso'))
    assert (err, out['status']) == (0, nxt.STATUS_OUT_OF_RANGE)

    # Mailboxes, both ways.
    msg = b'hello brick\0'
    nxt.ok(fd, 'MESSAGE_WRITE', inbox=3, size=len(msg), data=msg)
    assert brick.fw.program_receive(3) == msg
    err, out = nxt.command(fd, 'MESSAGE_READ', inbox=12, local_inbox=2, remove=1)
    assert (err, out['status']) == (0, nxt.STATUS_MAILBOX_EMPTY)
    brick.fw.program_send(12, b'from the program')
    out = nxt.ok(fd, 'MESSAGE_READ', inbox=12, local_inbox=2, remove=1)
    assert out['data'][:out['size']] == b'from the program\0'
    assert out['data'][out['size']:] == bytes(59 - out['size'])

    nxt.ok(fd, 'STOP_PROGRAM')
    wait_program(fd, False)


def test_motor_commands(brick, fd):
    out = nxt.ok(fd, 'SET_OUTPUT_STATE', port=1, power=50, mode=0x05, regulation_mode=1,
                 run_state=0x20, tacho_limit=0)
    assert out['status'] == 0
    t0 = nxt.ok(fd, 'GET_OUTPUT_STATE', port=1)
    assert (t0['power'], t0['mode'], t0['regulation_mode'], t0['run_state']) == (50, 5, 1, 0x20)
    time.sleep(0.3)
    t1 = nxt.ok(fd, 'GET_OUTPUT_STATE', port=1)
    assert t1['tacho_count'] > t0['tacho_count']
    assert t1['rotation_count'] > t0['rotation_count']
    nxt.ok(fd, 'RESET_MOTOR_POSITION', port=1, relative=0)
    nxt.ok(fd, 'SET_OUTPUT_STATE', port=1, power=0, mode=0, run_state=0)
    t2 = nxt.ok(fd, 'GET_OUTPUT_STATE', port=1)
    assert abs(t2['rotation_count']) < t1['rotation_count']
    # A limited run stops at its limit.
    nxt.ok(fd, 'SET_OUTPUT_STATE', port=0, power=-100, mode=1, run_state=0x20, tacho_limit=90)
    time.sleep(0.3)
    t3 = nxt.ok(fd, 'GET_OUTPUT_STATE', port=0)
    assert t3['tacho_count'] == -90 and t3['run_state'] == 0


def test_sensor_commands(brick, fd):
    nxt.ok(fd, 'SET_INPUT_MODE', port=0, type=0x01, mode=0x20)
    brick.fw.set_touch(0, True)
    deadline = time.monotonic() + 2
    while True:
        v = nxt.ok(fd, 'GET_INPUT_VALUES', port=0)
        if v['valid'] or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    assert (v['valid'], v['type'], v['mode'], v['scaled']) == (1, 0x01, 0x20, 1)
    brick.fw.set_touch(0, False)
    assert nxt.ok(fd, 'GET_INPUT_VALUES', port=0)['scaled'] == 0
    nxt.ok(fd, 'RESET_INPUT_SCALED_VALUE', port=0)
    assert nxt.ok(fd, 'KEEP_ALIVE')['sleep_limit'] == 600000
    assert nxt.ok(fd, 'GET_BATTERY_LEVEL')['millivolts'] == brick.fw.battery_mv


def test_ultrasonic_over_i2c(brick, fd):
    brick.fw.ultrasonic.distance = 42
    nxt.ok(fd, 'SET_INPUT_MODE', port=3, type=0x0b, mode=0x00)
    time.sleep(0.2)
    nxt.ok(fd, 'LS_WRITE', port=3, tx_length=2, rx_length=1, tx_data=b'\x02\x42')
    deadline = time.monotonic() + 2
    pending = 0
    while True:
        err, st = nxt.command(fd, 'LS_GET_STATUS', port=3)
        if err or st['status'] != nxt.STATUS_PENDING or time.monotonic() > deadline:
            break
        pending += 1
        time.sleep(0.002)
    assert (err, st['status'], st['bytes_ready']) == (0, 0, 1)
    r = nxt.ok(fd, 'LS_READ', port=3)
    assert (r['length'], r['data'][0]) == (1, 42)
    assert r['data'][1:] == bytes(15)
    # The product string, eight bytes from register 0x08.
    nxt.ok(fd, 'LS_WRITE', port=3, tx_length=2, rx_length=8, tx_data=b'\x02\x08')
    time.sleep(0.05)
    r = nxt.ok(fd, 'LS_READ', port=3)
    assert r['data'][:r['length']].rstrip(b'\0') == b'LEGO'
    # A port that is not low-speed: the firmware's "channel busy".
    err, r = nxt.command(fd, 'LS_READ', port=1)
    assert (err, r['status'], r['length']) == (0, nxt.STATUS_CHANNEL_BUSY, 0)


def test_i2c_pending_is_a_status_not_an_errno(brick, fd):
    """The brick's "pending" (0x20) is a reply like any other: the call
    succeeds and the status is in it. EAGAIN is only O_NONBLOCK's "busy,
    nothing sent", and then the argument is not written."""
    nxt.ok(fd, 'SET_INPUT_MODE', port=3, type=0x0b, mode=0x00)
    time.sleep(0.2)
    clock = brick.fw.now
    frozen = clock()
    brick.fw.now = lambda: frozen         # the I2C transfer never ends
    try:
        nxt.ok(fd, 'LS_WRITE', port=3, tx_length=2, rx_length=1, tx_data=b'\x02\x42')
        err, reply = nxt.transact(fd, nxt.telegram('LS_GET_STATUS', port=3))
        assert (err, reply) == (0, bytes([0x02, 0x0e, nxt.STATUS_PENDING, 0]))
    finally:
        brick.fw.now = clock
    deadline = time.monotonic() + 2
    while nxt.command(fd, 'LS_GET_STATUS', port=3)[1]['status'] == nxt.STATUS_PENDING:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    nxt.ok(fd, 'LS_READ', port=3)

    busy = brick.open(os.O_RDWR | os.O_NONBLOCK)
    try:
        assert nxt.set_timeout(fd, 5000) == 0
        os.write(fd, b'\x01\xa0')                  # DeleteUserFlash: about 1 s
        arg = nxt.pack('transaction', telegram=b'\x00\x0b', reply=b'\x55' * 64,
                       length=2, reply_length=0x55)
        _, err, out = nxt.raw_ioctl(busy, nxt.ioctl_number('TRANSACT'), arg)
        assert errno.errorcode.get(err, err) == 'EAGAIN'
        assert out == arg, 'the argument was written on EAGAIN'
        assert os.read(fd, 64) == b'\x02\xa0\x00'
    finally:
        os.close(busy)


def test_arguments_are_the_bricks_to_check(brick, fd):
    """The driver checks only that a telegram holds what its command reads;
    the ranges of the arguments are the brick's (and liblegonxt's) to check.
    An out-of-range port reaches the brick, which answers with its status."""
    before = brick.emu.commands
    for name, fields in [('GET_OUTPUT_STATE', dict(port=3)),
                         ('GET_INPUT_VALUES', dict(port=4)),
                         ('SET_INPUT_MODE', dict(port=4, type=1)),
                         ('SET_OUTPUT_STATE', dict(port=3, power=10, mode=1, run_state=0x20))]:
        err, out = nxt.command(fd, name, **fields)
        assert (err, out['status']) == (0, nxt.STATUS_OUT_OF_RANGE), (name, fields)
    assert brick.emu.commands == before + 4
    # A count that announces more bytes than the telegram holds: the
    # firmware would send stale ones, so the driver refuses it.
    for name, fields in [('LS_WRITE', dict(port=0, tx_length=17, rx_length=1)),
                         ('MESSAGE_WRITE', dict(inbox=0, size=3, data=b'ab')),
                         ('START_PROGRAM', dict(name=b'x' * 20))]:
        err, _ = nxt.command(fd, name, **fields)
        assert err == errno.EINVAL, (name, fields)
    assert brick.emu.commands == before + 4, 'an incomplete telegram reached the brick'


def test_stale_reply_after_timeout_is_drained(brick, fd):
    # DeleteUserFlash takes the brick about a second; with a 200 ms
    # timeout its reply comes late, and must not answer the next command.
    assert nxt.set_timeout(fd, 200) == 0
    t0 = time.monotonic()
    err, _ = nxt.transact(fd, b'\x01\xa0')
    assert err == errno.ETIMEDOUT
    assert time.monotonic() - t0 < 0.6
    assert nxt.set_timeout(fd, 3000) == 0
    for _ in range(3):
        err, reply = nxt.transact(fd, b'\x01\x88')
        assert (err, reply) == (0, VERSIONS_REPLY)
    assert nxt.ok(fd, 'GET_BATTERY_LEVEL')['millivolts'] == brick.fw.battery_mv


def erase_replies(brick):
    return sum(1 for _, what in list(brick.emu.events)
               if what.startswith('reply collected 02a0'))


def test_late_reply_of_slow_command_answers_nothing(brick, fd):
    """DeleteUserFlash, timed out: its reply comes about a second later.
    The same command sent again must get its own reply, not that one: the
    driver waits for the late reply (up to 3 s) before sending it."""
    before = erase_replies(brick)
    assert nxt.set_timeout(fd, 200) == 0
    err, _ = nxt.transact(fd, b'\x01\xa0')
    assert err == errno.ETIMEDOUT
    assert nxt.set_timeout(fd, 3000) == 0
    err, reply = nxt.transact(fd, b'\x01\xa0')
    assert (err, reply) == (0, b'\x02\xa0\x00')
    # Both replies have come out of the brick by the time the second
    # transaction ends, and none is left to answer anything else.
    deadline = time.monotonic() + 0.3
    while erase_replies(brick) < before + 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert erase_replies(brick) == before + 2
    err, reply = nxt.transact(fd, b'\x01\x88')
    assert (err, reply) == (0, VERSIONS_REPLY)


def test_nonblocking_write_does_not_wait_for_a_drain(brick, fd):
    """After a timeout the driver drains the late reply before it sends
    anything; an O_NONBLOCK write() gets EAGAIN then instead of sleeping."""
    assert nxt.set_timeout(fd, 200) == 0
    err, _ = nxt.transact(fd, b'\x01\xa0')       # its reply comes ~0.8 s late
    assert err == errno.ETIMEDOUT
    f = brick.open(os.O_RDWR | os.O_NONBLOCK)
    try:
        t0 = time.monotonic()
        with pytest.raises(OSError) as e:
            os.write(f, b'\x00\x0b')
        assert e.value.errno == errno.EAGAIN
        assert time.monotonic() - t0 < 0.5         # the drain lasts ~0.8 s
    finally:
        os.close(f)
    assert nxt.set_timeout(fd, 3000) == 0
    assert nxt.transact(fd, b'\x01\x88') == (0, VERSIONS_REPLY)


def test_signal_before_sending_restarts_the_call(brick, fd):
    """A signal that comes while an ioctl waits for the brick, before its
    telegram is sent: with SA_RESTART the call goes on (ERESTARTSYS), it
    does not fail with EINTR."""
    got = []
    old = signal.signal(signal.SIGUSR1, lambda signum, frame: got.append(signum))
    signal.siginterrupt(signal.SIGUSR1, False)
    g = brick.open()
    try:
        assert nxt.set_timeout(fd, 5000) == 0
        os.write(fd, b'\x01\xa0')                  # holds the brick about 1 s
        me = threading.get_ident()
        threading.Timer(0.2, signal.pthread_kill, (me, signal.SIGUSR1)).start()
        t0 = time.monotonic()
        err, out = nxt.command(g, 'GET_BATTERY_LEVEL')
        assert time.monotonic() - t0 > 0.2
        assert got == [signal.SIGUSR1]
        assert (errno.errorcode.get(err, err), out['millivolts']) == (0, brick.fw.battery_mv)
        assert os.read(fd, 64) == b'\x02\xa0\x00'
    finally:
        signal.signal(signal.SIGUSR1, old)
        os.close(g)


def test_waiters_get_the_brick_in_order(brick, fd):
    # DeleteUserFlash holds the brick for about a second; clients that come
    # meanwhile must get it in the order they came, whatever the scheduler
    # wakes first.
    assert nxt.set_timeout(fd, 5000) == 0
    t0 = time.monotonic()
    os.write(fd, b'\x01\xa0')

    replies = {}

    def client(index, f):
        os.write(f, bytes([0x00, 0x07, index]))     # GetInputValues, port index
        replies[index] = os.read(f, 64)

    files = [brick.open() for _ in range(4)]
    threads = []
    try:
        for i, f in enumerate(files):
            t = threading.Thread(target=client, args=(i, f))
            t.start()
            threads.append(t)
            time.sleep(0.15)        # each one surely waiting before the next
        assert os.read(fd, 64)[:3] == b'\x02\xa0\x00'
        for t in threads:
            t.join(10)
        assert not any(t.is_alive() for t in threads)
    finally:
        for f in files:
            os.close(f)
    for i in range(4):
        assert replies.get(i, b'')[:4] == bytes([0x02, 0x07, 0x00, i])
    # The order the brick received them in.
    order = [bytes.fromhex(what.split()[1])[2] for t, what in list(brick.emu.events)
             if t > t0 and what.startswith('command 0007')]
    assert order == [0, 1, 2, 3]


def test_eight_processes_thousand_transactions_each(brick):
    import multiprocessing
    ctx = multiprocessing.get_context('fork')
    q = ctx.Queue()
    start = ctx.Event()
    n = int(os.environ.get('LEGO_NXT_TRANSACTIONS', '1000'))
    procs = [ctx.Process(target=nxt.mixed_client, args=(brick.node, i, n, start, q))
             for i in range(8)]
    for p in procs:
        p.start()
    # Let the children settle (copy-on-write faults are slow under TCG).
    time.sleep(2)
    before = brick.emu.commands
    t0 = time.monotonic()
    start.set()
    results = [q.get(timeout=1200) for _ in procs]
    for p in procs:
        p.join(30)
        assert p.exitcode == 0
    elapsed = time.monotonic() - t0
    print('8 x %d transactions in %.1f s (%.0f/s)' % (n, elapsed, 8 * n / elapsed))
    assert sorted(i for i, _ in results) == list(range(8))
    assert all(b == 0 for _, b in results), results
    assert brick.emu.commands - before == 8 * n


def usbfs_path(intf):
    dev = os.path.dirname(intf)
    with open(os.path.join(dev, 'busnum')) as f:
        bus = int(f.read())
    with open(os.path.join(dev, 'devnum')) as f:
        num = int(f.read())
    return '/dev/bus/usb/%03d/%03d' % (bus, num)


def test_stale_reply_drained_on_open(brick):
    """A libusb program left a reply in the brick; the driver must not take it."""
    import fcntl
    intf = brick.interface()
    name = os.path.basename(intf)
    with open(nxt.DRIVER + '/unbind', 'w') as f:
        f.write(name)
    try:
        usbfs = os.open(usbfs_path(intf), os.O_RDWR)
        try:
            USBDEVFS_CLAIMINTERFACE = (2 << 30) | (4 << 16) | (ord('U') << 8) | 15
            fcntl.ioctl(usbfs, USBDEVFS_CLAIMINTERFACE, struct.pack('I', 0))
            before = brick.emu.commands
            data = ctypes.create_string_buffer(b'\x00\x0d', 2)
            bulk = struct.pack('IIIxxxxQ', 0x01, 2, 1000, ctypes.addressof(data))
            USBDEVFS_BULK = (3 << 30) | (len(bulk) << 16) | (ord('U') << 8) | 2
            fcntl.ioctl(usbfs, USBDEVFS_BULK, bulk)
            deadline = time.monotonic() + 5
            while brick.emu.commands == before and time.monotonic() < deadline:
                time.sleep(0.01)
        finally:
            os.close(usbfs)
        # The queued reply says 600000 ms; from now on the brick says 300000.
        brick.fw.sleep_minutes = 5
    finally:
        with open(nxt.DRIVER + '/bind', 'w') as f:
            f.write(name)
    try:
        brick.node = nxt.node_of(brick.serial)
        f = brick.open()
        try:
            assert nxt.ok(f, 'KEEP_ALIVE')['sleep_limit'] == 300000
        finally:
            os.close(f)
    finally:
        brick.fw.sleep_minutes = 10


def test_usb_reset_keeps_the_driver_bound(brick, fd):
    intf = brick.interface()
    usbfs = os.open(usbfs_path(intf), os.O_RDWR)
    try:
        USBDEVFS_RESET = (0 << 30) | (ord('U') << 8) | 20
        import fcntl
        fcntl.ioctl(usbfs, USBDEVFS_RESET, 0)
    finally:
        os.close(usbfs)
    assert brick.emu.wait_configured(10)
    assert brick.interface() == intf
    assert nxt.wait_versions(fd, 5) == (0, VERSIONS_REPLY)


def test_two_bricks_at_once(brick):
    # The second one with the firmware's 1 ms scheduler tick (nxt_brick.py).
    other = nxt.Brick('dummy_udc.1', SERIAL2, name='Second', tick=0.001)
    other.plug()
    try:
        assert other.node != brick.node
        a, b = brick.open(), other.open()
        try:
            assert nxt.transact(b, b'\x01\x9b')[0] == 0
            assert nxt.attr(nxt.node_dir(other.interface()), 'bt_address') == '00:16:53:0d:0e:0f'
            assert nxt.attr(nxt.node_dir(other.interface()), 'brick_name') == 'Second'
            for _ in range(50):
                assert nxt.ok(a, 'GET_BATTERY_LEVEL')['millivolts'] == brick.fw.battery_mv
                nxt.ok(b, 'SET_OUTPUT_STATE', port=2, power=20, mode=1, run_state=0x20)
            assert other.fw.motors[2].power == 20
            assert brick.fw.motors[2].power == 0
        finally:
            os.close(a)
            os.close(b)
    finally:
        other.unplug()
        assert other.wait_gone()


def test_unplug_during_io():
    b = nxt.Brick('dummy_udc.1', SERIAL2, tick=0.001)   # the firmware's 1 ms tick
    b.plug()
    f = b.open()
    errors = []
    stop = threading.Event()

    def hammer():
        g = b.open()
        try:
            while not stop.is_set():
                err, _ = nxt.transact(g, b'\x01\x9b')
                if err:
                    errors.append(err)
                    if err == errno.ENODEV:
                        break
        finally:
            os.close(g)

    threads = [threading.Thread(target=hammer) for _ in range(3)]
    for t in threads:
        t.start()
    time.sleep(0.5)
    b.unplug()
    for t in threads:
        t.join(10)
    stop.set()
    assert not any(t.is_alive() for t in threads)
    assert errors and errors[-1] == errno.ENODEV, errors
    # The open file outlives the brick: everything fails with ENODEV.
    p = select.poll()
    p.register(f, select.POLLIN)
    assert dict(p.poll(1000)).get(f, 0) & select.POLLHUP
    with pytest.raises(OSError) as e:
        os.write(f, b'\x00\x0b')
    assert e.value.errno == errno.ENODEV
    assert nxt.command(f, 'GET_BATTERY_LEVEL')[0] == errno.ENODEV
    os.close(f)
    assert b.wait_gone()
    # Plugged in again, it works again.
    b.plug()
    g = b.open()
    assert nxt.ok(g, 'KEEP_ALIVE')['sleep_limit'] == 600000
    os.close(g)
    b.unplug()
    assert b.wait_gone()


def test_every_stall_is_reported():
    """A brick that halts its IN endpoint instead of each reply: each
    command, sent right after the last one's EPIPE, gets EPIPE too. The
    driver clears the stall before it sends the next telegram; a clear
    left to its work item could come after that telegram and clear the
    stall meant for it, whose reply then never came (ETIMEDOUT)."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile='stall')
    b.plug()
    f = b.open()
    try:
        assert nxt.set_timeout(f, 3000) == 0
        got = [nxt.transact(f, b'\x00\x0b')[0] for _ in range(STALL_ROUNDS)]
        bad = [(i, errno.errorcode.get(e, e)) for i, e in enumerate(got) if e != errno.EPIPE]
        assert not bad, 'of %d commands, not EPIPE: %s' % (STALL_ROUNDS, bad)
    finally:
        os.close(f)
        b.unplug()
        assert b.wait_gone()


def test_sysfs_never_waits_for_a_silent_brick():
    """sysfs is world-readable: reading it asks nothing of the brick, so a
    brick that does not answer makes no read wait, and none is retried."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile='noreply')
    b.plug()
    try:
        intf = b.interface()
        before = b.emu.commands
        for _ in range(20):
            t = time.monotonic()
            for name in SYSFS_ATTRS:
                with pytest.raises(OSError) as e:
                    nxt.attr(nxt.node_dir(intf), name)
                assert e.value.errno == errno.ENODATA, name
            assert time.monotonic() - t < 0.5, 'a read waited'
        assert b.emu.commands == before
    finally:
        b.unplug()
        assert b.wait_gone()


def test_poll_waits_for_the_drain():
    """No POLLOUT while a lost reply is drained (a write() would get
    EAGAIN), and POLLOUT by itself once the drain ends."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile='noreply')
    b.plug()
    g = b.open()
    f = b.open(os.O_RDWR | os.O_NONBLOCK)
    try:
        assert nxt.set_timeout(g, 100) == 0
        assert nxt.transact(g, b'\x00\x0b')[0] == errno.ETIMEDOUT
        p = select.poll()
        p.register(f, select.POLLOUT)
        t0 = time.monotonic()
        assert dict(p.poll(2000)).get(f, 0) & select.POLLOUT
        assert time.monotonic() - t0 < 1.0
        os.write(f, b'\x80\x03\xb8\x01\x10\x00')
    finally:
        os.close(f)
        os.close(g)
        b.unplug()
        assert b.wait_gone()


def test_wrong_length_reply_is_skipped():
    """A reply to the same opcode but of the wrong length is not the reply:
    the real one that follows it is taken."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile='mislength')
    b.plug()
    f = b.open()
    try:
        err, reply = nxt.transact(f, b'\x00\x0b')
        assert err == 0 and reply[:3] == b'\x02\x0b\x00' and len(reply) == 5
        assert nxt.ok(f, 'GET_OUTPUT_STATE', port=1)['port'] == 1
    finally:
        os.close(f)
        b.unplug()
        assert b.wait_gone()


@pytest.mark.parametrize('mode,want', [
    ('short', errno.EPROTO),
    ('long', errno.EPROTO),
    ('opcode', errno.EPROTO),
    ('garbage', errno.EPROTO),
    ('noreply', errno.ETIMEDOUT),
    ('stall', errno.EPIPE),
    ('disconnect', errno.ENODEV),
])
def test_hostile_brick(mode, want):
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile=mode)
    b.plug()
    f = b.open()
    try:
        # Short where the timeout decides (a bad reply is skipped, the
        # real one may follow): in a slow emulated machine the
        # 'disconnect' brick may take longer than that to go.
        assert nxt.set_timeout(f, 3000 if mode in ('stall', 'disconnect') else 300) == 0
        err, _ = nxt.transact(f, b'\x00\x0b')
        assert err == want, errno.errorcode.get(err, err)
        err, _ = nxt.command(f, 'GET_OUTPUT_STATE', port=0)
        assert err in (want, errno.ENODEV), errno.errorcode.get(err, err)
    finally:
        os.close(f)
        b.unplug()
        assert b.wait_gone()


class Interrupted(Exception):
    """Raised by a signal handler: Python then does not retry the call the
    signal interrupted (PEP 475)."""


def test_signal_while_the_brick_takes_nothing():
    """A brick that takes no telegram (its firmware stuck): a signal ends
    the wait for the send at once; without one, the send times out."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, hostile='deaf')
    b.plug()
    f = b.open()

    def handler(signum, frame):
        raise Interrupted()
    old = signal.signal(signal.SIGUSR1, handler)
    try:
        assert nxt.set_timeout(f, 3000) == 0
        timer = threading.Timer(0.3, signal.pthread_kill,
                                (threading.get_ident(), signal.SIGUSR1))
        timer.start()
        t0 = time.monotonic()
        with pytest.raises(Interrupted):
            os.write(f, b'\x00\x0b')
        assert 0.3 <= time.monotonic() - t0 < 2.5
        timer.join()
        # Not taken: the telegram is unlinked when the timeout ends.
        assert nxt.set_timeout(f, 300) == 0
        err, _ = nxt.transact(f, b'\x00\x0b')
        assert err == errno.ETIMEDOUT, errno.errorcode.get(err, err)
    finally:
        signal.signal(signal.SIGUSR1, old)
        os.close(f)
        b.unplug()
        assert b.wait_gone()


# ---- issue 28: who may make the brick act, and what waits for it ----

def header_ioctls():
    """Every ioctl the uapi header defines, by name (NXT_IOC_ dropped)."""
    with open(os.path.join(nxt.TOP, 'include/uapi/linux/lego_nxt.h')) as f:
        text = f.read()
    names = re.findall(r'^#define\s+NXT_IOC_([A-Z0-9_]+)(?=[\s\\])', text, re.M)
    return [n for n in names if n != 'MAGIC']


# The ioctls that send nothing to the brick; every other one sends a telegram.
# TTY_MINOR is the serial discipline's, asked of its tty: ENOTTY here.
NO_TELEGRAM = {'SET_TIMEOUT', 'GET_TIMEOUT', 'TTY_MINOR'}

# Telegrams that a file opened for writing would send: EBADF, not EINVAL,
# must stop them on a read-only one.
MOTOR_C = dict(port=2, power=100, mode=1, run_state=0x20)
ACTING_TELEGRAMS = [b'\x01\xa0', b'\x81\xa0', nxt.telegram('SET_OUTPUT_STATE', **MOTOR_C),
                    nxt.telegram('SET_OUTPUT_STATE', reply=False, **MOTOR_C)]


def retired_ioctl_numbers():
    """The numbers of the typed ioctls of earlier releases (0x10 + opcode,
    _IOWR, their argument sizes), and every number of their range with
    sizes like theirs, which must stay unknown: ENOTTY."""
    sizes = (4, 8, 20, 24, 28, 64)
    numbers = {nxt.iowr(nr, size) for nr in range(0x10, 0x34) for size in sizes}
    return sorted(numbers | {nxt.retired_number(op) for op in nxt.RETIRED_TYPED})


def test_retired_typed_ioctls_are_enotty(brick, fd):
    before = brick.emu.commands
    for request in retired_ioctl_numbers():
        _, err, out = nxt.raw_ioctl(fd, request, bytes(64))
        assert err == errno.ENOTTY, hex(request)
        assert out == bytes(64)
    assert brick.emu.commands == before


def test_read_only_file_cannot_make_the_brick_act():
    """open(O_RDONLY), then each ioctl that sends a telegram, taken from the
    uapi header so that a new one is not missed: EBADF, as write() gives,
    and nothing reaches the brick (01 A0 would erase its flash,
    SetOutputState drive motor C)."""
    names = header_ioctls()
    unknown = set(names) - {'TRANSACT'} - NO_TELEGRAM
    assert not unknown, 'ioctls new to tests/guest/nxtdev.py: %s' % sorted(unknown)
    sending = [n for n in names if n not in NO_TELEGRAM]
    assert sending == ['TRANSACT']
    b = nxt.Brick('dummy_udc.1', SERIAL2)
    b.plug()
    try:
        files = dict(b.fw.files)
        ro = b.open(os.O_RDONLY)
        try:
            before = b.emu.commands
            got = {}
            for tg in ACTING_TELEGRAMS:
                got['TRANSACT ' + tg.hex()] = nxt.transact(ro, tg)[0]
                with pytest.raises(OSError) as e:
                    os.write(ro, tg)
                got['write() ' + tg.hex()] = e.value.errno
            bad = {n: errno.errorcode.get(e, e) for n, e in got.items() if e != errno.EBADF}
            assert not bad, 'not EBADF on a read-only file: %s' % bad
            time.sleep(0.2)
            assert b.emu.commands == before, 'a read-only file sent telegrams'
            assert b.fw.files == files and b.fw.motors[2].power == 0
            # The timeouts send nothing, and stay the file's own.
            assert nxt.set_timeout(ro, 300) == 0 and nxt.get_timeout(ro) == 300
            _, err, _ = nxt.raw_ioctl(ro, nxt.ioctl_number('TTY_MINOR'), bytes(4))
            assert err == errno.ENOTTY, 'NXT_IOC_TTY_MINOR on /dev/nxtN: %s' % err
        finally:
            os.close(ro)
        # The same arguments are fine on a file opened for writing.
        rw = b.open(os.O_WRONLY)
        try:
            assert nxt.command(rw, 'GET_BATTERY_LEVEL')[0] == 0
            assert nxt.command(rw, 'SET_OUTPUT_STATE', **MOTOR_C)[0] == 0
            assert b.fw.motors[2].power == 100
            nxt.ok(rw, 'SET_OUTPUT_STATE', port=2, power=0, mode=0, run_state=0)
        finally:
            os.close(rw)
    finally:
        b.unplug()
        assert b.wait_gone()


def readable_files(dirs):
    """The world-readable regular files directly in each of dirs."""
    out = []
    for d in dirs:
        for name in sorted(os.listdir(d)):
            path = os.path.join(d, name)
            st = os.lstat(path)
            if stat.S_ISREG(st.st_mode) and st.st_mode & stat.S_IROTH:
                out.append(path)
    return out


def read_all(paths):
    got = {}
    for path in paths:
        try:
            fd = os.open(path, os.O_RDONLY)
            try:
                got[path] = os.read(fd, 4096)
            finally:
                os.close(fd)
        except OSError as e:
            got[path] = e.errno
    return got


def test_reading_world_readable_attributes_sends_nothing():
    """Every world-readable file of the brick's interface, its USB device
    and its lego-nxt node, read again and again (and udevadm info -a): no
    telegram reaches the brick. The driver's attributes show ENODATA until
    a user of /dev/nxtN got a reply with their value, then that value."""
    b = nxt.Brick('dummy_udc.1', SERIAL2, name='Reader')
    b.plug()
    try:
        intf = b.interface()
        misc = nxt.node_dir(intf)
        paths = readable_files([intf, os.path.dirname(intf), misc])
        for name in SYSFS_ATTRS:
            assert os.path.join(misc, name) in paths, name
        before = b.emu.commands
        for _ in range(5):
            got = read_all(paths)
        udevadm = shutil.which('udevadm')
        if udevadm:
            subprocess.run([udevadm, 'info', '-a', '-p', intf], capture_output=True, timeout=60)
        time.sleep(0.2)
        assert b.emu.commands == before, 'reading sysfs sent %d telegrams' % (
            b.emu.commands - before)
        for name in SYSFS_ATTRS:
            assert got[os.path.join(misc, name)] == errno.ENODATA, name

        f = b.open()
        try:
            ask_brick_info(f)
        finally:
            os.close(f)
        asked = b.emu.commands
        for _ in range(5):
            got = read_all(paths)
        time.sleep(0.2)
        assert b.emu.commands == asked
        want = {'battery_mv': str(b.fw.battery_mv), 'firmware_version': '1.29',
                'protocol_version': '1.124', 'brick_name': 'Reader',
                'bt_address': '00:16:53:0d:0e:0f', 'free_flash': str(b.fw.free_flash)}
        assert {n: got[os.path.join(misc, n)].decode().strip() for n in SYSFS_ATTRS} == want
    finally:
        b.unplug()
        assert b.wait_gone()


@pytest.mark.parametrize('how', ['unplug', 'unbind'])
def test_unplug_and_unbind_do_not_wait_for_the_brick(how):
    """A silent brick, a transaction with a 30 s timeout in flight, another
    file's transaction queued behind it and sysfs being read: the unplug (or unbind)
    is done within about a second, not when the timeout ends, and every
    waiter gets ENODEV."""
    b = nxt.Brick('dummy_udc.1', SERIAL2)
    b.plug()
    intf = b.interface()
    name = os.path.basename(intf)
    node = nxt.node_dir(intf)
    f, g = b.open(), b.open()
    results = {}
    stop = threading.Event()

    def transaction():
        results['transact'] = nxt.transact(f, b'\x00\x0b')[0]

    def queued():
        results['queued'] = nxt.command(g, 'KEEP_ALIVE')[0]

    def reader():
        reads = 0
        while not stop.is_set():
            read_all([os.path.join(node, a) for a in SYSFS_ATTRS])
            reads += 1
        results['reads'] = reads

    threads = [threading.Thread(target=t) for t in (transaction, queued, reader)]
    try:
        assert nxt.set_timeout(f, 30000) == 0
        b.emu.hostile = 'noreply'               # the brick stays silent
        before = b.emu.commands
        threads[0].start()
        assert conftest.wait_for(lambda: b.emu.commands > before, 5)
        for t in threads[1:]:
            t.start()
        time.sleep(1.0)                 # the queued ones are surely waiting
        assert 'transact' not in results and 'queued' not in results
        t0 = time.monotonic()
        if how == 'unplug':
            b.unplug()
            gone = b.wait_gone(60)
        else:
            with open(nxt.DRIVER + '/unbind', 'w') as u:
                u.write(name)
            gone = nxt.interface_of(b.serial) is None
        elapsed = time.monotonic() - t0
        print('%s took %.2f s' % (how, elapsed))
        assert gone
        assert elapsed < 2.5, '%s took %.1f s: it waited for the brick' % (how, elapsed)
        for t in threads[:2]:
            t.join(5)
        assert (results.get('transact'), results.get('queued')) == (errno.ENODEV, errno.ENODEV)
    finally:
        stop.set()
        for t in threads:
            if t.ident:
                t.join(60)
        b.emu.hostile = None
        os.close(f)
        os.close(g)
        if how == 'unbind' and nxt.interface_of(b.serial) is None and b.emu.configured.is_set():
            with open(nxt.DRIVER + '/bind', 'w') as u:
                u.write(name)
        b.unplug()
        assert b.wait_gone(60)


def test_short_telegrams_are_refused(fd, brick):
    """A telegram shorter than what its command reads would run with bytes
    of earlier telegrams, another process's perhaps, that the firmware's
    receive buffer still holds: EINVAL, and nothing is sent."""
    # Another process's full SetOutputState leaves its bytes in the buffer.
    nxt.ok(fd, 'SET_OUTPUT_STATE', port=0, power=0, mode=0, run_state=0)
    before = brick.emu.commands
    short = [
        b'\x80\x04\x01\x64',                          # SetOutputState, port B, power 100
        b'\x01\x81' + nxt.name20('f.txt'),            # OpenWrite without its size
        b'\x00\x09\x00\x08ab\0',                      # MessageWrite of 8 bytes, 3 sent
        b'\x00\x0f\x00\x03\x01\x02',                  # LSWrite of 3 bytes, 1 sent
        b'\x01\x98NXT',                               # SetBrickName without its NUL
        b'\x00\x1f\x02\x10\x27',                      # SetProperty sleep, 2 of 4 bytes
    ]
    for tg in short:
        assert not nxt.request_complete(tg)
        with pytest.raises(OSError) as e:
            os.write(fd, tg)
        assert e.value.errno == errno.EINVAL, tg.hex()
        assert nxt.transact(fd, tg)[0] == errno.EINVAL, tg.hex()
    assert brick.emu.commands == before, 'a short telegram reached the brick'
    assert brick.fw.motors[1].power == 0
    # Complete ones go, and so do unknown opcodes (the brick answers them).
    assert nxt.transact(fd, b'\x01\x98NXT\0') == (0, b'\x02\x98\x00')
    assert nxt.transact(fd, b'\x00\x30') == (0, b'\x02\x30\xbe')


def test_open_restarts_after_a_signal_while_a_reset_holds_the_brick():
    """open() waits for the brick's I/O lock, which a USB reset holds from
    pre_reset() to post_reset() (made long here: the brick answers the
    reset's first descriptor request 2 s late). A signal with SA_RESTART
    meanwhile must restart the open (ERESTARTSYS), not fail it with EINTR.
    The open is a ctypes call, which Python does not retry itself."""
    import fcntl
    b = nxt.Brick('dummy_udc.1', SERIAL2)
    b.plug()
    slow = threading.Event()
    control = b.emu._control

    def slow_control(setup):
        # GET_DESCRIPTOR(DEVICE): the first request of the reset's re-enumeration.
        if slow.is_set() and setup[0] == 0x80 and setup[1] == 6 and setup[3] == 1:
            slow.clear()
            time.sleep(2.0)
        control(setup)

    b.emu._control = slow_control
    got = []
    old = signal.signal(signal.SIGUSR1, lambda signum, frame: got.append(signum))
    signal.siginterrupt(signal.SIGUSR1, False)
    libc = ctypes.CDLL(None, use_errno=True)
    usbfs = os.open(usbfs_path(b.interface()), os.O_RDWR)
    reset = threading.Thread(target=fcntl.ioctl, args=(usbfs, (ord('U') << 8) | 20, 0))
    fd = -1
    try:
        slow.set()
        t0 = time.monotonic()
        reset.start()
        assert conftest.wait_for(
            lambda: any(t > t0 and what == 'bus reset' for t, what in list(b.emu.events)), 5)
        assert slow.is_set()            # the descriptor request is not answered yet
        threading.Timer(0.3, signal.pthread_kill,
                        (threading.get_ident(), signal.SIGUSR1)).start()
        t1 = time.monotonic()
        fd = libc.open(b.node.encode(), os.O_RDWR)
        err = ctypes.get_errno() if fd < 0 else 0
        elapsed = time.monotonic() - t1
        assert got == [signal.SIGUSR1]
        assert (fd >= 0, errno.errorcode.get(err, err)) == (True, 0), \
            'open failed with %s after %.2f s' % (errno.errorcode.get(err, err), elapsed)
        assert elapsed > 0.3
        reset.join(10)
        assert b.emu.wait_configured(10)
        assert nxt.ok(fd, 'KEEP_ALIVE')['sleep_limit'] == 600000
    finally:
        signal.signal(signal.SIGUSR1, old)
        reset.join(10)
        if fd >= 0:
            os.close(fd)
        os.close(usbfs)
        b.emu._control = control
        b.unplug()
        assert b.wait_gone()
