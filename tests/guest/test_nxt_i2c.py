"""The NXT's sensor ports as I2C adapters (drivers/lego/nxt/nxt_i2c.c),
against the emulated brick (tests/emulator/nxt_brick.py), whose port 4 has
LEGO's ultrasonic sensor (address 0x02 in LEGO's 8-bit notation, 0x01 for
Linux): its strings and its distance are read with i2c-tools (i2cget,
i2cdump, i2cdetect) and from C through /dev/i2c-N (nxt_i2c_client.c), on
USB and on a serial line (Bluetooth's framing). A port with no I2C device
gives the brick's bus error as ENXIO, not a hang; what one LSWrite cannot
carry is refused with EOPNOTSUPP before anything is sent; the adapters take
turns with the other users of the brick and go away with it.
"""
import glob
import os
import re
import subprocess
import threading
import time

import pytest

import nxtdev as nxt
from conftest import wait_for

SERIAL = '0016530A0B0C'
US = 0x01                   # the ultrasonic sensor's 7-bit address
US_PORT = 4                 # the emulated brick's default: ports 1-3 are analog
DISTANCE = 0x42             # its first echo's distance register, in cm
STRINGS = {0x00: b'V1.0', 0x08: b'LEGO', 0x10: b'Sonar'}


def adapters(node):
    """{port: bus number} of a brick's adapters, children of its node."""
    out = {}
    for d in glob.glob('/sys/class/lego-nxt/%s/i2c-*' % os.path.basename(node)):
        with open(os.path.join(d, 'name')) as f:
            m = re.fullmatch(r'NXT (\S+) port ([1-4])', f.read().strip())
        assert m, d
        out[int(m.group(2))] = (int(d.rsplit('-', 1)[1]), m.group(1))
    return out


def bus(node, port):
    return adapters(node)[port][0]


def run(*args, timeout=60):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope='module')
def client(tmp_path_factory):
    out = str(tmp_path_factory.mktemp('i2c') / 'nxt_i2c_client')
    subprocess.run(['cc', '-O2', '-Wall', '-Wextra', '-Werror',
                    os.path.join(nxt.TOP, 'tests', 'guest', 'nxt_i2c_client.c'),
                    '-o', out], check=True)
    return out


def transfer(client, busnr, *msgs, count=1, addr=US):
    p = run(client, '-n', count, '/dev/i2c-%d' % busnr, hex(addr), *msgs)
    if p.returncode == 2:
        lines = p.stdout.split('\n')
        return int(lines[0].split()[1]), lines[1].split()[1]
    assert p.returncode == 0, (p.returncode, p.stdout, p.stderr)
    return [bytes.fromhex(ln) for ln in p.stdout.split()]


def test_one_adapter_per_port_named_by_the_serial(brick):
    ads = adapters(brick.node)
    assert sorted(ads) == [1, 2, 3, 4]
    assert {serial for _, serial in ads.values()} == {SERIAL}
    listed = run('i2cdetect', '-l').stdout
    for port, (nr, _) in ads.items():
        assert re.search(r'^i2c-%d\s+i2c\s+NXT %s port %d\s' % (nr, SERIAL, port),
                         listed, re.M), listed
        assert os.path.exists('/dev/i2c-%d' % nr)
    # What the brick can do, and no more: I2C, and the SMBus transactions
    # that fit in one LSWrite (no block reads, no PEC, no 10-bit).
    funcs = run('i2cdetect', '-F', ads[US_PORT][0]).stdout
    for name, want in (('I2C', 'yes'), ('SMBus Quick Command', 'yes'),
                       ('SMBus Read Byte', 'yes'), ('SMBus Write Word', 'yes'),
                       ('SMBus Block Read', 'no'), ('I2C Block Read', 'no'),
                       ('SMBus PEC', 'no')):
        assert re.search(r'^%s\s+%s$' % (re.escape(name), want), funcs, re.M), (name, funcs)


def test_i2cget_reads_the_distance(brick):
    nr = bus(brick.node, US_PORT)
    for cm in (123, 45, 255):
        brick.fw.ultrasonic.distance = cm
        p = run('i2cget', '-y', '-a', nr, hex(US), hex(DISTANCE))
        assert p.returncode == 0, (p.stdout, p.stderr)
        assert int(p.stdout, 16) == cm
    # By the adapter's name too, as the documentation shows it.
    brick.fw.ultrasonic.distance = 77
    p = run('i2cget', '-y', '-a', 'NXT %s port %d' % (SERIAL, US_PORT), hex(US), hex(DISTANCE))
    assert (p.returncode, p.stdout.strip()) == (0, '0x4d'), (p.stdout, p.stderr)


def test_strings_and_distance_from_c(brick, client):
    nr = bus(brick.node, US_PORT)
    for reg, text in STRINGS.items():
        data, = transfer(client, nr, 'w:%02x' % reg, 'r:8')
        assert data == text.ljust(8, b'\0'), (reg, data)
    brick.fw.ultrasonic.distance = 31
    assert transfer(client, nr, 'w:42', 'r:1') == [b'\x1f']
    # Sixteen bytes, the most a read can have: the measurement registers.
    data, = transfer(client, nr, 'w:40', 'r:16')
    assert data == bytes(brick.fw.ultrasonic.regs[0x40:0x50])
    assert data[2] == 31
    # A write alone, then read back: the continuous measurement interval.
    assert transfer(client, nr, 'w:4005') == []
    assert transfer(client, nr, 'w:40', 'r:1') == [b'\x05']
    assert brick.fw.ultrasonic.regs[0x40] == 5
    transfer(client, nr, 'w:4001')


def test_i2cdump_and_i2cdetect(brick):
    nr = bus(brick.node, US_PORT)
    brick.fw.ultrasonic.distance = 99
    p = run('i2cdump', '-y', '-a', '-r', '0x40-0x4f', nr, hex(US), 'b')
    assert p.returncode == 0, (p.stdout, p.stderr)
    row = re.search(r'^40: ((?:[0-9a-f]{2} ){16})', p.stdout, re.M)
    assert row, p.stdout
    assert bytes.fromhex(row.group(1)) == bytes(brick.fw.ultrasonic.regs[0x40:0x50])
    # The sensor answers at its address, and nothing else on its port.
    p = run('i2cdetect', '-y', '-a', '-q', nr, '0x00', '0x0f', timeout=120)
    assert p.returncode == 0, (p.stdout, p.stderr)
    found = re.findall(r' ([0-9a-f]{2})(?= |$)', p.stdout.split('\n', 1)[1], re.M)
    assert found == ['01'], p.stdout


def test_ports_without_an_i2c_device(brick, client):
    """The brick's bus error as ENXIO (nothing acknowledged), not a
    timeout (ETIMEDOUT, after the adapter's second) nor a hang."""
    before = brick.fw.inputs[1].device
    brick.fw.inputs[1].device = None
    try:
        for port in (1, 2):
            nr = bus(brick.node, port)
            assert transfer(client, nr, 'w:42', 'r:1') == (0, 'ENXIO')
            p = run('i2cget', '-y', '-a', nr, hex(US), hex(DISTANCE))
            assert p.returncode != 0
        # The sensor port answers only at its own address.
        assert transfer(client, bus(brick.node, US_PORT), 'w:42', 'r:1',
                        addr=0x02) == (0, 'ENXIO')
    finally:
        brick.fw.inputs[1].device = before


def test_what_one_lswrite_cannot_carry_is_refused(brick, client):
    nr = bus(brick.node, US_PORT)
    before = sum(brick.fw.handled.values())
    for msgs in (('w:00', 'r:1', 'r:1'),            # three messages
                 ('r:1', 'w:00'),                   # a read first
                 ('w:' + '00' * 16,),               # 16 bytes and the address
                 ('w:00', 'r:17'),                  # more than 16 read
                 ('r:17',),
                 ('r:0',)):                         # a read of nothing
        assert transfer(client, nr, *msgs) == (0, 'EOPNOTSUPP'), msgs
    assert sum(brick.fw.handled.values()) == before, 'a refused transfer sent telegrams'
    # Fifteen bytes written is the most, and it goes: one LSWrite.
    writes = brick.fw.handled[0x00, 0x0f]
    assert transfer(client, nr, 'w:' + '50' + '00' * 14) == []
    assert brick.fw.handled[0x00, 0x0f] == writes + 1


def test_a_port_set_to_another_mode_is_set_back(brick, fd):
    """Another user of the brick sets the port to a non-I2C mode: the next
    transfer sets low-speed mode again, and reads the sensor."""
    nr = bus(brick.node, US_PORT)
    brick.fw.ultrasonic.distance = 12
    assert run('i2cget', '-y', '-a', nr, hex(US), hex(DISTANCE)).stdout.strip() == '0x0c'
    # SetInputMode(port 4, SWITCH, BOOLEAN): no longer low-speed.
    assert nxt.transact(fd, bytes([0x00, 0x05, US_PORT - 1, 0x01, 0x20])) == (0, b'\x02\x05\x00')
    assert brick.fw.inputs[US_PORT - 1].type == 0x01
    p = run('i2cget', '-y', '-a', nr, hex(US), hex(DISTANCE))
    assert (p.returncode, p.stdout.strip()) == (0, '0x0c'), (p.stdout, p.stderr)
    assert brick.fw.inputs[US_PORT - 1].type == 0x0b


@pytest.fixture
def fd(brick):
    f = brick.open()
    yield f
    os.close(f)


def test_ports_and_other_users_take_turns(brick, client):
    """Two readers of the sensor's port, one of another port and a user of
    /dev/nxtN at once: every transfer and telegram gets its own answer."""
    nr = bus(brick.node, US_PORT)
    brick.fw.ultrasonic.distance = 66
    results, errors = [], []

    def reader():
        try:
            results.append(transfer(client, nr, 'w:08', 'r:8', count=25))
        except Exception as e:      # noqa: BLE001 - reported below
            errors.append(e)

    def other_port():
        try:
            results.append(transfer(client, bus(brick.node, 1), 'w:42', 'r:1', count=5))
        except Exception as e:      # noqa: BLE001
            errors.append(e)

    def user():
        try:
            f = brick.open()
            try:
                for _ in range(40):
                    err, reply = nxt.transact(f, b'\x00\x0b')
                    assert err == 0 and reply[:3] == b'\x02\x0b\x00', reply
            finally:
                os.close(f)
        except Exception as e:      # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=t) for t in (reader, reader, other_port, user)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not errors, errors
    assert sorted(map(repr, results)) == sorted(map(repr, [[b'LEGO\0\0\0\0']] * 2 + [(0, 'ENXIO')]))


def test_unplug_during_transfers(client):
    """Transfers in a loop when the brick goes: they fail, the adapters go
    with the brick once their files are closed, nothing hangs."""
    b = nxt.Brick('dummy_udc.1', '0016530A0B0D')
    b.plug()
    try:
        nr = bus(b.node, US_PORT)
        p = subprocess.Popen([client, '-n', '0', '/dev/i2c-%d' % nr, hex(US), 'w:42', 'r:1'],
                             stdout=subprocess.PIPE, text=True)
        time.sleep(1.0)
        assert p.poll() is None, p.stdout.read()
    finally:
        b.unplug()
    out = p.communicate(timeout=30)[0].split('\n')
    assert p.returncode == 2, out
    assert int(out[0].split()[1]) > 0
    assert out[1].split()[1] in ('ENODEV', 'EIO', 'EPROTO', 'ETIMEDOUT'), out
    assert b.wait_gone(10)
    assert wait_for(lambda: not os.path.exists('/dev/i2c-%d' % nr), 5)


def test_over_a_serial_line():
    """The same adapters on a brick on a serial line (Bluetooth's framing),
    named after the tty when the brick's serial number is not known."""
    from test_nxt_serial import Attached
    b = Attached()
    try:
        b.fw.ultrasonic.distance = 88
        ads = adapters(b.node)
        assert sorted(ads) == [1, 2, 3, 4]
        nr, name = ads[US_PORT]
        # The tty's name as the kernel has it: /dev/pts/0 is pts0.
        assert name == b.tty[len('/dev/'):].replace('/', ''), name
        p = run('i2cget', '-y', '-a', nr, hex(US), hex(DISTANCE))
        assert (p.returncode, p.stdout.strip()) == (0, '0x58'), (p.stdout, p.stderr)
        p = run('i2cget', '-y', '-a', ads[1][0], hex(US), hex(DISTANCE))
        assert p.returncode != 0
    finally:
        b.close()
