"""An emulated LEGO MINDSTORMS NXT brick on the USB bus.

The brick appears on the test VM's USB bus through the kernel's raw-gadget
interface (/dev/raw-gadget) on a dummy_hcd UDC, and behaves like a brick
running the LEGO 1.29 firmware as described in shared/research (nxt.md
sections 1.1, 1.2, 2.1-2.5 and 4, and the LEGO direct command document):

- USB identity: the brick's descriptors byte for byte (0694:0002, bcdUSB
  2.00, bMaxPacketSize0 8, no manufacturer or product string, the serial
  string is the Bluetooth address as 12 upper-case hex digits, one
  self-powered configuration with MaxPower 0, a vendor interface with bulk
  EP 0x01 OUT listed before bulk EP 0x82 IN, 64-byte packets); string 0 is
  LANGID 0x0409 and any other string STALLs; SET_INTERFACE, GET_INTERFACE,
  class and vendor requests STALL.
- Transport: one OUT packet (at most 64 bytes) is one command, so a longer
  host transfer becomes several commands; a reply is one IN packet with no
  zero-length packet after a full 64-byte reply. After queueing a reply the
  firmware busy-waits up to about 500 ms for the host to collect it and
  reads no command meanwhile; then it goes on with the reply still queued.
  Two replies fit (the AT91's dual-banked IN endpoint), so a host that
  skipped a read gets the stale reply first. A bus reset flushes them.
- Telegrams: replies only to types 0x00 and 0x01; 0x80/0x81 run without a
  reply; 0x02/0x82 and unknown types are ignored (a "reply to MessageRead"
  telegram is stored in its mailbox). An unknown direct opcode answers
  02 op BE; an unknown system opcode (0x8A and 0xA3 included) answers with
  request length + 2 bytes: 02 op and stale bytes of the previous reply. A
  short command is read together with stale bytes of earlier commands in the
  64-byte receive buffer, and extra bytes are ignored.
- Reply lengths are fixed even on error (25/16/20/23/28/34/64 ...), except
  LSGetStatus/LSRead with a bad port (3 bytes). Read echoes the requested
  count but carries at most 58 data bytes; the real firmware then zero-fills
  past its 64-byte buffer, which the emulator does not. ReadIOMap returns the
  actual count with at most 55 data bytes.
- Direct commands 0x00-0x13 and 0x19-0x21 with their status codes; motors
  whose tacho, block and rotation counts advance with the (injectable) clock
  while they run with non-zero power and stop at the tacho limit; inputs with
  plausible values per sensor type and valid=0 for a while after
  SetInputMode; mailboxes (inboxes 0-9, outboxes 10-19, 5 messages per queue,
  the oldest dropped, EC with no program, 40 when empty); programs (a start
  takes effect a little later, C0 for a missing file, EC for no program); a
  LEGO ultrasonic sensor behind LSWrite/LSGetStatus/LSRead on a LOWSPEED_9V
  port (pending 0x20 for a few ms, I2C address 0x02, register 0x42 the
  distance in cm, "V1.0"/"LEGO"/"Sonar" at 0x00/0x08/0x10).
- System commands: the flash file system (OpenRead/OpenWrite/Read/Write/
  Close/Delete/FindFirst/FindNext, linear and data files, 16 handles, status
  codes 81-8F, 92, 93), GetVersions (1.29), GetDeviceInfo, SetBrickName,
  GetBTAddress, DeleteUserFlash (slow), module search (handle byte always 0)
  and ReadIOMap/WriteIOMap, PollCommandLength/PollCommand, BootCommand and
  BTFactoryReset. Files opened over USB are closed when the brick is
  unplugged.

What dummy_hcd and raw-gadget cannot reproduce, and other simplifications:

- dummy_hcd answers SET_ADDRESS, GET_STATUS and SET/CLEAR_FEATURE itself;
  the gadget never sees them. GET_STATUS(device) therefore returns 0, not the
  brick's 1 (raw-gadget has no way to mark the gadget self-powered), and
  SET_FEATURE(ENDPOINT_HALT) halts the endpoint (the host gets EPIPE) where
  the brick disables it.
- dummy_hcd completes the first IN request of 64 bytes or less as soon as it
  is queued (it emulates a one-packet FIFO for the whole UDC), so a
  completed write would not mean the host read the reply. The emulator
  enables the brick's undescribed EP3 (interrupt IN, which the host never
  reads) and parks a packet there, so that the FIFO stays occupied and every
  reply completes only once the host has read it. Right after a bus reset
  there is a short window in which a reply could take the FIFO instead.
- bMaxPacketSize0 is 8 in the device descriptor, as on the brick, and the
  host uses 8; dummy_hcd itself moves control data in chunks of up to 64
  bytes, which makes no difference the host can see.
- The OUT side buffers at most one command (the pending raw-gadget request)
  instead of two; a third reply nobody collected is lost (the notes do not
  say what the AT91 does then).
- "Unplugging" closes the raw-gadget file: the gadget unbinds and the host
  sees a disconnect, as when VBUS goes away.
- BootCommand replies "Yes" and then unplugs; SAM-BA (03EB:6124) is not
  emulated.
- The 1 ms scheduler is modelled only with `tick` (--tick-ms 1; the tests
  turn it on for a share of the bricks, tests/guest/conftest.py): a command
  is then handled at the first tick at or after its arrival, and at most
  one per tick (the next pass comes at the first tick after the last one,
  its wait for the host included, has ended). Without it commands are
  handled as fast as Python goes. Regulation, synchronisation, turn ratio, ramps and brake are not
  modelled: a running motor turns at 10 degrees per second per unit of
  power and stops exactly at its tacho limit. The firmware's exact sensor
  scaling and flash allocation are not modelled either: values, sizes and
  delays marked "assumed" below are plausible, not measured.

The `hostile` option makes a misbehaving brick: `short` (truncated replies),
`long` (replies padded to 64 bytes), `opcode` (wrong echoed opcode),
`noreply` (never replies), `garbage` (random bytes not starting with 0x02),
`stall` (halts the IN endpoint instead of replying), `disconnect` (unplugs
after receiving a command, before replying), `mislength` (sends a reply to
the same opcode but of the wrong length before each real reply), `deaf`
(configured, but never reads its OUT endpoint: no telegram is taken, as
when the firmware is stuck in a long command).

Usage: python3 tests/emulator/nxt_brick.py [--udc dummy_udc.0]
    [--serial 001653A0B1C2] [--name NXT] [--hostile MODE] [--tick-ms MS]
runs until SIGTERM or SIGINT and prints one line when the host has configured
the brick. Tests import RawGadgetBrick (start, stop, unplug, replug) and
Firmware (the brick's behaviour alone, with an injectable clock).
"""
import argparse
import collections
import ctypes
import errno
import math
import os
import random
import signal
import struct
import sys
import threading
import time

from stop_signals import StopSignals

# ---------------------------------------------------------------------------
# Telegrams, opcodes and status codes

DIRECT, SYSTEM, REPLY = 0x00, 0x01, 0x02
NO_REPLY = 0x80

# Status codes (the LEGO firmware's names in the comments).
SUCCESS = 0x00
PENDING = 0x20              # STAT_COMM_PENDING
EMPTY_MAILBOX = 0x40        # STAT_MSG_EMPTY_MAILBOX
NO_MORE_HANDLES = 0x81
NO_SPACE = 0x82
NO_MORE_FILES = 0x83
EOF_EXPECTED = 0x84
END_OF_FILE = 0x85
NOT_LINEAR_FILE = 0x86
FILE_NOT_FOUND = 0x87
HANDLE_ALREADY_CLOSED = 0x88
NO_LINEAR_SPACE = 0x89
UNDEFINED_ERROR = 0x8A
FILE_BUSY = 0x8B
NO_WRITE_BUFFERS = 0x8C
APPEND_NOT_POSSIBLE = 0x8D
FILE_FULL = 0x8E
FILE_EXISTS = 0x8F
MODULE_NOT_FOUND = 0x90
OUT_OF_BOUNDS = 0x91
ILLEGAL_FILE_NAME = 0x92
ILLEGAL_HANDLE = 0x93
UNKNOWN_OPCODE = 0xBE       # ERR_RC_UNKNOWN_CMD
ILLEGAL_VALUE = 0xC0        # ERR_RC_ILLEGAL_VAL
BUS_ERROR = 0xDD            # ERR_COMM_BUS_ERR
CHANNEL_NOT_READY = 0xE0    # ERR_COMM_CHAN_NOT_READY
NO_PROGRAM = 0xEC           # ERR_NO_PROG
BAD_SIZE = 0xED             # ERR_INVALID_SIZE
BAD_QUEUE = 0xEE            # ERR_INVALID_QUEUE

# Sensor types and modes (SetInputMode).
NO_SENSOR, SWITCH, TEMPERATURE, REFLECTION, ANGLE = 0x00, 0x01, 0x02, 0x03, 0x04
LIGHT_ACTIVE, LIGHT_INACTIVE, SOUND_DB, SOUND_DBA = 0x05, 0x06, 0x07, 0x08
CUSTOM, LOWSPEED, LOWSPEED_9V = 0x09, 0x0A, 0x0B
RAWMODE, BOOLEANMODE, TRANSITIONCNTMODE, PERIODCOUNTERMODE = 0x00, 0x20, 0x40, 0x60
PCTFULLSCALEMODE, CELSIUSMODE, FAHRENHEITMODE, ANGLESTEPSMODE = 0x80, 0xA0, 0xC0, 0xE0

# Outputs (SetOutputState).
MOTORON, BRAKE, REGULATED = 0x01, 0x02, 0x04
RUN_IDLE, RUN_RAMPUP, RUN_RUNNING, RUN_RAMPDOWN = 0x00, 0x10, 0x20, 0x40

# ---------------------------------------------------------------------------
# Numbers that shape the behaviour (seconds unless said otherwise)

VERSIONS = bytes([0x7C, 0x01, 0x1D, 0x01])  # protocol 1.124, firmware 1.29
USB_REPLY_TIMEOUT = 0.5     # dUsbWrite gives up after ~500 x 1 ms
IN_BANKS = 2                # dual-banked EP2
READ_USB_MAX = 58           # Read: data bytes that fit a 64-byte reply
WRITE_USB_MAX = 61          # Write: data bytes that fit a 64-byte command
IOMAP_USB_MAX = 55          # ReadIOMap: data bytes that fit a 64-byte reply
POLL_USB_MAX = 59           # PollCommand: largest n on USB
MAX_HANDLES = 16
MAX_FILES = 127             # assumed
FLASH_BYTES = 130816        # user flash, assumed (511 pages of 256 bytes)
FLASH_PAGE = 256            # a file takes whole pages (assumed granularity)
MAILBOXES = 20              # 0-9 inboxes (host -> brick), 10-19 outboxes
MAILBOX_DEPTH = 5
MESSAGE_MAX = 59            # bytes including the NUL
DEFAULT_SLEEP_MS = 600000   # 10 minutes
DEGREES_PER_POWER = 10.0    # degrees per second per unit of power (assumed)
SENSOR_SETTLE = 0.1         # valid=0 this long after SetInputMode (assumed)
PROGRAM_START_DELAY = 0.1   # StartProgram -> running (assumed)
PROGRAM_STOP_DELAY = 0.01   # StopProgram -> stopped (assumed)
LS_BYTE_TIME = 0.001        # one I2C byte at the NXT's ~9.6 kbit/s
ERASE_TIME = 1.0            # DeleteUserFlash (assumed; NBC allows 3 s)
ULTRASONIC_ADDRESS = 0x02
BT_CONTACTS, BT_CONNECTIONS = 30, 4

# Modules for FindFirstModule/ReadIOMap: name, id, code size, IOMap size.
# Names and ids follow the LEGO firmware's numbering; the sizes are made up.
MODULES = [
    ('Command.mod', 0x00010001, 0x2000, 150),
    ('Output.mod', 0x00020001, 0x0C00, 96),
    ('Input.mod', 0x00030001, 0x0C00, 160),
    ('Button.mod', 0x00040001, 0x0400, 32),
    ('Comm.mod', 0x00050001, 0x4000, 256),
    ('IOCtrl.mod', 0x00060001, 0x0400, 4),
    ('Sound.mod', 0x00080001, 0x0800, 48),
    ('Loader.mod', 0x00090001, 0x1400, 8),
    ('Display.mod', 0x000A0001, 0x1000, 240),
    ('LowSpeed.mod', 0x000B0001, 0x0C00, 120),
    ('Ui.mod', 0x000C0001, 0x3000, 48),
]


def iomap_pattern(module_id, offset):
    """The initial byte at `offset` of a module's IOMap (until written)."""
    return (offset + 37 * ((module_id >> 16) & 0xFF) + (module_id & 0xFF)) & 0xFF


def flash_cost(size):
    """Flash bytes a file of `size` bytes takes (whole pages, at least one)."""
    return max(1, -(-size // FLASH_PAGE)) * FLASH_PAGE


def name20(name):
    """A file or module name as the 20-byte NUL-padded field."""
    raw = name.encode('latin-1') if isinstance(name, str) else bytes(name)
    return raw[:19].ljust(20, b'\0')


def pattern_match(pattern, name):
    """The firmware's search patterns: '*.*', 'name.*', '*.ext' or a full name."""
    if pattern == '*.*':
        return True
    pbase, _, pext = pattern.partition('.')
    base, _, ext = name.partition('.')
    return (pbase == '*' or pbase == base) and (pext == '*' or pext == ext)


class Ultrasonic:
    """The LEGO ultrasonic sensor's I2C side (address 0x02)."""

    STRINGS = {0x00: b'V1.0', 0x08: b'LEGO', 0x10: b'Sonar', 0x14: b'10E-2m'}

    def __init__(self, distance=50):
        self.regs = bytearray(256)
        self.regs[0x11] = 0           # factory zero
        self.regs[0x12] = 1           # factory scale factor
        self.regs[0x13] = 14          # factory scale divisor
        self.regs[0x40] = 1           # continuous measurement interval
        self.regs[0x41] = 0x02        # command: continuous measurement
        self.regs[0x43:0x4A] = b'\xff' * 7   # no further echoes
        self.regs[0x52] = 14
        self.distance = distance

    @property
    def distance(self):
        return self.regs[0x42]

    @distance.setter
    def distance(self, cm):
        self.regs[0x42] = max(0, min(255, int(cm)))

    def read(self, reg, n):
        # The string "registers" answer as whole fields from their start.
        if reg in self.STRINGS:
            return self.STRINGS[reg].ljust(8, b'\0')[:n].ljust(n, b'\0')
        return bytes(self.regs[(reg + i) & 0xFF] for i in range(n))

    def write(self, reg, data):
        for i, b in enumerate(data):
            if (reg + i) & 0xFF != 0x42:      # the measurement is read-only
                self.regs[(reg + i) & 0xFF] = b


class Motor:
    def __init__(self):
        self.power = 0
        self.mode = 0
        self.regmode = 0
        self.turn = 0
        self.runstate = RUN_IDLE
        self.limit = 0
        self.tacho = 0.0          # since the last goal (SetOutputState)
        self.block = 0.0          # since ResetMotorPosition(relative)
        self.rotation = 0.0       # since ResetMotorPosition(absolute)

    def running(self):
        return bool(self.mode & MOTORON) and self.power != 0 and self.runstate != RUN_IDLE

    def advance(self, dt):
        if dt <= 0 or not self.running():
            return
        step = abs(self.power) * DEGREES_PER_POWER * dt
        if self.limit:
            left = self.limit - abs(self.tacho)
            if step >= left:
                step = max(left, 0)
                self.runstate = RUN_IDLE
        step = step if self.power > 0 else -step
        self.tacho += step
        self.block += step
        self.rotation += step


class InputPort:
    def __init__(self, device):
        self.device = device        # what is plugged in: see Firmware.__init__
        self.type = NO_SENSOR
        self.mode = RAWMODE
        self.valid_at = 0.0
        self.raw = None             # set by the tests; None: the device's default
        self.boolean = 0
        self.transitions = 0
        self.count_base = 0
        # Low-speed (I2C) channel.
        self.ls_state = 'idle'      # idle, pending, done, error
        self.ls_done_at = 0.0
        self.ls_rx = b''
        self.ls_result = None


class File:
    def __init__(self, kind, size, data=b''):
        self.kind = kind            # 'normal', 'linear' or 'data'
        self.size = size            # declared size
        self.data = bytearray(data)

    @property
    def length(self):
        return len(self.data)


class Handle:
    def __init__(self, kind, name, usb=True):
        self.kind = kind            # 'read', 'write' or 'find'
        self.name = name
        self.pos = 0
        self.usb = usb
        self.pattern = None
        self.found = None           # name of the last file a search returned


class Firmware:
    """The LEGO 1.29 firmware's command interpreter, without any I/O.

    handle(packet) takes one USB OUT packet and returns the reply packet or
    None. `now` is the clock (seconds); tests pass their own to move time.
    Attributes the tests may set: battery_mv, sensor values through
    set_touch/set_analog/ultrasonic, program-side mailboxes through
    program_send/program_receive.
    """

    DEFAULT_FILES = {
        'Demo.rxe': bytes(range(64)) * 4,
        'Woops.rso': bytes(100),
    }
    DEFAULT_SENSORS = {0: 'touch', 1: 'sound', 2: 'light', 3: 'ultrasonic'}

    def __init__(self, now=time.monotonic, name='NXT', bt_address='001653A0B1C2',
                 battery_mv=7823, files=None, sensors=None, seed=0):
        self.now = now
        self.lock = threading.RLock()
        self.rng = random.Random(seed)
        self.name = name.encode('latin-1')[:15]
        self.bt_address = bytes.fromhex(bt_address) if isinstance(bt_address, str) else bytes(bt_address)
        assert len(self.bt_address) == 6
        self.battery_mv = battery_mv
        self.sleep_minutes = DEFAULT_SLEEP_MS // 60000
        self.last_keep_alive = now()
        self.volume = 3
        self.bt_on = 1
        self.rx = bytearray(64)     # the firmware's receive buffer (stale bytes stay)
        self.tx = bytearray(64)     # its reply buffer
        self.busy = 0.0             # seconds the last command kept the brick busy
        self.rebooting = False      # BootCommand accepted
        self.sound = None           # ('tone', freq, until) or ('file', name, loop)
        self.motors = [Motor() for _ in range(3)]
        self.motor_time = now()
        sensors = self.DEFAULT_SENSORS if sensors is None else sensors
        self.inputs = [InputPort(sensors.get(i)) for i in range(4)]
        self.analog = {'touch': 1023, 'sound': 900, 'light': 520, 'ultrasonic': 1023, None: 1023}
        self.ultrasonic = Ultrasonic()
        # Commands handled, by (type without the no-reply bit, opcode).
        self.handled = collections.Counter()
        self.mailboxes = [collections.deque(maxlen=MAILBOX_DEPTH) for _ in range(MAILBOXES)]
        self.datalog = collections.deque()
        self.poll_buffers = [bytearray(), bytearray()]
        self.program = None         # name of the running program
        self.program_next = None    # (time, name or None) of a pending start/stop
        self.files = {}
        for fname, data in (self.DEFAULT_FILES if files is None else files).items():
            kind = 'linear' if fname.endswith(('.rxe', '.sys', '.rtm')) else 'normal'
            self.files[fname] = File(kind, len(data), data)
        self.handles = {}
        self.iomaps = {mid: bytearray(iomap_pattern(mid, o) for o in range(size))
                       for _, mid, _, size in MODULES}
        self.module_search = None   # (pattern, index of the next module)

    # ---- test controls ----

    def set_touch(self, port, pressed):
        with self.lock:
            self.analog_port(port, 183 if pressed else 1023)

    def analog_port(self, port, raw):
        """Set the raw A/D value the sensor on `port` produces."""
        with self.lock:
            p = self.inputs[port]
            p.raw = raw
            self._update_boolean(p)

    def program_send(self, box, message):
        """The running program posts `message` (bytes, NUL added) to outbox `box`."""
        with self.lock:
            self.mailboxes[box].append(bytes(message) + b'\0')

    def program_receive(self, box):
        """The running program takes the oldest message from inbox `box` (or None)."""
        with self.lock:
            q = self.mailboxes[box]
            return q.popleft() if q else None

    def program_poll_write(self, buf, data):
        with self.lock:
            self.poll_buffers[buf][:] = data

    @property
    def free_flash(self):
        return FLASH_BYTES - sum(flash_cost(f.size) for f in self.files.values())

    def usb_disconnected(self):
        """VBUS gone: close every file handle opened over USB."""
        with self.lock:
            for h in [h for h, hd in self.handles.items() if hd.usb]:
                self._close(h)

    # ---- the interpreter ----

    def handle(self, packet):
        packet = bytes(packet)
        if len(packet) > 64:
            raise ValueError('a USB packet holds at most 64 bytes')
        with self.lock:
            self.busy = 0.0
            if not packet:
                return None
            self.rx[:len(packet)] = packet
            self._tick()
            kind = self.rx[0]
            op = self.rx[1]
            self.handled[kind & 0x7F, op] += 1
            if kind & 0x7F == DIRECT:
                reply = self._direct(op, len(packet))
                if kind == NO_REPLY | DIRECT:
                    return None
            elif kind & 0x7F == SYSTEM:
                reply = self._system(op, len(packet))
                self.tx[:len(reply)] = reply
                if kind == NO_REPLY | SYSTEM:
                    return None
            else:
                if kind & 0x7F == REPLY and op == 0x13:
                    self._reply_to_message_read()
                return None
            self.tx[:len(reply)] = reply
            return reply

    def _tick(self):
        t = self.now()
        for m in self.motors:
            m.advance(t - self.motor_time)
        self.motor_time = t
        if self.program_next and t >= self.program_next[0]:
            name = self.program_next[1]
            if name is not None:
                for q in self.mailboxes:
                    q.clear()
            self.program = name
            self.program_next = None
        for p in self.inputs:
            if p.ls_state == 'pending' and t >= p.ls_done_at:
                if p.ls_result is None:
                    p.ls_state = 'error'
                else:
                    p.ls_state, p.ls_rx = 'done', p.ls_result

    def _reply_to_message_read(self):
        status, box, size = self.rx[2], self.rx[3], self.rx[4]
        if status == SUCCESS and self.program and box < 10 and 0 < size <= MESSAGE_MAX:
            self.mailboxes[box].append(bytes(self.rx[5:5 + size]))

    @staticmethod
    def _r(op, status, payload=b''):
        return bytes([REPLY, op, status]) + bytes(payload)

    def _name(self, at):
        """The ASCIIZ name at rx[at:at+20], or None if it is not a legal name."""
        raw = bytes(self.rx[at:at + 20])
        if b'\0' not in raw:
            return None
        s = raw[:raw.index(b'\0')]
        if not s or any(c < 0x20 or c > 0x7E for c in s):
            return None
        return s.decode('latin-1')

    def _pattern(self, at):
        raw = bytes(self.rx[at:at + 20])
        return raw.split(b'\0', 1)[0].decode('latin-1')

    # ---- direct commands ----

    def _direct(self, op, length):
        fn = getattr(self, '_d%02x' % op, None)
        if fn is None:
            return self._r(op, UNKNOWN_OPCODE)
        return fn(op, length)

    def _d00(self, op, length):         # StartProgram
        name = self._name(2)
        if name is None or name not in self.files:
            return self._r(op, ILLEGAL_VALUE)
        # The UI starts it a little later; a file that is no program never runs.
        if name.endswith('.rxe'):
            self.program_next = (self.now() + PROGRAM_START_DELAY, name)
        return self._r(op, SUCCESS)

    def _d01(self, op, length):         # StopProgram
        if not self.program:
            return self._r(op, NO_PROGRAM)
        self.program_next = (self.now() + PROGRAM_STOP_DELAY, None)
        return self._r(op, SUCCESS)

    def _d02(self, op, length):         # PlaySoundFile
        name = self._name(3)
        if name is None or name not in self.files:
            return self._r(op, ILLEGAL_VALUE)
        self.sound = ('file', name, self.rx[2])
        return self._r(op, SUCCESS)

    def _d03(self, op, length):         # PlayTone (no range check)
        freq, dur = struct.unpack_from('<HH', self.rx, 2)
        self.sound = ('tone', freq, self.now() + dur / 1000)
        return self._r(op, SUCCESS)

    def _d04(self, op, length):         # SetOutputState
        port = self.rx[2]
        if port > 2 and port != 0xFF:
            return self._r(op, ILLEGAL_VALUE)
        power, mode, regmode, turn, runstate, limit = struct.unpack_from('<bBBbBI', self.rx, 3)
        for m in self.motors if port == 0xFF else [self.motors[port]]:
            m.power, m.mode, m.regmode, m.turn = power, mode, regmode, turn
            m.runstate, m.limit = runstate, limit
            m.tacho = 0.0             # a new goal resets the tacho count
        return self._r(op, SUCCESS)

    def _d05(self, op, length):         # SetInputMode
        port = self.rx[2]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE)
        p = self.inputs[port]
        p.type, p.mode = self.rx[3], self.rx[4]
        p.valid_at = self.now() + SENSOR_SETTLE
        p.transitions = p.count_base = 0
        p.ls_state, p.ls_rx = 'idle', b''
        return self._r(op, SUCCESS)

    def _d06(self, op, length):         # GetOutputState
        port = self.rx[2]
        if port > 2:
            return self._r(op, ILLEGAL_VALUE, bytes(22))
        m = self.motors[port]
        return self._r(op, SUCCESS, struct.pack(
            '<BbBBbBIiii', port, m.power, m.mode, m.regmode, m.turn, m.runstate,
            m.limit, round(m.tacho), round(m.block), round(m.rotation)))

    def _d07(self, op, length):         # GetInputValues
        port = self.rx[2]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE, bytes(13))
        p = self.inputs[port]
        raw, normalized, scaled = self._input_values(p)
        valid = 1 if self.now() >= p.valid_at else 0
        return self._r(op, SUCCESS, struct.pack(
            '<BBBBBHHhh', port, valid, 0, p.type, p.mode, raw, normalized, scaled, normalized))

    def _raw(self, p):
        if p.type in (LOWSPEED, LOWSPEED_9V):
            return 0
        if p.raw is not None:
            return p.raw
        if p.device == 'light':
            return 520 if p.type in (LIGHT_ACTIVE, REFLECTION) else 750
        return self.analog.get(p.device, 1023)

    def _update_boolean(self, p):
        # The firmware's thresholds: true below 45 %, false above 55 % of 1023.
        n = self._raw(p)
        new = 1 if n < 460 else 0 if n > 562 else p.boolean
        if new != p.boolean:
            p.transitions += 1
        p.boolean = new

    def _input_values(self, p):
        raw = self._raw(p)
        normalized = raw
        self._update_boolean(p)
        mode = p.mode & 0xE0
        if mode == BOOLEANMODE:
            scaled = p.boolean
        elif mode == TRANSITIONCNTMODE:
            scaled = p.transitions - p.count_base
        elif mode == PERIODCOUNTERMODE:
            scaled = (p.transitions - p.count_base) // 2
        elif mode == PCTFULLSCALEMODE:
            scaled = (1023 - normalized) * 100 // 1023
        elif mode == CELSIUSMODE:
            scaled = 215            # 21.5 degrees C, in tenths
        elif mode == FAHRENHEITMODE:
            scaled = 707            # 70.7 degrees F
        elif mode == ANGLESTEPSMODE:
            scaled = 0
        else:
            scaled = normalized
        return raw, normalized, scaled

    def _d08(self, op, length):         # ResetInputScaledValue
        port = self.rx[2]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE)
        p = self.inputs[port]
        p.count_base = p.transitions
        return self._r(op, SUCCESS)

    def _d09(self, op, length):         # MessageWrite
        box, size = self.rx[2], self.rx[3]
        if size == 0 or size > MESSAGE_MAX or self.rx[4 + size - 1] != 0:
            return self._r(op, ILLEGAL_VALUE)
        if not self.program:
            return self._r(op, NO_PROGRAM)
        if box >= MAILBOXES:
            return self._r(op, BAD_QUEUE)
        self.mailboxes[box].append(bytes(self.rx[4:4 + size]))  # the oldest drops
        return self._r(op, SUCCESS)

    def _d0a(self, op, length):         # ResetMotorPosition
        port = self.rx[2]
        if port > 2:
            return self._r(op, ILLEGAL_VALUE)
        if self.rx[3]:
            self.motors[port].block = 0.0
        else:
            self.motors[port].rotation = 0.0
        return self._r(op, SUCCESS)

    def _d0b(self, op, length):         # GetBatteryLevel
        return self._r(op, SUCCESS, struct.pack('<H', self.battery_mv))

    def _d0c(self, op, length):         # StopSoundPlayback
        self.sound = None
        return self._r(op, SUCCESS)

    def _d0d(self, op, length):         # KeepAlive
        self.last_keep_alive = self.now()
        return self._r(op, SUCCESS, struct.pack('<I', self.sleep_minutes * 60000))

    def _ls_check(self, p):
        if p.type not in (LOWSPEED, LOWSPEED_9V) or self.now() < p.valid_at:
            return CHANNEL_NOT_READY
        return None

    def _ls_status(self, p):
        err = self._ls_check(p)
        if err:
            return err
        return {'pending': PENDING, 'error': BUS_ERROR}.get(p.ls_state, SUCCESS)

    def _d0e(self, op, length):         # LSGetStatus
        port = self.rx[2]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE)
        p = self.inputs[port]
        status = self._ls_status(p)
        return self._r(op, status, [len(p.ls_rx) if status == SUCCESS else 0])

    def _d0f(self, op, length):         # LSWrite
        port, txlen, rxlen = self.rx[2], self.rx[3], self.rx[4]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE)
        if txlen > 16 or rxlen > 16:
            return self._r(op, BAD_SIZE)
        p = self.inputs[port]
        if self._ls_check(p) or p.ls_state == 'pending':
            return self._r(op, CHANNEL_NOT_READY)
        tx = bytes(self.rx[5:5 + txlen])
        p.ls_result = self._i2c(p, tx, rxlen)
        p.ls_rx = b''
        p.ls_state = 'pending'
        nbytes = txlen + (rxlen + 1 if rxlen else 0)
        p.ls_done_at = self.now() + LS_BYTE_TIME * nbytes
        return self._r(op, SUCCESS)

    def _i2c(self, p, tx, rxlen):
        """The bytes the device answers, or None if nothing acknowledged."""
        if (p.device != 'ultrasonic' or p.type != LOWSPEED_9V or not tx
                or tx[0] & 0xFE != ULTRASONIC_ADDRESS):
            return None
        reg = tx[1] if len(tx) > 1 else 0
        if rxlen:
            return self.ultrasonic.read(reg, rxlen)
        self.ultrasonic.write(reg, tx[2:])
        return b''

    def _d10(self, op, length):         # LSRead
        port = self.rx[2]
        if port > 3:
            return self._r(op, ILLEGAL_VALUE)
        p = self.inputs[port]
        status = self._ls_status(p)
        if status != SUCCESS:
            return self._r(op, status, bytes(17))
        data, p.ls_rx = p.ls_rx, b''
        return self._r(op, SUCCESS, bytes([len(data)]) + data.ljust(16, b'\0'))

    def _d11(self, op, length):         # GetCurrentProgramName
        if not self.program:
            return self._r(op, NO_PROGRAM, bytes(20))
        return self._r(op, SUCCESS, name20(self.program))

    def _d13(self, op, length):         # MessageRead
        box, local, remove = self.rx[2], self.rx[3], self.rx[4]
        if not self.program:
            status = NO_PROGRAM
        elif box >= MAILBOXES:
            status = BAD_QUEUE
        elif not self.mailboxes[box]:
            status = EMPTY_MAILBOX
        else:
            q = self.mailboxes[box]
            msg = q.popleft() if remove else q[0]
            return self._r(op, SUCCESS, bytes([local, len(msg)]) + msg.ljust(MESSAGE_MAX, b'\0'))
        return self._r(op, status, bytes([local, 0]) + bytes(MESSAGE_MAX))

    def _d19(self, op, length):         # DatalogRead (1.28+)
        if not self.datalog:
            return self._r(op, EMPTY_MAILBOX, bytes(61))
        entry = self.datalog[0]
        if self.rx[2]:
            self.datalog.popleft()
        return self._r(op, SUCCESS, bytes([len(entry)]) + entry.ljust(60, b'\0'))

    def _d1a(self, op, length):         # DatalogSetTimes
        self.datalog_sync = struct.unpack_from('<I', self.rx, 2)[0]
        return self._r(op, SUCCESS)

    def _d1b(self, op, length):         # BTGetContactCount
        return self._r(op, SUCCESS, [BT_CONTACTS])

    def _d1c(self, op, length):         # BTGetContactName
        status = SUCCESS if self.rx[2] < BT_CONTACTS else ILLEGAL_VALUE
        return self._r(op, status, bytes(18))

    def _d1d(self, op, length):         # BTGetConnCount
        return self._r(op, SUCCESS, [BT_CONNECTIONS])

    def _d1e(self, op, length):         # BTGetConnName
        status = SUCCESS if self.rx[2] < BT_CONNECTIONS else ILLEGAL_VALUE
        return self._r(op, status, bytes(18))

    def _d1f(self, op, length):         # SetProperty
        prop = self.rx[2]
        if prop == 0:
            self.bt_on = 1 if self.rx[3] else 0
        elif prop == 1:
            self.volume = min(self.rx[3], 4)
        elif prop == 2:
            self.sleep_minutes = struct.unpack_from('<I', self.rx, 3)[0] // 60000
        else:
            return self._r(op, UNKNOWN_OPCODE)
        return self._r(op, SUCCESS)

    def _d20(self, op, length):         # GetProperty
        prop = self.rx[2]
        if prop == 0:
            return self._r(op, SUCCESS, [self.bt_on])
        if prop == 1:
            return self._r(op, SUCCESS, [self.volume])
        if prop == 2:
            return self._r(op, SUCCESS, struct.pack('<I', self.sleep_minutes * 60000))
        return self._r(op, UNKNOWN_OPCODE)

    def _d21(self, op, length):         # UpdateResetCount
        port = self.rx[2]
        if port > 2:
            return self._r(op, ILLEGAL_VALUE)
        self.motors[port].tacho = 0.0
        return self._r(op, SUCCESS)

    # ---- system commands ----

    def _system(self, op, length):
        fn = getattr(self, '_s%02x' % op, None)
        if fn is None:
            # The handler leaves the length alone: the reply is the request's
            # length + 2 bytes, 02 op and whatever the reply buffer held.
            n = min(length + 2, 64)
            return bytes([REPLY, op]) + bytes(self.tx[2:n])
        return fn(op, length)

    def _new_handle(self, kind, name):
        for h in range(MAX_HANDLES):
            if h not in self.handles:
                self.handles[h] = Handle(kind, name)
                return h
        return None

    def _open_handles(self, name):
        return [hd for hd in self.handles.values() if hd.kind != 'find' and hd.name == name]

    def _close(self, h):
        hd = self.handles.pop(h)
        if hd.kind == 'write':
            f = self.files.get(hd.name)
            if f is not None and f.kind != 'data' and f.length < f.size:
                f.data.extend(bytes(f.size - f.length))

    def _existing_file(self, op):
        """(name, file, None) for the file named at rx[2:22], else (None, None, error reply).

        The error replies of OpenRead and OpenAppendData: a handle and a u32.
        """
        name = self._name(2)
        if name is None:
            return None, None, self._r(op, ILLEGAL_FILE_NAME, bytes(5))
        f = self.files.get(name)
        if f is None:
            return None, None, self._r(op, FILE_NOT_FOUND, bytes(5))
        return name, f, None

    def _s80(self, op, length):         # OpenRead
        name, f, error = self._existing_file(op)
        if error:
            return error
        if any(hd.kind == 'write' for hd in self._open_handles(name)):
            return self._r(op, FILE_BUSY, bytes(5))
        h = self._new_handle('read', name)
        if h is None:
            return self._r(op, NO_MORE_HANDLES, bytes(5))
        return self._r(op, SUCCESS, struct.pack('<BI', h, f.size))

    def _open_write(self, op, kind):
        name = self._name(2)
        size = struct.unpack_from('<I', self.rx, 22)[0]
        if name is None:
            return self._r(op, ILLEGAL_FILE_NAME, [0])
        linear = name.endswith(('.rxe', '.sys', '.rtm'))
        if kind == 'data' and linear:
            return self._r(op, ILLEGAL_FILE_NAME, [0])
        if kind == 'normal' and linear:
            kind = 'linear'
        if name in self.files:
            return self._r(op, FILE_EXISTS, [0])
        if len(self.files) >= MAX_FILES:
            return self._r(op, NO_MORE_FILES, [0])
        if flash_cost(size) > self.free_flash:
            return self._r(op, NO_LINEAR_SPACE if kind == 'linear' else NO_SPACE, [0])
        h = self._new_handle('write', name)
        if h is None:
            return self._r(op, NO_MORE_HANDLES, [0])
        self.files[name] = File(kind, size)
        return self._r(op, SUCCESS, [h])

    def _s81(self, op, length):         # OpenWrite
        return self._open_write(op, 'normal')

    def _s89(self, op, length):         # OpenWriteLinear
        return self._open_write(op, 'linear')

    def _s8b(self, op, length):         # OpenWriteData
        return self._open_write(op, 'data')

    def _s8c(self, op, length):         # OpenAppendData
        name, f, error = self._existing_file(op)
        if error:
            return error
        if f.kind != 'data':
            return self._r(op, APPEND_NOT_POSSIBLE, bytes(5))
        if self._open_handles(name):
            return self._r(op, FILE_BUSY, bytes(5))
        if f.length >= f.size:
            return self._r(op, FILE_FULL, bytes(5))
        h = self._new_handle('write', name)
        if h is None:
            return self._r(op, NO_MORE_HANDLES, bytes(5))
        return self._r(op, SUCCESS, struct.pack('<BI', h, f.size - f.length))

    def _s82(self, op, length):         # Read
        h = self.rx[2]
        n = struct.unpack_from('<H', self.rx, 3)[0]
        shown = min(n, READ_USB_MAX)
        hd = self.handles.get(h)
        if hd is None or hd.kind != 'read':
            return self._r(op, ILLEGAL_HANDLE, struct.pack('<BH', h, n) + bytes(shown))
        f = self.files[hd.name]
        data = bytes(f.data[hd.pos:hd.pos + n])
        # The firmware reads all n bytes (and moves on by them); only the
        # first 58 fit the USB reply, the count still says n.
        hd.pos += len(data)
        status = SUCCESS if len(data) == n else END_OF_FILE
        return self._r(op, status, struct.pack('<BH', h, n) + data[:shown].ljust(shown, b'\0'))

    def _s83(self, op, length):         # Write
        h = self.rx[2]
        data = bytes(self.rx[3:max(length, 3)])[:WRITE_USB_MAX]
        hd = self.handles.get(h)
        if hd is None or hd.kind != 'write':
            return self._r(op, ILLEGAL_HANDLE, struct.pack('<BH', h, 0))
        f = self.files[hd.name]
        room = f.size - f.length
        f.data.extend(data[:room])
        written = min(len(data), room)
        return self._r(op, SUCCESS if written == len(data) else FILE_FULL,
                       struct.pack('<BH', h, written))

    def _s84(self, op, length):         # Close
        h = self.rx[2]
        if h >= MAX_HANDLES:
            return self._r(op, ILLEGAL_HANDLE, [h])
        if h not in self.handles:
            return self._r(op, HANDLE_ALREADY_CLOSED, [h])
        self._close(h)
        return self._r(op, SUCCESS, [h])

    def _s85(self, op, length):         # Delete
        echo = bytes(self.rx[2:22])
        name = self._name(2)
        if name is None:
            return self._r(op, ILLEGAL_FILE_NAME, echo)
        if name not in self.files:
            return self._r(op, FILE_NOT_FOUND, echo)
        if self._open_handles(name) or name == self.program:
            return self._r(op, FILE_BUSY, echo)
        del self.files[name]
        return self._r(op, SUCCESS, echo)

    def _find_from(self, pattern, after):
        names = list(self.files)
        start = names.index(after) + 1 if after in names else 0
        for name in names[start:]:
            if pattern_match(pattern, name):
                return name
        return None

    def _found(self, op, h, name):
        return self._r(op, SUCCESS, bytes([h]) + name20(name) +
                       struct.pack('<I', self.files[name].size))

    def _s86(self, op, length):         # FindFirst
        pattern = self._pattern(2)
        name = self._find_from(pattern, None)
        if name is None:
            return self._r(op, FILE_NOT_FOUND, bytes(25))
        h = self._new_handle('find', None)
        if h is None:
            return self._r(op, NO_MORE_HANDLES, bytes(25))
        hd = self.handles[h]
        hd.pattern, hd.found = pattern, name
        return self._found(op, h, name)

    def _s87(self, op, length):         # FindNext
        h = self.rx[2]
        hd = self.handles.get(h)
        if hd is None or hd.kind != 'find':
            return self._r(op, ILLEGAL_HANDLE, bytes(25))
        name = self._find_from(hd.pattern, hd.found)
        if name is None:
            return self._r(op, FILE_NOT_FOUND, bytes(25))
        hd.found = name
        return self._found(op, h, name)

    def _s88(self, op, length):         # GetVersions
        return self._r(op, SUCCESS, VERSIONS)

    def _s8d(self, op, length):         # CropDataFile (1.28+)
        h = self.rx[2]
        hd = self.handles.get(h)
        if hd is None or hd.kind != 'write' or self.files[hd.name].kind != 'data':
            return self._r(op, ILLEGAL_HANDLE, [h])
        f = self.files[hd.name]
        f.size = f.length
        return self._r(op, SUCCESS, [h])

    def _module_reply(self, op, index):
        name, mid, size, iosize = MODULES[index]
        return self._r(op, SUCCESS, bytes([0]) + name20(name) + struct.pack('<IIH', mid, size, iosize))

    def _module_next(self, op):
        pattern, start = self.module_search
        for i in range(start, len(MODULES)):
            if pattern_match(pattern, MODULES[i][0]):
                self.module_search = (pattern, i + 1)
                return self._module_reply(op, i)
        self.module_search = None
        return self._r(op, MODULE_NOT_FOUND, bytes(31))

    def _s90(self, op, length):         # FindFirstModule
        self.module_search = (self._pattern(2), 0)
        return self._module_next(op)

    def _s91(self, op, length):         # FindNextModule (the handle is ignored)
        if self.module_search is None:
            return self._r(op, MODULE_NOT_FOUND, bytes(31))
        return self._module_next(op)

    def _s92(self, op, length):         # CloseModuleHandle
        self.module_search = None
        return self._r(op, SUCCESS, [0])

    def _s94(self, op, length):         # ReadIOMap
        mid, offset, n = struct.unpack_from('<IHH', self.rx, 2)
        shown = min(n, IOMAP_USB_MAX)
        iomap = self.iomaps.get(mid)
        if iomap is None:
            return self._r(op, MODULE_NOT_FOUND, struct.pack('<IH', mid, 0) + bytes(shown))
        data = bytes(iomap[offset:offset + shown])
        status = SUCCESS if offset <= len(iomap) else OUT_OF_BOUNDS
        return self._r(op, status, struct.pack('<IH', mid, len(data)) + data.ljust(shown, b'\0'))

    def _s95(self, op, length):         # WriteIOMap
        mid, offset, n = struct.unpack_from('<IHH', self.rx, 2)
        data = bytes(self.rx[10:10 + n])
        iomap = self.iomaps.get(mid)
        if iomap is None:
            return self._r(op, MODULE_NOT_FOUND, struct.pack('<IH', mid, 0))
        if offset > len(iomap):
            return self._r(op, OUT_OF_BOUNDS, struct.pack('<IH', mid, 0))
        data = data[:len(iomap) - offset]
        iomap[offset:offset + len(data)] = data
        return self._r(op, SUCCESS, struct.pack('<IH', mid, len(data)))

    def _s97(self, op, length):         # BootCommand
        if bytes(self.rx[2:21]) != b"Let's dance: SAMBA\0":
            return self._r(op, UNDEFINED_ERROR, bytes(4))
        self.rebooting = True
        return self._r(op, SUCCESS, b'Yes\0')

    def _s98(self, op, length):         # SetBrickName
        self.name = bytes(self.rx[2:17]).split(b'\0', 1)[0]
        return self._r(op, SUCCESS)

    def _s9a(self, op, length):         # GetBTAddress
        return self._r(op, SUCCESS, self.bt_address + b'\0')

    def _s9b(self, op, length):         # GetDeviceInfo
        return self._r(op, SUCCESS, self.name.ljust(15, b'\0') + self.bt_address + b'\0' +
                       bytes(4) + struct.pack('<I', self.free_flash))

    def _sa0(self, op, length):         # DeleteUserFlash
        for h in list(self.handles):
            self._close(h)
        self.files.clear()
        self.busy = ERASE_TIME
        return self._r(op, SUCCESS)

    def _sa1(self, op, length):         # PollCommandLength
        buf = self.rx[2]
        if buf > 1:
            return self._r(op, UNDEFINED_ERROR, [buf, 0])
        return self._r(op, SUCCESS, [buf, len(self.poll_buffers[buf])])

    def _sa2(self, op, length):         # PollCommand
        buf, n = self.rx[2], self.rx[3]
        if buf > 1 or n > POLL_USB_MAX:
            return self._r(op, UNDEFINED_ERROR, [buf, 0])
        pb = self.poll_buffers[buf]
        data = bytes(pb[:n])
        del pb[:n]
        return self._r(op, SUCCESS, bytes([buf, len(data)]) + data.ljust(n, b'\0'))

    def _sa4(self, op, length):         # BTFactoryReset (USB only)
        return self._r(op, SUCCESS)


# ---------------------------------------------------------------------------
# USB: descriptors and raw-gadget

VID, PID = 0x0694, 0x0002
EP_OUT_ADDR, EP_IN_ADDR = 0x01, 0x82
BULK = 0x02

DEVICE_DESCRIPTOR = struct.pack('<BBHBBBBHHHBBBB', 18, 1, 0x0200, 0, 0, 0, 8,
                                VID, PID, 0x0000, 0, 0, 1, 1)
EP_OUT_DESCRIPTOR = struct.pack('<BBBBHB', 7, 5, EP_OUT_ADDR, BULK, 64, 0)
EP_IN_DESCRIPTOR = struct.pack('<BBBBHB', 7, 5, EP_IN_ADDR, BULK, 64, 0)
# The brick's hardware EP3, an interrupt IN endpoint it never describes;
# the emulator uses it to keep dummy_hcd's IN FIFO busy (see RawGadgetBrick).
EP_HIDDEN_DESCRIPTOR = struct.pack('<BBBBHB', 7, 5, 0x83, 0x03, 64, 10)
CONFIG_DESCRIPTOR = (struct.pack('<BBHBBBBB', 9, 2, 32, 1, 1, 0, 0xC0, 0) +
                     struct.pack('<BBBBBBBBB', 9, 4, 0, 0, 2, 0xFF, 0xFF, 0xFF, 0) +
                     EP_OUT_DESCRIPTOR + EP_IN_DESCRIPTOR)


def string_descriptor(index, serial):
    if index == 0:
        return bytes([4, 3, 0x09, 0x04])
    if index == 1:
        s = serial.encode('utf-16-le')
        return bytes([2 + len(s), 3]) + s
    return None


def _ioc(direction, nr, size):
    return (direction << 30) | (size << 16) | (ord('U') << 8) | nr


_W, _R = 1, 2
USB_RAW_IOCTL_INIT = _ioc(_W, 0, 257)
USB_RAW_IOCTL_RUN = _ioc(0, 1, 0)
USB_RAW_IOCTL_EVENT_FETCH = _ioc(_R, 2, 8)
USB_RAW_IOCTL_EP0_WRITE = _ioc(_W, 3, 8)
USB_RAW_IOCTL_EP0_READ = _ioc(_W | _R, 4, 8)
USB_RAW_IOCTL_EP_ENABLE = _ioc(_W, 5, 9)
USB_RAW_IOCTL_EP_WRITE = _ioc(_W, 7, 8)
USB_RAW_IOCTL_EP_READ = _ioc(_W | _R, 8, 8)
USB_RAW_IOCTL_CONFIGURE = _ioc(0, 9, 0)
USB_RAW_IOCTL_VBUS_DRAW = _ioc(_W, 10, 4)
USB_RAW_IOCTL_EP0_STALL = _ioc(0, 12, 0)
USB_RAW_IOCTL_EP_SET_HALT = _ioc(_W, 13, 4)

EVENT_CONNECT, EVENT_CONTROL, EVENT_SUSPEND, EVENT_RESUME = 1, 2, 3, 4
EVENT_RESET, EVENT_DISCONNECT = 5, 6
USB_SPEED_FULL = 2

# Standard requests.
GET_STATUS, SET_ADDRESS, GET_DESCRIPTOR = 0x00, 0x05, 0x06
GET_CONFIGURATION, SET_CONFIGURATION = 0x08, 0x09
DT_DEVICE, DT_CONFIG, DT_STRING = 1, 2, 3

HOSTILE_MODES = ('short', 'long', 'opcode', 'noreply', 'garbage', 'stall', 'disconnect',
                 'mislength', 'deaf')

# Blocking raw-gadget ioctls are woken by this signal (its handler does
# nothing, so the ioctl returns EINTR and the thread sees it should stop).
WAKE_SIGNAL = signal.SIGUSR1

_libc = ctypes.CDLL(None, use_errno=True)
_libc.ioctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_void_p]
_libc.ioctl.restype = ctypes.c_int


def _ioctl(fd, request, arg=None):
    """ioctl through ctypes, which lets other threads run while it blocks."""
    ret = _libc.ioctl(fd, request, arg)
    if ret < 0:
        e = ctypes.get_errno()
        raise OSError(e, os.strerror(e))
    return ret


def _ensure_wake_handler():
    if signal.getsignal(WAKE_SIGNAL) in (signal.SIG_DFL, signal.SIG_IGN, None):
        if threading.current_thread() is not threading.main_thread():
            raise RuntimeError('start the first RawGadgetBrick from the main thread '
                               '(it installs a handler for SIGUSR1)')
        signal.signal(WAKE_SIGNAL, lambda signum, frame: None)


class _Reply:
    def __init__(self, data):
        self.data = data
        self.collected = threading.Event()


class RawGadgetBrick:
    """A brick on the UDC `udc` (dummy_udc.N), running `firmware`.

    start() plugs it in, stop() or unplug() pulls it out (closing the files
    opened over USB), replug() plugs the same brick in again. `configured`
    is set while the host has it configured; `events` logs what happened.
    """

    def __init__(self, udc='dummy_udc.0', serial='001653A0B1C2', name='NXT',
                 hostile=None, firmware=None, driver='dummy_udc', seed=1,
                 reply_timeout=USB_REPLY_TIMEOUT, verbose=False, tick=None):
        if hostile is not None and hostile not in HOSTILE_MODES:
            raise ValueError('hostile must be one of %s' % ', '.join(HOSTILE_MODES))
        if len(serial) != 12 or any(c not in '0123456789ABCDEF' for c in serial):
            raise ValueError('the serial is the BT address as 12 upper-case hex digits')
        self.udc, self.driver, self.serial = udc, driver, serial
        self.fw = firmware or Firmware(name=name, bt_address=serial)
        self.hostile = hostile
        self.rng = random.Random(seed)
        self.reply_timeout = reply_timeout
        self.verbose = verbose
        self.tick = tick                # seconds per scheduler pass, or None
        self._next_pass = 0             # (tick) the earliest next pass, in ticks
        self.configured = threading.Event()
        self.events = []
        self.commands = 0
        self.replies_lost = 0
        self.times_configured = 0
        self.fd = None
        self._ctl = threading.Lock()
        self._stopping = threading.Event()
        self._threads = []
        self._banks = collections.deque()
        self._cond = threading.Condition()
        self._config = 0
        self._ep_out = self._ep_in = self._ep_hidden = None
        self._parked = threading.Event()
        # A reply the command loop writes itself: (thread id, deadline),
        # 'interrupted' once the IN loop's watchdog stopped the write.
        self._writing = None

    def log(self, what):
        self.events.append((time.monotonic(), what))
        if self.verbose:
            print('nxt_brick %s: %s' % (self.udc, what), flush=True)

    # ---- control ----

    def start(self):
        with self._ctl:
            if self.fd is not None:
                return
            _ensure_wake_handler()
            fd = os.open('/dev/raw-gadget', os.O_RDWR)
            try:
                init = struct.pack('128s128sB', self.driver.encode(), self.udc.encode(),
                                   USB_SPEED_FULL)
                _ioctl(fd, USB_RAW_IOCTL_INIT, ctypes.create_string_buffer(init, len(init)))
                _ioctl(fd, USB_RAW_IOCTL_RUN)
            except OSError:
                os.close(fd)
                raise
            self.fd = fd
            self._stopping.clear()
            self._banks.clear()
            self._config = 0
            self._ep_out = self._ep_in = self._ep_hidden = None
            self._parked.clear()
            self.fw.rebooting = False       # plugged in again: the firmware booted
            self._spawn(self._ep0_loop, 'ep0')
            self.log('plugged in')

    def stop(self):
        self.unplug()

    def unplug(self):
        """Pull the cable: the host sees a disconnect, USB file handles close."""
        with self._ctl:
            if self.fd is None:
                return
            self._stopping.set()
            with self._cond:
                self._cond.notify_all()
            me = threading.current_thread()
            for t in self._threads:
                while t is not me and t.is_alive():
                    try:
                        signal.pthread_kill(t.ident, WAKE_SIGNAL)
                    except ProcessLookupError:
                        pass
                    t.join(0.05)
            self._threads = []
            os.close(self.fd)
            self.fd = None
            self.configured.clear()
            self.fw.usb_disconnected()
            self.log('unplugged')

    def replug(self):
        self.unplug()
        self.start()

    def wait_configured(self, timeout):
        return self.configured.wait(timeout)

    def _spawn(self, fn, name):
        t = threading.Thread(target=fn, name='nxt-%s-%s' % (self.udc, name), daemon=True)
        self._threads.append(t)
        t.start()

    def _unplug_soon(self, why):
        self.log(why)
        threading.Thread(target=self.unplug, daemon=True).start()

    # ---- raw-gadget I/O ----

    def _io(self, request, ep, data=b'', length=None):
        n = len(data) if length is None else length
        buf = ctypes.create_string_buffer(struct.pack('<HHI', ep, 0, n) + data, 8 + n)
        got = _ioctl(self.fd, request, buf)
        return buf.raw[8:8 + got]

    def _fetch_event(self):
        buf = ctypes.create_string_buffer(struct.pack('<II', 0, 8), 16)
        _ioctl(self.fd, USB_RAW_IOCTL_EVENT_FETCH, buf)
        etype, length = struct.unpack_from('<II', buf.raw)
        return etype, buf.raw[8:8 + min(length, 8)]

    def _after_flush(self, e, gen):
        """A bulk transfer failed with `e`; `gen` is times_configured when it
        was queued. After a bus reset or an unplug flushed it (ESHUTDOWN),
        queue nothing until the host has configured the brick again: until
        the port is enabled again, queueing fails, and raw-gadget in 6.1
        (which reports no reset event) then marks the whole device failed.
        """
        if e.errno == errno.EINTR or self._stopping.is_set():
            return
        if e.errno != errno.ESHUTDOWN:
            self._stopping.wait(0.01)
            return
        while self.times_configured == gen and not self._stopping.is_set():
            self._stopping.wait(0.01)

    # ---- ep0 ----

    def _ep0_loop(self):
        while not self._stopping.is_set():
            try:
                etype, data = self._fetch_event()
            except OSError as e:
                if e.errno != errno.EINTR and not self._stopping.is_set():
                    self.log('event fetch failed: %s' % e)
                    self._stopping.wait(0.1)
                continue
            if etype == EVENT_CONTROL:
                try:
                    self._control(data)
                except OSError as e:
                    if not self._stopping.is_set():
                        self.log('control request %s failed: %s' % (data.hex(), e))
            elif etype == EVENT_CONNECT:
                self.log('bound to %s' % self.udc)
            elif etype == EVENT_RESET:
                self.log('bus reset')
                self._config = 0
                self.configured.clear()
            elif etype == EVENT_DISCONNECT:
                self.log('disconnected')
                self._config = 0
                self.configured.clear()
                self.fw.usb_disconnected()
            elif etype == EVENT_SUSPEND:
                self.log('suspended')
                self.configured.clear()
            elif etype == EVENT_RESUME:
                self.log('resumed')
                if self._config:
                    self.configured.set()

    def _control(self, setup):
        rtype, req, value, index, length = struct.unpack('<BBHHH', setup)
        reply = None
        if rtype & 0x60 == 0:                       # standard
            if rtype == 0x80 and req == GET_DESCRIPTOR:
                dtype, dindex = value >> 8, value & 0xFF
                if dtype == DT_DEVICE:
                    reply = DEVICE_DESCRIPTOR
                elif dtype == DT_CONFIG and dindex == 0:
                    reply = CONFIG_DESCRIPTOR
                elif dtype == DT_STRING:
                    reply = string_descriptor(dindex, self.serial)
            elif rtype == 0x80 and req == GET_CONFIGURATION:
                reply = bytes([self._config])
            elif rtype == 0x80 and req == GET_STATUS:   # dummy_hcd answers it first
                reply = b'\x01\x00'
            elif rtype == 0x00 and req == SET_CONFIGURATION and value in (0, 1):
                self._set_configuration(value)
                self._io(USB_RAW_IOCTL_EP0_READ, 0, length=0)
                return
        if reply is None:
            _ioctl(self.fd, USB_RAW_IOCTL_EP0_STALL)
            self.log('stalled control request %s' % setup.hex())
            return
        self._io(USB_RAW_IOCTL_EP0_WRITE, 0, reply[:length])

    def _set_configuration(self, value):
        if value == 1 and self._ep_out is None:
            self._ep_out = _ioctl(self.fd, USB_RAW_IOCTL_EP_ENABLE,
                                  ctypes.create_string_buffer(EP_OUT_DESCRIPTOR + b'\0\0', 9))
            self._ep_in = _ioctl(self.fd, USB_RAW_IOCTL_EP_ENABLE,
                                 ctypes.create_string_buffer(EP_IN_DESCRIPTOR + b'\0\0', 9))
            self._ep_hidden = _ioctl(self.fd, USB_RAW_IOCTL_EP_ENABLE,
                                     ctypes.create_string_buffer(EP_HIDDEN_DESCRIPTOR + b'\0\0', 9))
            self._spawn(self._park_loop, 'park')
            self._spawn(self._command_loop, 'commands')
            self._spawn(self._in_loop, 'in')
        if value == 1:
            _ioctl(self.fd, USB_RAW_IOCTL_VBUS_DRAW, 0)    # MaxPower 0
            _ioctl(self.fd, USB_RAW_IOCTL_CONFIGURE)
        self._config = value
        if value:
            self.times_configured += 1
            self.configured.set()
            self.log('configured')
        else:
            self.configured.clear()
            self.log('unconfigured')

    # ---- the command loop (the firmware's comm module) ----

    def _next_command(self):
        """The next command packet from the host, or None (not configured
        yet, or the read was flushed by a reset or disconnect): call again."""
        if not self.configured.wait(0.1):
            return None
        gen = self.times_configured
        try:
            packet = self._io(USB_RAW_IOCTL_EP_READ, self._ep_out, length=64)
        except OSError as e:
            # Reset or disconnect: the request was flushed.
            self._after_flush(e, gen)
            return None
        self.commands += 1
        return packet

    def _wait_for_pass(self):
        """(tick) Sleep until the scheduler pass that reads the command
        that has just come: the first tick at or after now and after the
        last pass ended."""
        now = time.monotonic()
        at = max(self._ticks(now, math.ceil), self._next_pass) * self.tick
        if at - now > 1e-9:
            time.sleep(at - now)

    def _pass_done(self):
        """(tick) The pass that handled a command has ended: the next one
        is on the next tick."""
        self._next_pass = self._ticks(time.monotonic(), math.floor) + 1

    def _ticks(self, t, rounding):
        """(tick) Time `t` in ticks, rounded by `rounding` (math.ceil or
        math.floor), to the nanosecond: t / tick is not exact in floating
        point, and a command that comes on a tick must not wait for the
        next."""
        return rounding(round(t / self.tick, 6))

    def _command_loop(self):
        while not self._stopping.is_set():
            if self.hostile == 'deaf':
                self._stopping.wait(0.1)
                continue
            packet = self._next_command()
            if packet is None:
                continue
            if self.tick:
                self._wait_for_pass()
            self.log('command %s' % packet.hex())
            if self.hostile == 'disconnect':
                self._unplug_soon('unplugging instead of replying')
                return
            reply = self.fw.handle(packet)
            if self.fw.busy:
                self._stopping.wait(self.fw.busy)
            if reply is not None:
                self._send(reply)
            if self.tick:
                self._pass_done()
            if self.fw.rebooting:
                self._unplug_soon('rebooting into SAM-BA (not emulated)')
                return

    def _spoil(self, reply):
        """What a hostile brick sends instead of `reply` (None: nothing)."""
        h = self.hostile
        if h == 'short':
            return reply[:max(1, len(reply) // 2)]
        if h == 'long':
            return reply + b'\xa5' * (64 - len(reply))
        if h == 'opcode':
            return reply[:1] + bytes([(reply[1] + 1) & 0xFF]) + reply[2:]
        if h == 'garbage':
            junk = bytes(self.rng.randrange(256) for _ in range(self.rng.randrange(1, 65)))
            return bytes([self.rng.choice([b for b in range(256) if b != REPLY])]) + junk[1:]
        if h in ('noreply', 'stall'):
            return None
        return reply

    def _send(self, reply):
        if self.hostile == 'mislength':
            # A reply to the same opcode but of the wrong length first.
            self._queue_reply(reply + b'\xa5' * (64 - len(reply)) if len(reply) < 64
                              else reply[:-1])
        reply = self._spoil(reply)
        if self.hostile == 'stall':
            try:
                _ioctl(self.fd, USB_RAW_IOCTL_EP_SET_HALT, self._ep_in)
                self.log('halted the IN endpoint')
            except OSError as e:
                self.log('set halt failed: %s' % e)
            return
        if reply is None:
            return
        self._queue_reply(reply)

    def _queue_reply(self, reply):
        """Put `reply` in the IN FIFO and wait, as the firmware does, for
        the host to collect it."""
        if self._write_reply(reply):
            return
        item = _Reply(reply)
        with self._cond:
            if len(self._banks) >= IN_BANKS:
                self.replies_lost += 1
                self.log('reply lost, both IN banks full: %s' % reply.hex())
                item = None
            else:
                self._banks.append(item)
                self._cond.notify_all()
        # The firmware busy-waits for the host to take the reply, then goes on.
        deadline = time.monotonic() + self.reply_timeout
        while not self._stopping.is_set():
            left = deadline - time.monotonic()
            if left <= 0 or (item is not None and item.collected.wait(min(left, 0.05))):
                break
            if item is None:
                self._stopping.wait(min(left, 0.05))
        if item is not None and not item.collected.is_set():
            self.log('reply not collected in time, left queued')

    def _write_reply(self, reply):
        """The common case of _queue_reply(), with no thread in between:
        when no older reply is queued, write `reply` to the IN endpoint
        from here and return once the host has read it. If it has not
        within reply_timeout, the IN loop's watchdog interrupts the write,
        and the reply goes to the IN loop to stay queued while the firmware
        goes on. False when this does not apply (an older reply is queued,
        or nothing is parked yet after a reset): queue it instead."""
        gen = self.times_configured
        with self._cond:
            if self._banks or not self._parked.is_set():
                return False
            self._writing = (threading.get_ident(), time.monotonic() + self.reply_timeout)
        try:
            self._io(USB_RAW_IOCTL_EP_WRITE, self._ep_in, reply)
        except OSError as e:
            with self._cond:
                interrupted = self._writing == 'interrupted'
                self._writing = None
                if interrupted and not self._stopping.is_set():
                    # Not collected in time: it stays queued, the firmware goes on.
                    self.log('reply not collected in time, left queued')
                    self._banks.append(_Reply(reply))
                    self._cond.notify_all()
                    return True
            if self._stopping.is_set():
                return True
            if e.errno != errno.EINTR:
                self.log('IN endpoint flushed (%s), 1 replies dropped' % e)
                self._after_flush(e, gen)
            return True
        with self._cond:
            self._writing = None
        self.log('reply collected %s' % reply.hex())
        return True

    def _watchdog(self):
        """(IN loop, under _cond) Interrupt a write of _write_reply() that
        has waited reply_timeout for the host."""
        w = self._writing
        if w and w != 'interrupted' and time.monotonic() >= w[1]:
            self._writing = 'interrupted'
            try:
                signal.pthread_kill(w[0], WAKE_SIGNAL)
            except ProcessLookupError:
                pass

    def _park_loop(self):
        """Keep a packet in dummy_hcd's IN FIFO, on the endpoint nobody reads.

        The first write takes the FIFO and completes at once; the next one
        waits for ever, until a reset or disconnect flushes both.
        """
        while not self._stopping.is_set():
            if not self.configured.wait(0.1):
                continue
            gen = self.times_configured
            try:
                self._io(USB_RAW_IOCTL_EP_WRITE, self._ep_hidden, b'\0')
                self._parked.set()
            except OSError as e:
                self._parked.clear()
                self._after_flush(e, gen)

    def _in_loop(self):
        while not self._stopping.is_set():
            with self._cond:
                while not self._banks and not self._stopping.is_set():
                    self._watchdog()
                    self._cond.wait(min(0.05, self.reply_timeout / 5))
                if self._stopping.is_set():
                    return
                item = self._banks[0]
            self._parked.wait(USB_REPLY_TIMEOUT)
            gen = self.times_configured
            try:
                self._io(USB_RAW_IOCTL_EP_WRITE, self._ep_in, item.data)
            except OSError as e:
                if self._stopping.is_set():
                    return
                if e.errno != errno.EINTR:
                    # A bus reset or disconnect flushed the endpoint.
                    with self._cond:
                        dropped = len(self._banks)
                        self._banks.clear()
                    self.log('IN endpoint flushed (%s), %d replies dropped' % (e, dropped))
                    self._after_flush(e, gen)
                continue
            with self._cond:
                if self._banks and self._banks[0] is item:
                    self._banks.popleft()
            item.collected.set()
            self.log('reply collected %s' % item.data.hex())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--udc', default='dummy_udc.0', help='UDC device (default dummy_udc.0)')
    ap.add_argument('--driver', default='dummy_udc', help='UDC driver (default dummy_udc)')
    ap.add_argument('--serial', default='001653A0B1C2',
                    help='USB serial = Bluetooth address, 12 upper-case hex digits')
    ap.add_argument('--name', default='NXT', help='brick name (GetDeviceInfo)')
    ap.add_argument('--hostile', choices=HOSTILE_MODES)
    ap.add_argument('--verbose', action='store_true', help='log every event and command')
    ap.add_argument('--tick-ms', type=float, default=0,
                    help='model the firmware\'s scheduler: at most one command per tick of '
                    'MS ms (the real brick: 1); default 0, as fast as possible')
    args = ap.parse_args()

    stop = StopSignals()
    brick = RawGadgetBrick(udc=args.udc, driver=args.driver, serial=args.serial,
                           name=args.name, hostile=args.hostile, verbose=args.verbose,
                           tick=args.tick_ms / 1000 if args.tick_ms > 0 else None)
    try:
        brick.start()
    except OSError as e:
        sys.exit('nxt_brick: cannot start on %s: %s' % (args.udc, e))
    announced = False
    while not stop.wait(0.1):
        if not announced and brick.configured.is_set():
            print('nxt_brick: configured on %s, serial %s' % (args.udc, args.serial), flush=True)
            announced = True
    brick.stop()


if __name__ == '__main__':
    main()
