"""nxt-python 3.5.1, unmodified, against the emulated brick.

Through lego_nxt_usb's /dev/nxtN with the backend in tools/python
(lego_nxt_linux), and through nxt-python's own libusb backend once the
driver is unbound from the brick.

The guest test helpers are tests/guest/nxtdev.py; `nxt` is nxt-python.
"""
import errno
import os
import sys
import termios
import time

import pytest

import nxtdev                            # tests/guest/nxtdev.py

TOOLS_PYTHON = os.path.join(nxtdev.TOP, 'tools', 'python')
sys.path.insert(0, TOOLS_PYTHON)

import nxt                               # noqa: E402  nxt-python, from PyPI
import nxt.backend.devfile               # noqa: E402
import nxt.backend.usb                   # noqa: E402
import nxt.brick                         # noqa: E402
import nxt.error                         # noqa: E402
import nxt.locator                       # noqa: E402
import nxt.motor                         # noqa: E402
import nxt.sensor                        # noqa: E402
import nxt.sensor.generic                # noqa: E402
import lego_nxt_linux                    # noqa: E402

assert lego_nxt_linux.__file__.startswith(TOOLS_PYTHON), lego_nxt_linux.__file__

SERIAL = '001653A0B1C2'
# The module's brick has the firmware's 1 ms scheduler tick (conftest.brick).
BRICK_TICK = 0.001
HOST = '00:16:53:A0:B1:C2'
SERIAL2 = '0016530D0E0F'
HOST2 = '00:16:53:0D:0E:0F'


def version_string():
    import importlib.metadata as md
    return md.version('nxt-python')


def find(**kw):
    """The locator with our backend only, and no configuration file."""
    kw.setdefault('backends', [lego_nxt_linux.get_backend()])
    return nxt.locator.find(config=None, **kw)


@pytest.fixture
def nb(brick):
    """nxt-python's Brick for the emulated brick, found by the locator."""
    b = find(host=HOST)
    yield b
    b.close()


@pytest.fixture
def packets(brick):
    """Every USB OUT packet the emulated firmware handles during a test."""
    log = []
    orig = brick.fw.handle

    def handle(packet):
        log.append(bytes(packet))
        return orig(packet)
    brick.fw.handle = handle
    yield log
    del brick.fw.handle


def test_nxt_python_version():
    assert version_string() == '3.5.1'


def test_list_devices_and_sock(brick):
    assert brick.node in lego_nxt_linux.list_devices()
    with find() as b:
        sock = b._sock
        assert isinstance(sock, lego_nxt_linux.DevNodeSock)
        assert sock.filename == brick.node
        assert sock.type == 'usb' and sock.bsize == 58
    assert sock._fd is None            # closed with the brick



def test_devfile_backend_cannot_use_the_node(brick):
    """nxt-python's devfile backend wants a tty (Bluetooth framing): refused."""
    with pytest.raises(termios.error) as e:
        nxt.locator.find(backends=['devfile'], filename=brick.node, config=None)
    assert e.value.args[0] == errno.ENOTTY

def test_find_returns_working_brick(brick, nb):
    name, host, signal, flash = nb.get_device_info()
    assert (name, host) == ('NXT', HOST)
    assert flash == brick.fw.free_flash
    assert nb.get_firmware_version() == ((1, 124), (1, 29))
    assert nb.get_battery_level() == brick.fw.battery_mv
    brick.fw.battery_mv = 6543
    try:
        assert nb.get_battery_level() == 6543
    finally:
        brick.fw.battery_mv = 7823


def test_find_filters_by_name_host_and_node(brick):
    other = nxtdev.Brick('dummy_udc.1', SERIAL2, name='Second')
    other.plug()
    try:
        with find(name='Second') as b:
            assert b._sock.filename == other.node
            assert b.get_device_info()[:2] == ('Second', HOST2)
        # The host filter uses the USB serial in sysfs: the other brick
        # is not even opened, so it sees no command.
        before = other.emu.commands
        with find(host=HOST) as b:
            assert b._sock.filename == brick.node
        # The backend takes any spelling, the locator's own check does not.
        found = list(lego_nxt_linux.Backend().find(host=HOST.lower()))
        try:
            assert [b._sock.filename for b in found] == [brick.node]
        finally:
            for b in found:
                b.close()
        assert other.emu.commands == before
        with find(backends=[lego_nxt_linux.Backend(devices=[other.node])]) as b:
            assert b.get_device_info()[0] == 'Second'
        with find(filename=other.node) as b:
            assert b._sock.filename == other.node
        with pytest.raises(nxt.locator.BrickNotFoundError):
            find(name='Nobody')
        with pytest.raises(nxt.locator.BrickNotFoundError):
            find(host='00:16:53:FF:FF:FF')
        found = list(find(find_all=True))
        try:
            assert sorted(b.get_device_info()[0] for b in found) == ['NXT', 'Second']
        finally:
            for b in found:
                b.close()
    finally:
        other.unplug()
        assert other.wait_gone()


def test_play_tone(brick, nb):
    brick.fw.sound = None
    nb.play_tone(880, 300)
    # No reply is asked for: the write returns once the brick took it.
    deadline = time.monotonic() + 5
    while brick.fw.sound is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert brick.fw.sound is not None and brick.fw.sound[:2] == ('tone', 880)


def test_output_state_and_motor(brick, nb, packets):
    M = nxt.motor
    nb.set_output_state(M.Port.B, 40, M.Mode.ON, M.RegulationMode.IDLE, 0,
                        M.RunState.RUNNING, 0)
    state = nb.get_output_state(M.Port.B)
    assert state[0] == M.Port.B and state[1] == 40
    assert brick.fw.motors[1].power == 40
    nb.set_output_state(M.Port.B, 0, M.Mode.IDLE, M.RegulationMode.IDLE, 0,
                        M.RunState.IDLE, 0)
    assert nb.get_output_state(M.Port.B)[1] == 0

    motor = M.Motor(nb, M.Port.A)
    motor.reset_position(False)
    motor.turn(100, 360, emulate=False)
    assert brick.fw.motors[0].rotation == pytest.approx(360, abs=1)
    assert motor.get_tacho().rotation_count == pytest.approx(360, abs=1)
    motor.idle()
    assert not brick.fw.motors[0].running()
    # SetOutputState went without reply requests (type 0x80).
    assert any(p[:2] == b'\x80\x04' for p in packets)


def test_touch_sensor_and_input_values(brick, nb):
    S = nxt.sensor
    touch = S.generic.Touch(nb, S.Port.S1)
    brick.fw.set_touch(0, True)
    assert touch.is_pressed() is True
    brick.fw.set_touch(0, False)
    assert touch.is_pressed() is False
    values = nb.get_input_values(S.Port.S1)
    assert values[0] == S.Port.S1 and values[1] is True        # valid
    assert values[3] == S.Type.SWITCH
    assert values[5] == brick.fw.inputs[0].raw


def test_program_and_mailboxes(brick, nb):
    E = nxt.error
    with pytest.raises(E.NoActiveProgramError):
        nb.get_current_program_name()
    nb.start_program('Demo.rxe')
    deadline = time.monotonic() + 5
    while True:
        try:
            assert nb.get_current_program_name() == 'Demo.rxe'
            break
        except E.NoActiveProgramError:
            assert time.monotonic() < deadline, 'the program never started'
            time.sleep(0.05)
    try:
        nb.message_write(3, b'hello brick')
        assert brick.fw.program_receive(3) == b'hello brick\0'
        brick.fw.program_send(13, b'pong')
        assert nb.message_read(13, 3, True) == (3, b'pong\0')
        with pytest.raises(E.EmptyMailboxError):
            nb.message_read(13, 3, True)
    finally:
        nb.stop_program()
    deadline = time.monotonic() + 5
    while True:
        try:
            nb.get_current_program_name()
        except E.NoActiveProgramError:
            break
        assert time.monotonic() < deadline, 'the program never stopped'
        time.sleep(0.05)
    with pytest.raises(E.NoActiveProgramError):
        nb.message_write(3, b'nobody listens')


def test_file_upload_read_back_and_find(brick, nb, packets):
    data = bytes((i * 7 + 3) & 0xff for i in range(300))
    name = 'pyback.dat'
    with nb.open_file(name, 'wb', len(data)) as f:
        f.write(data)
    try:
        assert bytes(brick.fw.files[name].data) == data
        with nb.open_file(name, 'rb') as f:
            assert f.read() == data
        with nb.open_file(name, 'rb', buffering=0) as f:
            assert f.read(1000) == data[:58]     # one chunk at a time
        assert dict(nb.find_files('pyback.*')) == {name: len(data)}
        assert ('Demo.rxe', 256) in list(nb.find_files('*.rxe'))
        # USB-sized chunks: every Read asks for at most 58 bytes (what one
        # reply packet carries), every Write telegram fits one packet.
        reads = [int.from_bytes(p[3:5], 'little') for p in packets if p[:2] == b'\x01\x82']
        writes = [p for p in packets if p[:2] == b'\x01\x83']
        assert reads and max(reads) == 58
        assert len(writes) == 6       # 300 bytes in 58-byte chunks
        # Text mode goes through the same path.
        with nb.open_file('pyback.txt', 'w', 12) as f:
            f.write('hello, brick')
        try:
            with nb.open_file('pyback.txt') as f:
                assert f.read() == 'hello, brick'
        finally:
            nb.file_delete('pyback.txt')
    finally:
        nb.file_delete(name)
    assert name not in brick.fw.files


def test_brick_errors_are_nxt_python_exceptions(brick, nb):
    E = nxt.error
    with pytest.raises(E.FileNotFoundError):
        nb.open_file('Missing.txt', 'rb')
    with pytest.raises(E.FileExistsError):
        nb.open_file('Woops.rso', 'wb', 10)
    with pytest.raises(E.DirectProtocolError) as e:       # status 0xC0
        nb.start_program('Missing.rxe')
    assert 'out-of-range' in str(e.value)
    with pytest.raises(E.DirectProtocolError) as e:       # status 0xEC
        nb.stop_program()
    assert isinstance(e.value, E.NoActiveProgramError)
    # The brick still answers normally afterwards.
    assert nb.get_battery_level() == brick.fw.battery_mv


def test_timeout_is_an_oserror():
    mute = nxtdev.Brick('dummy_udc.1', SERIAL2, hostile='noreply')
    mute.plug()
    try:
        b = find(backends=[lego_nxt_linux.Backend(devices=[mute.node], timeout_ms=300)])
        try:
            t = time.monotonic()
            with pytest.raises(OSError) as e:
                b.get_battery_level()
            assert e.value.errno == errno.ETIMEDOUT
            assert time.monotonic() - t < 0.9       # the 300 ms timeout, not 1 s
        finally:
            b.close()
        with pytest.raises(ValueError):
            lego_nxt_linux.Backend(timeout_ms=0)
    finally:
        mute.unplug()
        assert mute.wait_gone()


def _wait(cond, timeout, what):
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


def test_libusb_backend_after_unbind(brick):
    import usb.core
    import usb.util
    E, M = nxt.error, nxt.motor
    intf = brick.interface()
    name = os.path.basename(intf)
    assert os.path.isdir('/dev/bus/usb'), 'libusb needs /dev/bus/usb'

    # Bound: nxt-python's own USB backend cannot configure the brick.
    with pytest.raises(usb.core.USBError) as e:
        nxt.locator.find(backends=['usb'], config=None)
    assert e.value.errno == errno.EBUSY
    assert brick.emu.wait_configured(10)
    assert nxtdev.interface_of(SERIAL) == intf      # still ours after the reset

    with open(nxtdev.DRIVER + '/unbind', 'w') as f:
        f.write(name)
    try:
        _wait(lambda: not os.path.exists(brick.node), 5, 'the node outlived the unbind')
        assert brick.node not in lego_nxt_linux.list_devices()
        with pytest.raises(nxt.locator.BrickNotFoundError):
            find()
        b = nxt.locator.find(backends=['usb'], config=None, host=HOST)
        dev = b._sock._dev
        try:
            assert dev.serial_number == SERIAL
            assert b.get_device_info()[:2] == ('NXT', HOST)
            assert b.get_battery_level() == brick.fw.battery_mv
            b.play_tone(440, 100)
            b.set_output_state(M.Port.C, 25, M.Mode.ON, M.RegulationMode.IDLE, 0,
                               M.RunState.RUNNING, 0)
            assert b.get_output_state(M.Port.C)[1] == 25
            assert brick.fw.motors[2].power == 25
            with pytest.raises(E.FileNotFoundError):
                b.open_file('Missing.txt', 'rb')
        finally:
            b.set_output_state(M.Port.C, 0, M.Mode.IDLE, M.RegulationMode.IDLE, 0,
                               M.RunState.IDLE, 0)
            b.close()
            # pyusb keeps the interface claimed until its resources go.
            usb.util.dispose_resources(dev)
    finally:
        with open(nxtdev.DRIVER + '/bind', 'w') as f:
            f.write(name)
    brick.node = nxtdev.node_of(SERIAL)
    assert brick.node, 'no node after the bind'
    with find(host=HOST) as b:
        assert b.get_battery_level() == brick.fw.battery_mv
        assert b.get_firmware_version()[1] == (1, 29)
