"""Helpers for the NXT guest tests: the uapi of /dev/nxtN in Python.

The ioctl numbers and the structure layout are written out here by hand and
checked against include/uapi/linux/lego_nxt.h by uapi_layout(), which
compiles a small C program against the header. The direct commands are
built and decoded here (command()), as a program does with liblegonxt.
"""
import ctypes
import errno
import glob
import os
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))
import nxt_brick  # noqa: E402

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
DRIVER = '/sys/bus/usb/drivers/lego_nxt_usb'

MAGIC = 0xE4
_IOC_WRITE, _IOC_READ = 1, 2


def _ioc(direction, nr, size):
    return direction << 30 | size << 16 | MAGIC << 8 | nr


def iowr(nr, size):
    return _ioc(_IOC_READ | _IOC_WRITE, nr, size)


STRUCTS = {
    'transaction': ('<64s64sII', 'telegram reply length reply_length'),
}

# The direct commands the tests send, built and decoded here in Python: the
# kernel only carries telegrams. Written from the firmware's documentation
# (research nxt.md), not from liblegonxt, so that each checks the other.
# name -> (opcode, request format and fields after the opcode,
#          reply format and fields after the status byte, reply length)
COMMANDS = {
    'START_PROGRAM': (0x00, '<20s', 'name', '', '', 3),
    'STOP_PROGRAM': (0x01, '', '', '', '', 3),
    'PLAY_SOUND_FILE': (0x02, '<B20s', 'loop name', '', '', 3),
    'PLAY_TONE': (0x03, '<HH', 'frequency duration', '', '', 3),
    'SET_OUTPUT_STATE': (0x04, '<BbBBbBI', 'port power mode regulation_mode turn_ratio '
                         'run_state tacho_limit', '', '', 3),
    'SET_INPUT_MODE': (0x05, '<BBB', 'port type mode', '', '', 3),
    'GET_OUTPUT_STATE': (0x06, '<B', 'port', '<BbBBbBIiii',
                         'port power mode regulation_mode turn_ratio run_state tacho_limit '
                         'tacho_count block_tacho_count rotation_count', 25),
    'GET_INPUT_VALUES': (0x07, '<B', 'port', '<BBBBBHHhh',
                         'port valid calibrated type mode raw normalized scaled '
                         'calibrated_value', 16),
    'RESET_INPUT_SCALED_VALUE': (0x08, '<B', 'port', '', '', 3),
    'MESSAGE_WRITE': (0x09, '<BB', 'inbox size', '', '', 3),          # then the message
    'RESET_MOTOR_POSITION': (0x0a, '<BB', 'port relative', '', '', 3),
    'GET_BATTERY_LEVEL': (0x0b, '', '', '<H', 'millivolts', 5),
    'STOP_SOUND_PLAYBACK': (0x0c, '', '', '', '', 3),
    'KEEP_ALIVE': (0x0d, '', '', '<I', 'sleep_limit', 7),
    'LS_GET_STATUS': (0x0e, '<B', 'port', '<B', 'bytes_ready', 4),
    'LS_WRITE': (0x0f, '<BBB', 'port tx_length rx_length', '', '', 3),  # then the bytes
    'LS_READ': (0x10, '<B', 'port', '<B16s', 'length data', 20),
    'GET_CURRENT_PROGRAM_NAME': (0x11, '', '', '<20s', 'name', 23),
    'MESSAGE_READ': (0x13, '<BBB', 'inbox local_inbox remove', '<BB59s',
                     'local_inbox size data', 64),
}

# Status bytes of the brick that the tests look for.
STATUS_PENDING = 0x20
STATUS_MAILBOX_EMPTY = 0x40
STATUS_FILE_NOT_FOUND = 0x87
STATUS_OUT_OF_RANGE = 0xc0
STATUS_CHANNEL_BUSY = 0xe0
STATUS_NO_PROGRAM = 0xec


# What the firmware reads of each known command (drivers/lego/nxt/nxt_proto.c,
# nxt_request_complete()): opcode -> (shortest telegram, offset of a string
# that must end in the telegram, or 0). Written out again here from the
# firmware's handlers, so that the driver's table is checked, not copied.
DIRECT_REQUEST = {
    0x00: (3, 2), 0x01: (2, 0), 0x02: (4, 3), 0x03: (6, 0), 0x04: (12, 0), 0x05: (5, 0),
    0x06: (3, 0), 0x07: (3, 0), 0x08: (3, 0), 0x09: (4, 0), 0x0a: (4, 0), 0x0b: (2, 0),
    0x0c: (2, 0), 0x0d: (2, 0), 0x0e: (3, 0), 0x0f: (5, 0), 0x10: (3, 0), 0x11: (2, 0),
    0x13: (5, 0), 0x19: (3, 0), 0x1a: (6, 0), 0x1b: (2, 0), 0x1c: (3, 0), 0x1d: (2, 0),
    0x1e: (3, 0), 0x1f: (4, 0), 0x20: (3, 0), 0x21: (3, 0),
}
SYSTEM_REQUEST = {
    0x80: (3, 2), 0x81: (26, 0), 0x82: (5, 0), 0x83: (3, 0), 0x84: (3, 0), 0x85: (3, 2),
    0x86: (3, 2), 0x87: (3, 0), 0x88: (2, 0), 0x89: (26, 0), 0x8b: (26, 0), 0x8c: (3, 2),
    0x8d: (3, 0), 0x90: (3, 2), 0x91: (3, 0), 0x92: (3, 0), 0x94: (10, 0), 0x95: (10, 0),
    0x97: (3, 2), 0x98: (3, 2), 0x9a: (2, 0), 0x9b: (2, 0), 0xa0: (2, 0), 0xa1: (3, 0),
    0xa2: (4, 0), 0xa4: (2, 0),
}


def request_complete(tg):
    """Whether a command telegram (2 to 64 bytes, type 0x00/0x01/0x80/0x81)
    holds every byte its command reads: else the driver refuses it (EINVAL)."""
    table = DIRECT_REQUEST if tg[0] & 0x7f == 0x00 else SYSTEM_REQUEST
    if tg[1] not in table:
        return True
    need, string_at = table[tg[1]]
    if len(tg) < need:
        return False
    if string_at:
        # A brick name may also be its 15 characters without a NUL.
        return 0 in tg[string_at:] or (tg[1] == 0x98 and len(tg) >= string_at + 15)
    if tg[0] & 0x7f == 0x00 and tg[1] in (0x09, 0x0f):
        need += tg[3]                   # MessageWrite size, LSWrite tx_length
    elif tg[0] & 0x7f == 0x00 and tg[1] == 0x1f and tg[2] == 2:
        need = 7                        # SetProperty: the sleep time
    elif tg[0] & 0x7f == 0x01 and tg[1] == 0x95:
        need += tg[8] | tg[9] << 8      # WriteIOMap's count
    return len(tg) >= need


# The typed ioctls of the releases before the driver went into the kernel,
# retired by issue 30 (they must stay unknown: ENOTTY): _IOWR(MAGIC,
# 0x10 + opcode, its structure), opcode -> the structure's size (the same on
# i386 and x86_64).
RETIRED_TYPED = {
    0x00: 24, 0x01: 4, 0x02: 24, 0x03: 8, 0x04: 24, 0x05: 4, 0x06: 24, 0x07: 16, 0x08: 4,
    0x09: 64, 0x0a: 4, 0x0b: 4, 0x0c: 4, 0x0d: 8, 0x0e: 4, 0x0f: 20, 0x10: 20, 0x11: 24,
    0x13: 64,
}


def retired_number(opcode):
    """The number the typed ioctl of a direct command had."""
    return iowr(0x10 + opcode, RETIRED_TYPED[opcode])


def struct_size(name):
    return struct.calcsize(STRUCTS[name][0])


def ioctl_number(name):
    if name == 'TRANSACT':
        return iowr(0x00, struct_size('transaction'))
    if name == 'SET_TIMEOUT':
        return _ioc(_IOC_WRITE, 0x01, 4)
    if name == 'GET_TIMEOUT':
        return _ioc(_IOC_READ, 0x02, 4)
    if name == 'TTY_MINOR':          # of the tty with N_LEGONXT, not /dev/nxtN
        return _ioc(_IOC_READ, 0x03, 4)
    raise KeyError(name)


def pack(sname, **fields):
    fmt, names = STRUCTS[sname]
    names = names.split()
    unknown = set(fields) - set(names)
    assert not unknown, unknown
    values = []
    for n, code in zip(names, _codes(fmt)):
        values.append(fields.get(n, b'' if code == 's' else 0))
    return struct.pack(fmt, *values)


def unpack(sname, data):
    fmt, names = STRUCTS[sname]
    return dict(zip(names.split(), struct.unpack(fmt, data)))


def _codes(fmt):
    """The value codes of a struct format, in order (padding skipped)."""
    out, digits = [], ''
    for c in fmt[1:]:
        if c.isdigit():
            digits += c
            continue
        if c == 'x':
            digits = ''
            continue
        out.extend([c] if c == 's' else [c] * int(digits or 1))
        digits = ''
    return out


_libc = ctypes.CDLL(None, use_errno=True)


def raw_ioctl(fd, request, data):
    """ioctl() with a buffer: (return value, errno, the buffer afterwards)."""
    buf = ctypes.create_string_buffer(bytes(data), len(data))
    ret = _libc.ioctl(fd, ctypes.c_ulong(request), buf)
    err = ctypes.get_errno() if ret < 0 else 0
    return ret, err, buf.raw


def telegram(which, /, reply=True, **fields):
    """The telegram of a direct command, from its fields (missing ones are 0)."""
    op, fmt, names, _, _, _ = COMMANDS[which]
    names = names.split()
    unknown = set(fields) - set(names) - {'data', 'tx_data'}
    assert not unknown, unknown
    args = [fields.get(n, b'' if c == 's' else 0) for n, c in zip(names, _codes(fmt))]
    tg = bytes([0x00 if reply else 0x80, op]) + (struct.pack(fmt, *args) if fmt else b'')
    if which == 'MESSAGE_WRITE':
        tg += bytes(fields.get('data', b''))[:fields.get('size', 0)]
    elif which == 'LS_WRITE':
        tg += bytes(fields.get('tx_data', b''))[:fields.get('tx_length', 0)]
    return tg


def decode(which, reply):
    """A reply's status byte and values; values are 0 when the reply is
    shorter (the brick's three-byte error replies)."""
    _, _, _, fmt, names, length = COMMANDS[which]
    out = {'status': reply[2] if len(reply) > 2 else None}
    if fmt:
        body = bytes(reply[3:length]).ljust(length - 3, b'\0')
        out.update(zip(names.split(), struct.unpack(fmt, body)))
    return out


def command(fd, which, /, **fields):
    """A direct command through NXT_IOC_TRANSACT: (errno, the decoded reply).

    The errno is the transport's; the brick's answer is out['status']. The
    reply is checked for its opcode and, on success, its length.
    """
    err, reply = transact(fd, telegram(which, **fields))
    if err:
        return err, {'status': None}
    op, length = COMMANDS[which][0], COMMANDS[which][5]
    assert reply[:2] == bytes([0x02, op]), '%s: reply %s' % (which, reply.hex())
    assert reply[2] != 0 or len(reply) == length, '%s: reply %s' % (which, reply.hex())
    return 0, decode(which, reply)


def ok(fd, which, /, **fields):
    err, out = command(fd, which, **fields)
    assert err == 0, '%s: %s' % (which, errno.errorcode.get(err, err))
    assert out['status'] == 0, '%s: status 0x%02x' % (which, out['status'])
    return out


def transact(fd, telegram):
    """NXT_IOC_TRANSACT: (errno, reply bytes)."""
    data = pack('transaction', telegram=bytes(telegram), length=len(telegram))
    _, err, out = raw_ioctl(fd, ioctl_number('TRANSACT'), data)
    t = unpack('transaction', out)
    return err, t['reply'][:t['reply_length']] if not err else b''


def mixed_request(fd, index, i):
    """Request `i` of client `index` in the many-clients tests: each reply
    depends on what was asked, so a reply given to the wrong client shows.

    Cycles through a ReadIOMap at an offset unique to the client and the
    request (NXT_IOC_TRANSACT or write()/read()), a GetInputValues and
    a raw GetOutputState (opcode 0x06) by write()/read(), each for a port
    that depends on the client and the request. Returns (kind, errno or 0,
    reply matched).
    """
    kind = (index + i) % 3
    if kind == 0:
        offset = (index * 131 + i * 7) % 150
        tg = b'\x01\x94' + struct.pack('<IHH', 0x00030001, offset, 8)
        if i % 2:
            err, reply = transact(fd, tg)
        else:
            os.write(fd, tg)
            reply, err = os.read(fd, 64), 0
        want = b'\x02\x94\x00' + struct.pack('<IH', 0x00030001, 8) + \
            bytes(nxt_brick.iomap_pattern(0x00030001, offset + k) for k in range(8))
        return kind, err, not err and reply[:len(want)] == want
    if kind == 1:
        port = (index + i) % 4
        err, v = command(fd, 'GET_INPUT_VALUES', port=port)
        return kind, err, not err and v['port'] == port
    port = (index + i) % 3
    os.write(fd, bytes([0x00, 0x06, port]))
    reply = os.read(fd, 64)
    return kind, 0, len(reply) == 25 and reply[:4] == bytes([0x02, 0x06, 0x00, port])


def mixed_client(node, index, count, start, out):
    """A client process of the many-clients tests: once `start` is set,
    `count` mixed_request()s on its own open file of `node`; puts (index,
    mismatches, or the exception's repr) in the queue `out`.

    Runs at a lower priority than the emulated brick, which shares the
    guest's CPUs with it (a real brick does not), and with a long timeout:
    this is about replies never crossing, not about latency under TCG.
    """
    os.nice(5)
    f = os.open(node, os.O_RDWR)
    bad = 0
    start.wait()
    try:
        assert set_timeout(f, 5000) == 0
        for i in range(count):
            _, err, ok = mixed_request(f, index, i)
            if err or not ok:
                bad += 1
    except Exception as e:          # reported, not lost with the process
        bad = repr(e)
    finally:
        os.close(f)
    out.put((index, bad))


def mixed_clients(node, clients, count, timeout=600):
    """`clients` processes of mixed_client() at once: [(index, mismatches)]."""
    import multiprocessing
    ctx = multiprocessing.get_context('fork')
    q = ctx.Queue()
    start = ctx.Event()
    procs = [ctx.Process(target=mixed_client, args=(node, i, count, start, q))
             for i in range(clients)]
    for p in procs:
        p.start()
    start.set()
    results = sorted(q.get(timeout=timeout) for _ in procs)
    for p in procs:
        p.join(30)
        assert p.exitcode == 0, p.exitcode
    return results


def wait_versions(fd, timeout):
    """GetVersions until the brick answers (after a reset, say): (errno, reply)."""
    deadline = time.monotonic() + timeout
    while True:
        err, reply = transact(fd, b'\x01\x88')
        if err == 0 or time.monotonic() > deadline:
            return err, reply
        time.sleep(0.1)


def set_timeout(fd, ms):
    _, err, _ = raw_ioctl(fd, ioctl_number('SET_TIMEOUT'), struct.pack('<I', ms))
    return err


def get_timeout(fd):
    _, err, out = raw_ioctl(fd, ioctl_number('GET_TIMEOUT'), bytes(4))
    assert err == 0
    return struct.unpack('<I', out)[0]


def cstr(b):
    return b.split(b'\0', 1)[0].decode()


def name20(s):
    return s.encode().ljust(20, b'\0')


UAPI_CHECK = os.path.join(os.path.dirname(__file__), 'nxt_uapi_check.c')


def uapi_layout():
    """Sizes, offsets and ioctl numbers as the C compiler sees the header.

    tests/build-modules.sh builds the program on the host, beside the
    modules (a compiler in the emulated guest is slow); it is built here
    only when that did not happen.
    """
    built = os.path.join(os.environ.get('LEGO_BUILD', ''), 'uapi-check')
    if os.access(built, os.X_OK):
        out = subprocess.run([built], check=True, capture_output=True, text=True).stdout
        return {k: int(v) for k, v in (line.split() for line in out.splitlines())}
    with tempfile.TemporaryDirectory() as d:
        exe = os.path.join(d, 'check')
        subprocess.run(['gcc', '-Wall', '-Werror', '-I', os.path.join(TOP, 'include/uapi'),
                        '-o', exe, UAPI_CHECK], check=True)
        out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout
    return {k: int(v) for k, v in (line.split() for line in out.splitlines())}


NXTCTL = os.path.join(os.environ.get('LEGO_BUILD', ''), 'tools', 'nxtctl')
# Where nxtctl connect's and attach's daemons leave their files in the tests.
NXTCTL_RUNDIR = '/tmp/nxtctl-run'


def nxtctl(*args, text=True, timeout=120):
    """Run the nxtctl tests/build-modules.sh built: CompletedProcess."""
    assert os.access(NXTCTL, os.X_OK), 'nxtctl not built: ' + NXTCTL
    env = dict(os.environ, NXTCTL_RUNDIR=NXTCTL_RUNDIR)
    return subprocess.run([NXTCTL] + [str(a) for a in args], capture_output=True,
                          text=text, timeout=timeout, env=env)


def nxtctl_ok(p):
    """The output of an nxtctl run that must have succeeded."""
    assert p.returncode == 0, (p.args, p.returncode, p.stdout, p.stderr)
    return p.stdout


def load_driver():
    from conftest import module_path
    for name in ('lego_nxt', 'lego_nxt_usb'):
        if not os.path.isdir('/sys/module/' + name):
            subprocess.run(['insmod', module_path(name)], check=True)


def interface_of(serial):
    """The bound interface directory of the brick with this USB serial."""
    for intf in glob.glob(DRIVER + '/*:1.0'):
        try:
            with open(os.path.join(intf, '..', 'serial')) as f:
                if f.read().strip() == serial:
                    return os.path.realpath(intf)
        except OSError:
            pass
    return None


def node_of(serial, timeout=10.0):
    """/dev/nxtN of the brick with this serial, waiting for it to appear."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        intf = interface_of(serial)
        if intf:
            names = glob.glob(os.path.join(intf, 'lego-nxt', 'nxt*'))
            if names and os.path.exists('/dev/' + os.path.basename(names[0])):
                return '/dev/' + os.path.basename(names[0])
        time.sleep(0.05)
    return None


def node_dir(intf):
    """The sysfs directory of a bound interface's node, /sys/class/lego-nxt/nxtN,
    where the driver's attributes are."""
    names = glob.glob(os.path.join(intf, 'lego-nxt', 'nxt*'))
    assert len(names) == 1, names
    return os.path.realpath(names[0])


def attr(intf, name):
    with open(os.path.join(intf, name)) as f:
        return f.read().strip()


class Brick:
    """An emulated brick plugged in on a dummy_hcd port, with its node."""

    def __init__(self, udc='dummy_udc.0', serial='001653A0B1C2', **kw):
        load_driver()
        self.serial = serial
        self.emu = nxt_brick.RawGadgetBrick(udc=udc, serial=serial, **kw)
        self.fw = self.emu.fw
        self.node = None

    def plug(self, timeout=15.0):
        self.emu.start()
        assert self.emu.wait_configured(timeout), 'brick %s not configured' % self.serial
        self.node = node_of(self.serial, timeout)
        assert self.node, 'no /dev/nxtN for %s' % self.serial
        return self.node

    def interface(self):
        return interface_of(self.serial)

    def open(self, flags=os.O_RDWR):
        return os.open(self.node, flags)

    def unplug(self):
        self.emu.unplug()

    def wait_gone(self, timeout=5.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if not os.path.exists(self.node) and not interface_of(self.serial):
                return True
            time.sleep(0.02)
        return False
