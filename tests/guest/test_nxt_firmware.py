"""The emulated NXT brick's firmware alone (no USB): the byte vectors, quirks
and behaviour of shared/research/nxt.md (sections 2.1-2.5 and 4.4) and the
LEGO direct command document. The expected bytes are written out from those
documents, not taken from the emulator."""
import os
import struct
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))
import nxt_brick  # noqa: E402


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t

    def advance(self, seconds):
        self.t += seconds


@pytest.fixture
def clock():
    return Clock()


@pytest.fixture
def fw(clock):
    return nxt_brick.Firmware(now=clock, bt_address='001653A0B1C2')


def h(s):
    return bytes.fromhex(s.replace(' ', ''))


def name(s, size=20):
    return s.encode().ljust(size, b'\0')


def run(fw, packet):
    return fw.handle(h(packet) if isinstance(packet, str) else packet)


def start_program(fw, clock, prog='Demo.rxe'):
    assert run(fw, b'\x00\x00' + name(prog)) == h('02 00 00')
    clock.advance(1.0)
    assert run(fw, '00 11')[2] == 0x00


# ---- section 4.4: vectors worked out from the firmware source ----

@pytest.mark.parametrize('request_hex,reply_hex', [
    ('00 12', '02 12 BE'),                          # GetButtonState: not in LEGO firmware
    ('00 30', '02 30 BE'),
    ('00 0E 07', '02 0E C0'),                       # LSGetStatus, bad port: 3 bytes
    ('00 10 07', '02 10 C0'),                       # LSRead, bad port: 3 bytes
    ('00 06 05', '02 06 C0' + ' 00' * 22),          # GetOutputState, bad port: still 25
    ('00 07 04', '02 07 C0' + ' 00' * 13),          # GetInputValues, bad port: still 16
    ('00 11', '02 11 EC' + ' 00' * 20),             # no program running
    ('00 13 00 00 01', '02 13 EC 00 00' + ' 00' * 59),
    ('01 88', '02 88 00 7C 01 1D 01'),              # 1.29
    ('00 0D', '02 0D 00 C0 27 09 00'),              # 600000 ms
])
def test_vectors(fw, request_hex, reply_hex):
    assert run(fw, request_hex) == h(reply_hex)


def test_start_missing_program(fw):
    assert run(fw, b'\x00\x00' + name('nofile.rxe')) == h('02 00 C0')
    assert run(fw, b'\x00\x02\x00' + name('nofile.rso')) == h('02 02 C0')


@pytest.mark.parametrize('kind', [0x02, 0x03, 0x82, 0x7F, 0xFF])
def test_no_reply_for_other_types(fw, kind):
    assert fw.handle(bytes([kind, 0x9B])) is None
    assert fw.handle(bytes([kind, 0x0B])) is None


def test_no_reply_types_still_run(fw):
    assert run(fw, '80 30') is None                 # unknown opcode: silently
    assert run(fw, '80 04 01 32 01 00 00 20 00000000') is None
    assert run(fw, '00 06 01')[3:5] == h('01 32')    # port 1, power 50
    assert fw.handle(b'\x81\x98' + name('Quiet', 16)) is None
    assert run(fw, '01 9B')[3:18] == name('Quiet', 15)


def test_unknown_direct_opcodes(fw):
    for op in [0x12, 0x14, 0x15, 0x16, 0x17, 0x18] + list(range(0x22, 0x100)):
        assert fw.handle(bytes([0x00, op])) == bytes([0x02, op, 0xBE]), hex(op)


@pytest.mark.parametrize('op', [0x8A, 0xA3, 0x93, 0xFF])
def test_unknown_system_opcode_returns_stale_bytes(fw, op):
    info = run(fw, '01 9B')
    assert len(info) == 33
    request = bytes([0x01, op]) + bytes(range(18))
    reply = fw.handle(request)
    assert len(reply) == len(request) + 2
    assert reply[:2] == bytes([0x02, op])
    assert reply[2:] == info[2:len(request) + 2]


def test_unknown_system_opcode_first_reply_is_zeros(fw):
    assert run(fw, '01 A3 41 42 43') == h('02 A3 00 00 00 00 00')  # 5 + 2


def test_short_command_reads_stale_bytes(fw):
    run(fw, '00 04 02 9C 01 00 00 20 00000000')     # port C, power -100
    assert run(fw, '00 06 02')[3:5] == h('02 9C')
    # Two bytes only: the port byte left in the receive buffer (02) is used.
    assert run(fw, '00 06')[3:5] == h('02 9C')


def test_extra_trailing_bytes_are_ignored(fw):
    reply = run(fw, '01 9B 00')                      # what aNXT sends
    assert len(reply) == 33 and reply[:3] == h('02 9B 00')


# ---- fixed reply lengths ----

@pytest.mark.parametrize('request_hex,length,status', [
    ('00 06 03', 25, 0xC0),
    ('00 07 09', 16, 0xC0),
    ('00 0E 00', 4, 0xE0),          # S1 is not a low-speed port
    ('00 10 00', 20, 0xE0),
    ('00 11', 23, 0xEC),
    ('00 13 0A 00 01', 64, 0xEC),
    ('00 1C 40', 21, 0xC0),
    ('00 20 07', 3, 0xBE),
    ('01 80' + '6E6F7065' + '00' * 16, 8, 0x87),     # OpenRead "nope"
    ('01 86' + '2A2E787878' + '00' * 15, 28, 0x87),  # FindFirst "*.xxx"
    ('01 87 0F', 28, 0x93),
    ('01 90' + '2A2E6E6F' + '00' * 16, 34, 0x90),    # FindFirstModule "*.no"
    ('01 82 0E 0A 00', 16, 0x93),                    # Read on no handle
    ('01 84 05', 4, 0x88),
    ('01 A2 00 3C', 5, 0x8A),                        # PollCommand n = 60 > 59
])
def test_error_replies_keep_their_length(fw, request_hex, length, status):
    reply = run(fw, request_hex)
    assert len(reply) == length
    assert reply[2] == status
    assert reply[3:].strip(b'\0') == b'' or request_hex.startswith(('00 13', '01 82', '01 84'))


def test_find_first_module_error_is_all_zero(fw):
    reply = run(fw, b'\x01\x90' + name('Nothing.mod'))
    assert reply == h('02 90 90') + bytes(31)


# ---- Read and ReadIOMap USB caps (quirk 6) ----

def test_read_caps_data_at_58_and_echoes_count(fw):
    fw.files['big.dat'] = nxt_brick.File('normal', 100, bytes(range(100)))
    reply = run(fw, b'\x01\x80' + name('big.dat'))
    assert reply[:3] == h('02 80 00')
    handle, size = struct.unpack('<BI', reply[3:8])
    assert size == 100
    reply = fw.handle(bytes([0x01, 0x82, handle, 100, 0]))
    assert len(reply) == 64
    assert reply[:6] == bytes([0x02, 0x82, 0x00, handle, 100, 0])
    assert reply[6:] == bytes(range(58))


def test_read_iomap_count_is_actual_and_data_capped_at_55(fw):
    mid, size = 0x00050001, 256                     # Comm.mod
    reply = run(fw, '01 94' + struct.pack('<IHH', mid, 0, 100).hex())
    assert len(reply) == 64
    assert reply[:3] == h('02 94 00')
    assert struct.unpack('<IH', reply[3:9]) == (mid, 55)
    assert reply[9:] == bytes(nxt_brick.iomap_pattern(mid, o) for o in range(55))
    # Near the end: the count says what was there, the data is padded.
    reply = run(fw, '01 94' + struct.pack('<IHH', mid, size - 4, 10).hex())
    assert len(reply) == 19
    assert struct.unpack('<IH', reply[3:9]) == (mid, 4)
    assert reply[13:] == bytes(6)


def test_iomap_is_deterministic_and_writable(fw):
    for mid in (0x00010001, 0x000C0001):
        reply = run(fw, '01 94' + struct.pack('<IHH', mid, 3, 5).hex())
        assert reply[9:] == bytes(nxt_brick.iomap_pattern(mid, 3 + i) for i in range(5))
    mid = 0x00080001
    reply = run(fw, '01 95' + struct.pack('<IHH', mid, 2, 3).hex() + 'AABBCC')
    assert reply == h('02 95 00') + struct.pack('<IH', mid, 3)
    reply = run(fw, '01 94' + struct.pack('<IHH', mid, 1, 5).hex())
    assert reply[9:] == bytes([nxt_brick.iomap_pattern(mid, 1), 0xAA, 0xBB, 0xCC,
                               nxt_brick.iomap_pattern(mid, 5)])
    assert run(fw, '01 94 78563412 0000 0400')[2] == 0x90


# ---- modules (quirk 8) ----

def test_module_search_handle_is_always_zero(fw):
    reply = run(fw, b'\x01\x90' + name('*.*'))
    assert len(reply) == 34 and reply[:4] == h('02 90 00 00')
    seen = [reply[4:24].rstrip(b'\0')]
    while True:
        reply = run(fw, '01 91 07')
        if reply[2] != 0:
            break
        assert reply[3] == 0
        seen.append(reply[4:24].rstrip(b'\0'))
    assert reply == h('02 91 90') + bytes(31)
    assert b'Loader.mod' in seen and b'Command.mod' in seen and len(seen) == len(set(seen))
    assert run(fw, '01 92 05') == h('02 92 00 00')
    reply = run(fw, b'\x01\x90' + name('Loader.*'))
    assert reply[4:24] == name('Loader.mod')
    assert struct.unpack('<I', reply[24:28])[0] == 0x00090001


# ---- programs and mailboxes (quirk 7) ----

def test_program_start_name_stop(fw, clock):
    assert run(fw, '00 01') == h('02 01 EC')
    assert run(fw, b'\x00\x00' + name('Demo.rxe')) == h('02 00 00')
    # The reply comes first; the UI starts the program a little later.
    assert run(fw, '00 11')[2] == 0xEC
    clock.advance(1.0)
    assert run(fw, '00 11') == h('02 11 00') + name('Demo.rxe')
    assert run(fw, '00 01') == h('02 01 00')
    clock.advance(1.0)
    assert run(fw, '00 11') == h('02 11 EC') + bytes(20)
    assert run(fw, '00 01') == h('02 01 EC')


def test_message_write_needs_a_program(fw, clock):
    assert run(fw, '00 09 00 03 41 42 00') == h('02 09 EC')
    start_program(fw, clock)
    assert run(fw, '00 09 00 03 41 42 00') == h('02 09 00')
    assert fw.program_receive(0) == b'AB\0'


def test_message_write_checks(fw, clock):
    start_program(fw, clock)
    assert run(fw, '00 09 01 00 00') == h('02 09 C0')            # size 0
    assert run(fw, '00 09 01 03 41 42 43') == h('02 09 C0')      # no NUL
    assert run(fw, '00 09 01 3C' + '41' * 59 + '00') == h('02 09 C0')   # 60 > 59
    assert run(fw, '00 09 14 02 41 00') == h('02 09 EE')         # queue 20
    assert run(fw, '00 09 01 3B' + '41' * 58 + '00') == h('02 09 00')   # 59: fits


def test_mailbox_keeps_five_and_drops_the_oldest(fw, clock):
    start_program(fw, clock)
    for i in range(7):
        assert run(fw, '00 09 04 02 %02x 00' % (0x30 + i)) == h('02 09 00')
    got = [fw.program_receive(4) for _ in range(6)]
    assert got == [b'2\0', b'3\0', b'4\0', b'5\0', b'6\0', None]


def test_message_read_from_outbox(fw, clock):
    assert run(fw, '00 13 0A 00 01')[2] == 0xEC
    start_program(fw, clock)
    assert run(fw, '00 13 0A 00 01') == h('02 13 40 00 00') + bytes(59)
    assert run(fw, '00 13 14 00 01')[2] == 0xEE
    fw.program_send(10, b'hello')
    fw.program_send(10, b'world')
    reply = run(fw, '00 13 0A 03 00')                 # peek
    assert reply == h('02 13 00 03 06') + b'hello\0'.ljust(59, b'\0')
    assert run(fw, '00 13 0A 03 01') == reply        # take
    reply = run(fw, '00 13 0A 03 01')
    assert reply[:5] == h('02 13 00 03 06') and reply[5:11] == b'world\0'
    assert run(fw, '00 13 0A 03 01')[2] == 0x40


def test_reply_telegram_to_message_read_is_stored(fw, clock):
    start_program(fw, clock)
    assert run(fw, '02 13 00 02 03 61 62 00') is None
    assert fw.program_receive(2) == b'ab\0'


# ---- motors ----

def output_state(fw, port):
    reply = run(fw, '00 06 %02x' % port)
    assert len(reply) == 25 and reply[:4] == bytes([2, 6, 0, port])
    return struct.unpack('<bBBbBIiii', reply[4:])


def test_motor_counts_advance_with_time(fw, clock):
    # Port B, power 50, MOTORON, regulation idle, turn 0, RUNNING, no limit.
    assert run(fw, '00 04 01 32 01 00 00 20 00000000') == h('02 04 00')
    clock.advance(2.0)
    power, mode, reg, turn, state, limit, tacho, block, rotation = output_state(fw, 1)
    assert (power, mode, state, limit) == (50, 1, 0x20, 0)
    # 10 degrees per second per unit of power (the emulator's documented rate).
    assert tacho == block == rotation == 1000
    # Ports A and C did not move.
    assert output_state(fw, 0)[6:] == (0, 0, 0)
    run(fw, '00 04 01 E7 01 00 00 20 00000000')       # power -25: a new goal
    clock.advance(1.0)
    assert output_state(fw, 1)[6:] == (-250, 750, 750)


def test_motor_stops_at_tacho_limit(fw, clock):
    run(fw, '00 04 00 64 01 00 00 20' + struct.pack('<I', 360).hex())
    clock.advance(0.2)
    assert output_state(fw, 0)[6] == 200
    clock.advance(5.0)
    state = output_state(fw, 0)
    assert state[4] == 0x00                          # idle
    assert state[6:] == (360, 360, 360)


@pytest.mark.parametrize('command', [
    '00 04 02 32 00 00 00 20 00000000',              # not MOTORON
    '00 04 02 00 01 00 00 20 00000000',              # power 0
    '00 04 02 32 01 00 00 00 00000000',              # run state idle
])
def test_motor_does_not_move(fw, clock, command):
    run(fw, command)
    clock.advance(1.0)
    assert output_state(fw, 2)[6:] == (0, 0, 0)


def test_motor_all_ports_and_resets(fw, clock):
    assert run(fw, '00 04 03 32 01 00 00 20 00000000') == h('02 04 C0')
    run(fw, '00 04 FF 0A 01 00 00 20 00000000')
    clock.advance(1.0)
    for port in range(3):
        assert output_state(fw, port)[6:] == (100, 100, 100)
    assert run(fw, '00 0A 00 01') == h('02 0A 00')    # relative: block count
    assert output_state(fw, 0)[6:] == (100, 0, 100)
    run(fw, '00 0A 00 00')                            # absolute: rotation count
    assert output_state(fw, 0)[6:] == (100, 0, 0)
    assert run(fw, '00 21 00') == h('02 21 00')       # UpdateResetCount
    assert output_state(fw, 0)[6] == 0
    assert run(fw, '00 0A 03 00') == h('02 0A C0')


# ---- inputs ----

def input_values(fw, port):
    reply = run(fw, '00 07 %02x' % port)
    assert len(reply) == 16 and reply[:4] == bytes([2, 7, 0, port])
    return struct.unpack('<BBBBHHhh', reply[4:])


def test_touch_sensor(fw, clock):
    assert run(fw, '00 05 00 01 20') == h('02 05 00')  # S1: SWITCH, BOOLEAN
    valid, calibrated, stype, mode, raw, norm, scaled, cal = input_values(fw, 0)
    assert (valid, calibrated, stype, mode) == (0, 0, 0x01, 0x20)
    clock.advance(0.5)
    assert input_values(fw, 0)[0] == 1
    assert input_values(fw, 0)[6] == 0                 # released
    fw.set_touch(0, True)
    values = input_values(fw, 0)
    assert values[6] == 1 and values[5] < 0.45 * 1023
    fw.set_touch(0, False)
    run(fw, '00 05 00 01 40')                          # TRANSITIONCNT
    clock.advance(0.5)
    for _ in range(3):
        fw.set_touch(0, True)
        input_values(fw, 0)
        fw.set_touch(0, False)
        input_values(fw, 0)
    assert input_values(fw, 0)[6] == 6
    assert run(fw, '00 08 00') == h('02 08 00')        # ResetInputScaledValue
    assert input_values(fw, 0)[6] == 0


def test_light_sensor_percent(fw, clock):
    run(fw, '00 05 02 05 80')                          # S3: LIGHT_ACTIVE, PCTFULLSCALE
    clock.advance(0.5)
    valid, _, stype, mode, raw, norm, scaled, cal = input_values(fw, 2)
    assert (valid, stype, mode) == (1, 5, 0x80)
    assert 0 < raw < 1023
    assert scaled == (1023 - norm) * 100 // 1023
    assert cal == norm
    assert run(fw, '00 05 04 01 00') == h('02 05 C0')


# ---- the ultrasonic sensor over I2C ----

def ls_write(fw, port, tx, rxlen):
    return fw.handle(bytes([0x00, 0x0F, port, len(tx), rxlen]) + tx)


def i2c_read(fw, clock, port, tx, rxlen):
    assert ls_write(fw, port, tx, rxlen) == h('02 0F 00')
    clock.advance(0.05)
    assert run(fw, '00 0E %02x' % port) == bytes([2, 0x0E, 0, rxlen])
    reply = run(fw, '00 10 %02x' % port)
    assert len(reply) == 20 and reply[:4] == bytes([2, 0x10, 0, rxlen])
    return reply[4:4 + rxlen]


def test_ultrasonic_i2c_sequence(fw, clock):
    fw.ultrasonic.distance = 123
    assert run(fw, '00 05 03 0B 00') == h('02 05 00')  # S4: LOWSPEED_9V, RAW
    assert ls_write(fw, 3, h('02 42'), 1) == h('02 0F E0')   # not ready yet
    clock.advance(0.5)
    assert ls_write(fw, 3, h('02 42'), 1) == h('02 0F 00')
    # The transaction takes a few ms: pending (0x20) meanwhile.
    assert run(fw, '00 0E 03') == h('02 0E 20 00')
    assert run(fw, '00 10 03') == h('02 10 20') + bytes(17)
    assert ls_write(fw, 3, h('02 42'), 1) == h('02 0F E0')   # busy
    clock.advance(0.010)
    assert run(fw, '00 0E 03') == h('02 0E 00 01')
    assert run(fw, '00 10 03') == h('02 10 00 01 7B') + bytes(15)
    assert run(fw, '00 0E 03') == h('02 0E 00 00')           # read once
    assert i2c_read(fw, clock, 3, h('02 00'), 8) == b'V1.0\0\0\0\0'
    assert i2c_read(fw, clock, 3, h('02 08'), 8) == b'LEGO\0\0\0\0'
    assert i2c_read(fw, clock, 3, h('02 10'), 8) == b'Sonar\0\0\0'
    fw.ultrasonic.distance = 42
    assert i2c_read(fw, clock, 3, h('02 42'), 1) == bytes([42])


def test_i2c_errors(fw, clock):
    run(fw, '00 05 03 0B 00')
    run(fw, '00 05 00 0B 00')                          # S1 (a touch sensor) as I2C
    clock.advance(0.5)
    assert ls_write(fw, 3, bytes(17), 1) == h('02 0F ED')
    assert ls_write(fw, 3, h('02 42'), 17) == h('02 0F ED')
    assert ls_write(fw, 5, h('02 42'), 1) == h('02 0F C0')
    assert ls_write(fw, 1, h('02 42'), 1) == h('02 0F E0')   # S2 is analog
    assert ls_write(fw, 3, h('04 42'), 1) == h('02 0F 00')   # nobody at 0x04
    assert ls_write(fw, 0, h('02 42'), 1) == h('02 0F 00')   # no I2C device
    clock.advance(0.05)
    assert run(fw, '00 0E 03') == h('02 0E DD 00')
    assert run(fw, '00 0E 00') == h('02 0E DD 00')
    assert run(fw, '00 0E 09') == h('02 0E C0')


# ---- the file system ----

def test_upload_then_find_and_read_back(fw):
    content = bytes((i * 7) & 0xFF for i in range(100))
    free = struct.unpack('<I', run(fw, '01 9B')[29:33])[0]
    reply = fw.handle(b'\x01\x81' + name('hello.txt') + struct.pack('<I', 100))
    assert reply[:3] == h('02 81 00') and len(reply) == 4
    handle = reply[3]
    reply = fw.handle(bytes([0x01, 0x83, handle]) + content[:61])   # 61: USB maximum
    assert reply == bytes([2, 0x83, 0, handle, 61, 0])
    reply = fw.handle(bytes([0x01, 0x83, handle]) + content[61:])
    assert reply == bytes([2, 0x83, 0, handle, 39, 0])
    assert fw.handle(bytes([0x01, 0x84, handle])) == bytes([2, 0x84, 0, handle])
    assert free - struct.unpack('<I', run(fw, '01 9B')[29:33])[0] >= 100

    reply = fw.handle(b'\x01\x86' + name('*.txt'))
    assert len(reply) == 28 and reply[2] == 0
    fh = reply[3]
    assert reply[4:24] == name('hello.txt')
    assert struct.unpack('<I', reply[24:28])[0] == 100
    assert fw.handle(bytes([0x01, 0x87, fh])) == bytes([2, 0x87, 0x87]) + bytes(25)
    assert fw.handle(bytes([0x01, 0x84, fh]))[2] == 0

    reply = fw.handle(b'\x01\x80' + name('hello.txt'))
    assert reply[2] == 0 and struct.unpack('<I', reply[4:8])[0] == 100
    rh = reply[3]
    first = fw.handle(bytes([0x01, 0x82, rh, 58, 0]))
    second = fw.handle(bytes([0x01, 0x82, rh, 42, 0]))
    assert first[:6] == bytes([2, 0x82, 0, rh, 58, 0])
    assert second[:6] == bytes([2, 0x82, 0, rh, 42, 0])
    assert first[6:] + second[6:] == content
    fw.handle(bytes([0x01, 0x84, rh]))

    assert fw.handle(b'\x01\x85' + name('hello.txt')) == h('02 85 00') + name('hello.txt')
    assert fw.handle(b'\x01\x86' + name('hello.txt'))[2] == 0x87
    assert fw.handle(b'\x01\x85' + name('hello.txt')) == h('02 85 87') + name('hello.txt')


def test_find_patterns(fw):
    fw.files.clear()
    for n in ('a.rxe', 'b.rxe', 'a.rso', 'c.txt'):
        fw.files[n] = nxt_brick.File('normal', 1, b'x')

    def find(pattern):
        found = []
        reply = fw.handle(b'\x01\x86' + name(pattern))
        while reply[2] == 0:
            found.append(reply[4:24].rstrip(b'\0').decode())
            reply = fw.handle(bytes([0x01, 0x87, reply[3]]))
        assert reply[2] == 0x87
        return found

    assert find('*.*') == ['a.rxe', 'b.rxe', 'a.rso', 'c.txt']
    assert find('a.*') == ['a.rxe', 'a.rso']
    assert find('*.rxe') == ['a.rxe', 'b.rxe']
    assert find('c.txt') == ['c.txt']
    assert find('d.txt') == []


def test_file_errors(fw):
    create = b'\x01\x81' + name('f.txt') + struct.pack('<I', 10)
    reply = fw.handle(create)
    assert reply[2] == 0
    handle = reply[3]
    assert fw.handle(create)[2] == 0x8F                        # exists
    assert fw.handle(b'\x01\x80' + name('f.txt'))[2] == 0x8B   # being written
    assert fw.handle(b'\x01\x85' + name('f.txt'))[2] == 0x8B
    assert fw.handle(bytes([1, 0x83, handle]) + bytes(12)) == bytes([2, 0x83, 0x8E, handle, 10, 0])
    assert fw.handle(bytes([1, 0x84, handle]))[2] == 0
    assert fw.handle(bytes([1, 0x84, handle])) == bytes([2, 0x84, 0x88, handle])
    assert fw.handle(bytes([1, 0x83, handle]) + b'x')[2] == 0x93
    assert fw.handle(b'\x01\x80' + name('missing.txt')) == h('02 80 87') + bytes(5)
    assert fw.handle(b'\x01\x81' + bytes(20) + bytes(4))[2] == 0x92        # empty name
    assert fw.handle(b'\x01\x8B' + name('prog.rxe') + bytes(4))[2] == 0x92
    too_big = struct.pack('<I', nxt_brick.FLASH_BYTES)
    assert fw.handle(b'\x01\x81' + name('huge.dat') + too_big)[2] == 0x82
    assert fw.handle(b'\x01\x89' + name('huge.rxe') + too_big)[2] == 0x89


def test_handles_run_out(fw):
    handles = set()
    for i in range(16):
        reply = fw.handle(b'\x01\x80' + name('Demo.rxe'))
        assert reply[2] == 0
        handles.add(reply[3])
    assert len(handles) == 16
    assert fw.handle(b'\x01\x80' + name('Demo.rxe'))[2] == 0x81


def test_data_file_append(fw):
    reply = fw.handle(b'\x01\x8B' + name('log.dat') + struct.pack('<I', 20))
    assert reply[2] == 0
    fw.handle(bytes([1, 0x83, reply[3]]) + b'12345')
    fw.handle(bytes([1, 0x84, reply[3]]))
    reply = fw.handle(b'\x01\x8C' + name('log.dat'))
    assert reply[2] == 0 and struct.unpack('<I', reply[4:8])[0] == 15
    assert fw.handle(bytes([1, 0x83, reply[3]]) + b'67') == bytes([2, 0x83, 0, reply[3], 2, 0])
    assert fw.handle(bytes([1, 0x8D, reply[3]])) == bytes([2, 0x8D, 0, reply[3]])   # crop
    fw.handle(bytes([1, 0x84, reply[3]]))
    assert fw.handle(b'\x01\x8C' + name('log.dat'))[2] == 0x8E                     # full
    assert struct.unpack('<I', fw.handle(b'\x01\x86' + name('log.dat'))[24:28])[0] == 7
    assert fw.handle(b'\x01\x8C' + name('Woops.rso'))[2] == 0x8D
    assert fw.handle(b'\x01\x8C' + name('none.dat'))[2] == 0x87


def test_usb_handles_close_on_disconnect(fw):
    reply = fw.handle(b'\x01\x80' + name('Demo.rxe'))
    handle = reply[3]
    fw.usb_disconnected()
    assert fw.handle(bytes([1, 0x82, handle, 4, 0]))[2] == 0x93
    assert fw.handle(bytes([1, 0x84, handle]))[2] == 0x88


def test_delete_user_flash(fw):
    assert run(fw, '01 A0') == h('02 A0 00')
    assert fw.busy > 0
    assert fw.handle(b'\x01\x86' + name('*.*'))[2] == 0x87
    assert struct.unpack('<I', run(fw, '01 9B')[29:33])[0] == nxt_brick.FLASH_BYTES


# ---- brick identity and the rest ----

def test_device_info_and_bt_address(fw):
    reply = run(fw, '01 9B')
    assert len(reply) == 33
    assert reply[:18] == h('02 9B 00') + b'NXT'.ljust(15, b'\0')
    assert reply[18:25] == h('00 16 53 A0 B1 C2 00')
    assert run(fw, '01 9A') == h('02 9A 00 00 16 53 A0 B1 C2 00')
    assert run(fw, '01 98' + b'MyBrick'.ljust(16, b'\0').hex()) == h('02 98 00')
    assert run(fw, '01 9B')[3:18] == b'MyBrick'.ljust(15, b'\0')


def test_battery_and_keep_alive(fw):
    reply = run(fw, '00 0B')
    assert len(reply) == 5 and reply[:3] == h('02 0B 00')
    assert 6000 <= struct.unpack('<H', reply[3:])[0] <= 9500
    fw.battery_mv = 8184
    assert run(fw, '00 0B') == h('02 0B 00 F8 1F')
    assert run(fw, '00 1F 02' + struct.pack('<I', 300000).hex()) == h('02 1F 00')
    assert run(fw, '00 0D') == h('02 0D 00') + struct.pack('<I', 300000)
    assert run(fw, '00 20 02') == h('02 20 00') + struct.pack('<I', 300000)


def test_properties_and_bluetooth(fw):
    assert run(fw, '00 1F 01 09') == h('02 1F 00')
    assert run(fw, '00 20 01') == h('02 20 00 04')     # volume clamped to 4
    assert run(fw, '00 1F 09 01') == h('02 1F BE')
    assert run(fw, '00 1B') == h('02 1B 00 1E')        # 30 contacts
    assert run(fw, '00 1D') == h('02 1D 00 04')        # 4 connections
    assert len(run(fw, '00 1E 00')) == 21


def test_poll_buffers(fw):
    fw.program_poll_write(0, b'abc')
    assert run(fw, '01 A1 00') == h('02 A1 00 00 03')
    assert run(fw, '01 A2 00 05') == h('02 A2 00 00 03 61 62 63 00 00')
    assert run(fw, '01 A1 00') == h('02 A1 00 00 00')
    assert run(fw, '01 A2 00 3C') == h('02 A2 8A 00 00')


def test_boot_command(fw):
    assert not fw.rebooting
    assert run(fw, '01 97' + b"Let's dance: SAMBA\0".hex()) == h('02 97 00') + b'Yes\0'
    assert fw.rebooting
