"""The emulated NXT brick on dummy_hcd, seen from the host side of the same
VM: its enumeration through sysfs, its telegrams through usbfs.

The NXT kernel driver is unloaded while these tests run (and loaded again
after them), so they do not depend on what it does with a brick; if it
cannot be unloaded, usbfs takes the interface from it."""
import ctypes
import errno
import fcntl
import glob
import os
import select
import struct
import subprocess
import sys
import time
import types

import pytest

from conftest import loaded, module_path

EMULATOR = os.path.join(os.path.dirname(__file__), '..', 'emulator')
sys.path.insert(0, EMULATOR)
import nxt_brick  # noqa: E402

SERIAL0 = '001653A0B1C2'
SERIAL1 = '0016530F1E2D'


def _ioc(direction, nr, size):
    return (direction << 30) | (size << 16) | (ord('U') << 8) | nr


USBDEVFS_CONTROL = _ioc(3, 0, 24)
USBDEVFS_BULK = _ioc(3, 2, 24)
USBDEVFS_CLAIMINTERFACE = _ioc(2, 15, 4)
USBDEVFS_RESET = _ioc(0, 20, 0)
USBDEVFS_CLEAR_HALT = _ioc(2, 21, 4)
USBDEVFS_DISCONNECT_CLAIM = _ioc(2, 27, 264)

# The brick's descriptors, from the firmware's tables (nxt.md 1.1).
DEVICE = bytes.fromhex('12 01 0002 00 00 00 08 9406 0200 0000 00 00 01 01')
CONFIG = bytes.fromhex('09 02 2000 01 01 00 C0 00'
                       '09 04 00 00 02 FF FF FF 00'
                       '07 05 01 02 4000 00'      # bulk OUT 0x01 first
                       '07 05 82 02 4000 00')     # then bulk IN 0x82


def read_attr(path, name):
    with open(os.path.join(path, name)) as f:
        return f.read().strip()


def find_device(serial):
    for d in glob.glob('/sys/bus/usb/devices/*'):
        try:
            if read_attr(d, 'idVendor') == '0694' and read_attr(d, 'serial') == serial:
                return d
        except OSError:
            continue
    return None


def wait_device(serial, timeout=60):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        d = find_device(serial)
        if d and os.path.exists(os.path.join(d, 'bConfigurationValue')) \
                and read_attr(d, 'bConfigurationValue') == '1':
            return d
        time.sleep(0.1)
    raise AssertionError('no brick with serial %s on the bus' % serial)


def wait_gone(serial, timeout=30):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if find_device(serial) is None:
            return True
        time.sleep(0.1)
    return False


class Usbfs:
    """The brick's interface 0 through /dev/bus/usb, as libusb would drive it."""

    def __init__(self, serial):
        self.sysfs = wait_device(serial)
        node = '/dev/bus/usb/%03d/%03d' % (int(read_attr(self.sysfs, 'busnum')),
                                           int(read_attr(self.sysfs, 'devnum')))
        deadline = time.monotonic() + 10
        while not os.path.exists(node) and time.monotonic() < deadline:
            time.sleep(0.05)
        self.fd = os.open(node, os.O_RDWR)
        try:
            fcntl.ioctl(self.fd, USBDEVFS_CLAIMINTERFACE, struct.pack('I', 0))
        except OSError as e:
            if e.errno != errno.EBUSY:
                raise
            # A kernel driver holds it: take it over.
            fcntl.ioctl(self.fd, USBDEVFS_DISCONNECT_CLAIM, struct.pack('II256s', 0, 0, b''))

    def close(self):
        os.close(self.fd)

    def bulk(self, ep, data=b'', length=None, timeout_ms=1000):
        n = len(data) if length is None else length
        buf = ctypes.create_string_buffer(bytes(data), max(n, 1))
        arg = bytearray(struct.pack('@IIIP', ep, n, timeout_ms, ctypes.addressof(buf)))
        got = fcntl.ioctl(self.fd, USBDEVFS_BULK, arg)
        return buf.raw[:got]

    def send(self, data, timeout_ms=1000):
        self.bulk(0x01, data, timeout_ms=timeout_ms)

    def recv(self, timeout_ms=1000):
        return self.bulk(0x82, length=64, timeout_ms=timeout_ms)

    def cmd(self, data):
        self.send(bytes.fromhex(data) if isinstance(data, str) else data)
        return self.recv()

    def drain(self):
        while True:
            try:
                self.recv(timeout_ms=100)
            except OSError as e:
                if e.errno == errno.ETIMEDOUT:
                    return
                raise

    def control(self, rtype, req, value, index, length=0, timeout_ms=1000):
        buf = ctypes.create_string_buffer(max(length, 1))
        arg = bytearray(struct.pack('@BBHHHIP', rtype, req, value, index, length, timeout_ms,
                                    ctypes.addressof(buf)))
        got = fcntl.ioctl(self.fd, USBDEVFS_CONTROL, arg)
        return buf.raw[:got]

    def reset(self):
        fcntl.ioctl(self.fd, USBDEVFS_RESET, 0)

    def clear_halt(self, ep):
        fcntl.ioctl(self.fd, USBDEVFS_CLEAR_HALT, struct.pack('I', ep))


@pytest.fixture(scope='module')
def no_nxt_driver():
    was_loaded = loaded('lego_nxt_usb')
    if was_loaded:
        subprocess.run(['rmmod', 'lego_nxt_usb'])
    yield
    if was_loaded and not loaded('lego_nxt_usb'):
        subprocess.run(['insmod', module_path('lego_nxt_usb')], check=True)


@pytest.fixture(scope='module')
def brick0(no_nxt_driver):
    # With the firmware's 1 ms scheduler tick, as a share of the tests'
    # bricks have it (nxt_brick.py `tick`).
    brick = nxt_brick.RawGadgetBrick(udc='dummy_udc.0', serial=SERIAL0, tick=0.001)
    brick.start()
    assert brick.wait_configured(60), brick.events
    yield brick
    brick.stop()
    assert wait_gone(SERIAL0)


@pytest.fixture
def usb0(brick0):
    assert brick0.wait_configured(60), brick0.events
    usb = Usbfs(SERIAL0)
    usb.drain()
    yield usb
    usb.close()


def test_enumerates_with_the_brick_descriptors(brick0):
    d = wait_device(SERIAL0)
    with open(os.path.join(d, 'descriptors'), 'rb') as f:
        assert f.read() == DEVICE + CONFIG
    expected = {'idVendor': '0694', 'idProduct': '0002', 'bcdDevice': '0000',
                'version': '2.00', 'bDeviceClass': '00', 'bDeviceSubClass': '00',
                'bDeviceProtocol': '00', 'bMaxPacketSize0': '8', 'bNumConfigurations': '1',
                'bConfigurationValue': '1', 'bmAttributes': 'c0', 'bMaxPower': '0mA',
                'bNumInterfaces': '1', 'speed': '12', 'serial': SERIAL0}
    assert {k: read_attr(d, k) for k in expected} == expected
    assert not os.path.exists(os.path.join(d, 'manufacturer'))
    assert not os.path.exists(os.path.join(d, 'product'))
    intf = d + '/' + os.path.basename(d) + ':1.0'
    assert [read_attr(intf, a) for a in ('bInterfaceClass', 'bInterfaceSubClass',
                                         'bInterfaceProtocol', 'bNumEndpoints')] == \
        ['ff', 'ff', 'ff', '02']
    for ep, direction in (('ep_01', 'out'), ('ep_82', 'in')):
        assert read_attr(os.path.join(intf, ep), 'type') == 'Bulk'
        assert read_attr(os.path.join(intf, ep), 'direction') == direction
        assert read_attr(os.path.join(intf, ep), 'wMaxPacketSize') == '0040'


def test_strings_and_stalled_requests(usb0):
    assert usb0.control(0x80, 6, 0x0300, 0, 255) == bytes.fromhex('04 03 09 04')
    serial = usb0.control(0x80, 6, 0x0301, 0x0409, 255)
    assert serial == bytes([26, 3]) + SERIAL0.encode('utf-16-le')
    assert usb0.control(0x80, 8, 0, 0, 1) == b'\x01'           # GET_CONFIGURATION
    for rtype, req, value, index, length in [
            (0x80, 6, 0x0302, 0x0409, 255),    # string 2
            (0x80, 6, 0x03EE, 0x0409, 255),    # string 0xEE
            (0x01, 11, 0, 0, 0),               # SET_INTERFACE
            (0xC0, 1, 0, 0, 8),                # vendor IN
            (0x40, 1, 0, 0, 0)]:               # vendor OUT
        with pytest.raises(OSError) as e:
            usb0.control(rtype, req, value, index, length)
        assert e.value.errno == errno.EPIPE, (rtype, req, value)
    # The brick still answers afterwards.
    assert usb0.cmd('00 0B')[:3] == bytes.fromhex('02 0B 00')


def test_get_device_info(usb0, brick0):
    reply = usb0.cmd('01 9B')
    assert len(reply) == 33
    assert reply[:18] == bytes.fromhex('02 9B 00') + b'NXT'.ljust(15, b'\0')
    assert reply[18:25] == bytes.fromhex(SERIAL0) + b'\0'
    assert struct.unpack('<I', reply[29:33])[0] == brick0.fw.free_flash


def test_battery(usb0, brick0):
    reply = usb0.cmd('00 0B')
    assert len(reply) == 5 and reply[:3] == bytes.fromhex('02 0B 00')
    assert struct.unpack('<H', reply[3:])[0] == brick0.fw.battery_mv


def test_no_reply_command_gets_no_reply(usb0, brick0):
    before = brick0.commands
    usb0.send(bytes.fromhex('80 03 F4 01 F4 01'))            # PlayTone 500 Hz, 500 ms
    with pytest.raises(OSError) as e:
        usb0.recv(timeout_ms=700)
    assert e.value.errno == errno.ETIMEDOUT
    assert brick0.commands == before + 1
    assert brick0.fw.sound[:2] == ('tone', 500)
    assert usb0.cmd('00 0B')[:3] == bytes.fromhex('02 0B 00')


def test_unknown_opcodes(usb0):
    assert usb0.cmd('00 30') == bytes.fromhex('02 30 BE')
    assert usb0.cmd('00 12') == bytes.fromhex('02 12 BE')
    version = usb0.cmd('01 88')
    assert version == bytes.fromhex('02 88 00 7C 01 1D 01')
    assert usb0.cmd('01 A3 00 00') == bytes.fromhex('02 A3') + version[2:6]


def test_one_packet_is_one_command(usb0):
    # A 66-byte transfer is two packets: GetBatteryLevel (with 62 bytes of
    # padding the brick ignores), then GetVersions.
    usb0.send(bytes.fromhex('00 0B') + bytes(62) + bytes.fromhex('01 88'))
    assert usb0.recv()[:3] == bytes.fromhex('02 0B 00')
    assert usb0.recv() == bytes.fromhex('02 88 00 7C 01 1D 01')


def test_unread_reply_comes_out_later(usb0, brick0):
    usb0.send(bytes.fromhex('00 0B'))
    time.sleep(0.8)                     # the brick gives up waiting after ~0.5 s
    usb0.send(bytes.fromhex('01 88'))
    assert usb0.recv()[:3] == bytes.fromhex('02 0B 00')      # the stale one first
    assert usb0.recv() == bytes.fromhex('02 88 00 7C 01 1D 01')


def test_brick_takes_no_command_while_its_reply_waits(usb0):
    usb0.send(bytes.fromhex('00 0B'))
    # The firmware busy-waits ~0.5 s for the host to take the reply: the
    # next command is not accepted (NAKed) meanwhile.
    with pytest.raises(OSError) as e:
        usb0.send(bytes.fromhex('01 88'), timeout_ms=200)
    assert e.value.errno == errno.ETIMEDOUT
    assert usb0.recv()[:3] == bytes.fromhex('02 0B 00')
    assert usb0.cmd('01 88') == bytes.fromhex('02 88 00 7C 01 1D 01')


def test_two_replies_queue_and_a_third_is_lost(usb0, brick0):
    lost = brick0.replies_lost
    for command in ('00 0B', '01 88', '00 0D'):
        usb0.send(bytes.fromhex(command))
        time.sleep(0.7)
    assert usb0.recv()[:3] == bytes.fromhex('02 0B 00')
    assert usb0.recv()[:3] == bytes.fromhex('02 88 00')
    with pytest.raises(OSError) as e:
        usb0.recv(timeout_ms=300)
    assert e.value.errno == errno.ETIMEDOUT
    assert brick0.replies_lost == lost + 1


def test_bus_reset_flushes_stale_replies(usb0, brick0):
    usb0.send(bytes.fromhex('00 0B'))
    time.sleep(0.7)
    usb0.reset()
    assert brick0.wait_configured(30)
    assert usb0.cmd('01 88') == bytes.fromhex('02 88 00 7C 01 1D 01')


def test_unplug_closes_files_opened_over_usb(usb0, brick0):
    reply = usb0.cmd(b'\x01\x80' + b'Demo.rxe'.ljust(20, b'\0'))
    assert reply[:3] == bytes.fromhex('02 80 00')
    handle = reply[3]
    assert usb0.cmd(bytes([1, 0x82, handle, 4, 0]))[:3] == bytes.fromhex('02 82 00')
    usb0.close()
    brick0.unplug()
    assert wait_gone(SERIAL0)
    brick0.replug()
    assert brick0.wait_configured(60), brick0.events
    usb0.__init__(SERIAL0)
    assert usb0.cmd(bytes([1, 0x82, handle, 4, 0]))[2] == 0x93


def stop_program(proc, timeout=30):
    """SIGTERM, then status 0 within `timeout` s. An emulator that does not
    stop is killed, after its threads' kernel stacks are taken for the
    report: it holds its UDC, which every later test needs."""
    proc.terminate()
    try:
        status = proc.wait(timeout)
    except subprocess.TimeoutExpired:
        stacks = []
        for task in sorted(glob.glob('/proc/%d/task/*' % proc.pid)):
            try:
                with open(task + '/comm') as f, open(task + '/stack') as g:
                    stacks.append('%s %s\n%s' % (task, f.read().strip(), g.read()))
            except OSError as e:
                stacks.append('%s: %s' % (task, e))
        proc.kill()
        proc.wait(30)
        raise AssertionError('%s did not stop in %d s after SIGTERM; its threads:\n%s'
                             % (proc.args, timeout, '\n'.join(stacks)))
    assert status == 0, (proc.args, status)


def test_two_bricks_at_once(usb0):
    proc = subprocess.Popen([sys.executable, os.path.join(EMULATOR, 'nxt_brick.py'),
                             '--udc', 'dummy_udc.1', '--serial', SERIAL1, '--name', 'Second'],
                            stdout=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 90)
        assert ready, 'the second brick never said it was configured'
        line = proc.stdout.readline()
        assert 'configured' in line and SERIAL1 in line
        usb1 = Usbfs(SERIAL1)
        try:
            assert find_device(SERIAL0) and find_device(SERIAL1)
            assert read_attr(usb0.sysfs, 'busnum') != read_attr(usb1.sysfs, 'busnum')
            one, two = usb0.cmd('01 9B'), usb1.cmd('01 9B')
            assert one[3:25] == b'NXT'.ljust(15, b'\0') + bytes.fromhex(SERIAL0) + b'\0'
            assert two[3:25] == b'Second'.ljust(15, b'\0') + bytes.fromhex(SERIAL1) + b'\0'
        finally:
            usb1.close()
    finally:
        stop_program(proc)
    assert wait_gone(SERIAL1)
    assert find_device(SERIAL0)


@pytest.mark.parametrize('mode', nxt_brick.HOSTILE_MODES)
def test_hostile_brick(no_nxt_driver, mode):
    brick = nxt_brick.RawGadgetBrick(udc='dummy_udc.1', serial=SERIAL1, hostile=mode)
    brick.start()
    try:
        assert brick.wait_configured(60), brick.events
        usb = Usbfs(SERIAL1)
        try:
            if mode == 'deaf':
                # Configured, but the command is never taken.
                with pytest.raises(OSError) as e:
                    usb.send(bytes.fromhex('01 9B'), timeout_ms=1500)
                assert e.value.errno == errno.ETIMEDOUT, e.value
                return
            usb.send(bytes.fromhex('01 9B'))
            if mode in ('noreply', 'stall', 'disconnect'):
                with pytest.raises(OSError) as e:
                    usb.recv(timeout_ms=1500)
                expect = {'noreply': (errno.ETIMEDOUT,), 'stall': (errno.EPIPE,),
                          'disconnect': (errno.ENODEV, errno.ESHUTDOWN, errno.EPROTO)}
                assert e.value.errno in expect[mode], e.value
                if mode == 'stall':
                    usb.clear_halt(0x82)
                if mode == 'disconnect':
                    assert wait_gone(SERIAL1)
                return
            reply = usb.recv()
            if mode == 'short':
                assert len(reply) == 16 and reply[:3] == bytes.fromhex('02 9B 00')
            elif mode == 'long':
                assert len(reply) == 64 and reply[:3] == bytes.fromhex('02 9B 00')
            elif mode == 'opcode':
                assert len(reply) == 33 and reply[:3] == bytes.fromhex('02 9C 00')
            elif mode == 'garbage':
                assert reply and reply[0] != 0x02
        finally:
            usb.close()
    finally:
        brick.stop()
    assert wait_gone(SERIAL1)


def test_tick_one_command_per_pass(monkeypatch):
    """The firmware's 1 ms scheduler (`tick`): a command waits for the
    first tick at or after its arrival, and the next one for the tick after
    the pass that handled the last one ended."""
    clock = [5.0003]

    def sleep(s):
        assert s > 0
        clock[0] += s
    monkeypatch.setattr(nxt_brick, 'time', types.SimpleNamespace(
        monotonic=lambda: clock[0], sleep=sleep))
    b = nxt_brick.RawGadgetBrick(tick=0.001)
    b._wait_for_pass()
    assert clock[0] == pytest.approx(5.001)
    clock[0] = 5.0012
    b._pass_done()
    clock[0] = 5.0013                  # the next command came at once
    b._wait_for_pass()
    assert clock[0] == pytest.approx(5.002)
    clock[0] = 5.0020004               # it was handled within its tick
    b._pass_done()
    clock[0] = 5.0107                  # a command long after
    b._wait_for_pass()
    assert clock[0] == pytest.approx(5.011)
    b._pass_done()
    clock[0] = 5.012                   # comes on a tick: no wait
    b._wait_for_pass()
    assert clock[0] == 5.012
    b._pass_done()
    clock[0] = 5.0125
    b._wait_for_pass()
    assert clock[0] == pytest.approx(5.013)
