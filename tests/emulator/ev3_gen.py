"""Generated EV3 UART sensor handshakes: valid by the protocol's rules, and
extreme.

Every case comes from one integer seed (case(seed)), so a failure is
replayed from the seed alone. A case is either

- generated: every type id, 1 to 8 modes (9 to 16 for a Powered Up device:
  4-byte MODES, MODE_PLUS_8, NAME flags, MAPPING, MODE_COMBOS), every value count and data type a
  32-byte payload allows, figures and decimals at their limits, every unit
  of the driver's IIO table, LEGO's own units and unknown ones, RAW/PCT/SI
  ranges that are zero, inverted, huge, tiny, NaN or infinite (or left out),
  names up to 11 characters in payloads of 1 to 32 bytes, optional MODES and
  SPEED, Powered Up extras (the 4-byte MODES, VERSION and EXT_MODE
  commands, INFO types 5..12 and the mode-plus-8 flag), the bytes the
  parser skips between messages (SYNC, NACK, 0xff) and garbage before the
  TYPE; or
- mutated: the handshake of a real sensor (every one ev3_sensor.py plays)
  or of a generated one, with payload bytes, headers, info types, whole
  messages and fields changed, every checksum then repaired so that the
  change gets past the checksum.

parse() is a model of the driver's handshake parser (ev3_uart_proto.c:
ev3_uart_cmd/info/format and the state machine around them). It tells what
the driver will make of the bytes: the sensor description it registers, or
the reason it refuses them. The guest runner (tests/guest/ev3_fuzz.py)
plays the case with ev3_sensor.EmulatedSensor and checks the driver
against this model and the ABI's invariants.

known_bugs() names the driver bugs a description is known to trigger, so
that runs can steer away from them (known='avoid'), run only them
(known='only') or ignore them (known='include').

Usage (on the host, no VM needed):
  python3 tests/emulator/ev3_gen.py --seed S [--known avoid|include|only]
      print the case: its description, the model's verdict, its bytes
  python3 tests/emulator/ev3_gen.py --find BUG [--start S] [--limit N]
      the first seeds whose case triggers a known bug (BUG: a name from
      KNOWN_BUGS or "any")
  python3 tests/emulator/ev3_gen.py --stats N
      how N cases split between kinds, verdicts and known bugs
"""
import argparse
import math
import os
import random
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ev3_sensor as es  # noqa: E402

# ---- the driver's limits (drivers/lego/ev3/ev3_uart_proto.h) ----
MAX_PAYLOAD = 32
MAX_EV3_MODES = 8
MAX_MODES = 16          # Powered Up devices
SHORT_NAME_LEN = 5      # a Powered Up NAME this short may carry 6 flag bytes
NAME_LEN = 11
UNITS_LEN = 4
TYPE_MIN, TYPE_MAX = 1, 101
SPEED_MIN, SPEED_MAX = 2400, 460800
MAX_DECIMALS = 9
MAX_FIGURES = 15
CMD_EXT_MODE, CMD_VERSION = 6, 7
INFO_PUP_FIRST, INFO_PUP_LAST, INFO_MODE_PLUS_8 = 0x05, 0x0c, 0x20
TYPE_COLOR, TYPE_US, TYPE_GYRO, TYPE_IR = 29, 30, 32, 33
SIZE = {es.S8: 1, es.S16: 2, es.S32: 4, es.FLOAT: 4}
FORMATS = {es.S8: 's8', es.S16: 's16', es.S32: 's32', es.FLOAT: 'float'}

DRIVER_NAMES = {29: 'lego-ev3-color', 30: 'lego-ev3-us', 32: 'lego-ev3-gyro',
                33: 'lego-ev3-ir', 71: 'fcl-adc', 72: 'fcl-gesture', 73: 'fcl-light',
                74: 'fcl-altitude', 75: 'fcl-ir', 76: 'fcl-9dof', 77: 'fcl-humidity'}
# Powered Up devices (a handshake that used an extension): a table of their own.
LUMP_DRIVER_NAMES = {34: 'lego-wedo2-tilt', 35: 'lego-wedo2-motion',
                     37: 'lego-boost-color-dist', 38: 'lego-boost-motor',
                     46: 'lego-technic-l-motor', 47: 'lego-technic-xl-motor',
                     48: 'lego-spike-m-motor', 49: 'lego-spike-l-motor',
                     61: 'lego-spike-color', 62: 'lego-spike-ultrasonic',
                     63: 'lego-spike-force', 64: 'lego-technic-color-matrix',
                     65: 'lego-spike-s-motor', 75: 'lego-technic-m-angular-motor',
                     76: 'lego-technic-l-angular-motor'}

# The IIO unit table of ev3_uart_iio.c: unit -> (IIO type name, nano)
IIO_UNITS = {'deg': ('angl', 17453293), 'd/s': ('anglvel', 17453293),
             'cm': ('distance', 10000000), 'inch': ('distance', 25400000),
             'mm': ('distance', 1000000), 'C': ('temp', 10 ** 12),
             '%RH': ('humidityrelative', 10 ** 12), 'mV': ('voltage', 10 ** 9),
             'lx': ('illuminance', 10 ** 9), 'hPa': ('pressure', 10 ** 8),
             'g': ('accel', 9806650000), 'uT': ('magn', 10000000)}
# Modes whose unit says nothing (ev3_iio_modes): (type, name) -> nano
IIO_MODES = {(29, 'COL-REFLECT'): 10 ** 9, (29, 'COL-AMBIENT'): 10 ** 9,
             (29, 'REF-RAW'): 10 ** 9, (29, 'RGB-RAW'): 10 ** 9,
             (32, 'GYRO-FAS'): 17453293, (32, 'GYRO-G&A'): 17453293,
             (33, 'IR-PROX'): 10 ** 9}
# The same for Powered Up devices: (type, name) -> nano
IIO_LUMP_MODES = {(37, 'REFLT'): 10 ** 9, (37, 'AMBI'): 10 ** 9, (37, 'RGB I'): 10 ** 9,
                  (37, 'PROX'): 10 ** 9, (37, 'COUNT'): 10 ** 9,
                  (61, 'REFLT'): 10 ** 9, (61, 'AMBI'): 10 ** 9, (61, 'RREFL'): 10 ** 9,
                  (61, 'RGB I'): 10 ** 9}
IIO_MAX_CHANNELS = MAX_EV3_MODES * 8      # plus the timestamp: arrays of 65
LEGO_UNITS = ['pct', 'col', 'btn', 'F', '%', 'V', 'A', 'm', 's', 'ms', 'kPa', 'N', 'rpm',
              'Hz', 'mA', 'rot', 'ppm', 'lux', 'K', 'us']

# Real sensors' modes, per type, for names that hit the driver's tables.
REAL_NAMES = {}
for _s in es.SENSORS.values():
    REAL_NAMES.setdefault(_s.type, [])
    REAL_NAMES[_s.type] += [m.name for m in _s.modes if m.name not in REAL_NAMES[_s.type]]

F32_NAN = [0x7fc00000, 0x7f800001, 0xffc00000, 0x7fffffff]
F32_INF = [0x7f800000, 0xff800000]
DEFAULT_RANGES = {'raw': (0.0, 1023.0), 'pct': (0.0, 100.0), 'si': (0.0, 1.0)}


def fbits(x):
    return struct.unpack('<I', struct.pack('<f', x))[0]


def bits_float(b):
    return struct.unpack('<f', struct.pack('<I', b))[0]


# ---- the model of the driver's parser ----------------------------------------

def f32_to_fixed(bits, decimals):
    """ev3_uart_f32_to_fixed(): None for NaN, infinities and what does not
    fit an s32, else the value times 10^decimals rounded half away from 0."""
    neg = bits >> 31
    exp = (bits >> 23) & 0xff
    v = bits & 0x7fffff
    if exp == 0xff:
        return None
    if exp == 0:
        return 0
    v = (v | 0x800000) * 10 ** decimals
    shift = exp - 150
    if shift >= 0:
        if shift > 8:
            return None
        v <<= shift
    elif shift < -62:
        v = 0
    else:
        v = (v + (1 << (-shift - 1))) >> -shift
    if v > 0x7fffffff + neg:
        return None
    return -v if neg else v


class Mode:
    """What the driver keeps of one mode (struct ev3_uart_mode)."""

    def __init__(self):
        self.name = ''
        self.units = ''
        self.n = self.t = self.fig = self.dec = 0
        self.raw = self.pct = self.si = (0, 0)

    def __repr__(self):
        return ('Mode(%r, units=%r, n=%d, %s, fig=%d, dec=%d, raw=%s, pct=%s, si=%s)'
                % (self.name, self.units, self.n, FORMATS[self.t], self.fig, self.dec,
                   self.raw, self.pct, self.si))


class Desc:
    """What the driver registers (struct ev3_uart_sensor)."""

    def __init__(self, type_id):
        self.type = type_id
        self.num_modes = 1
        self.views = 1
        self.speed = SPEED_MIN
        self.lump = False       # a Powered Up extension was used
        self.fw_version = 0     # VERSION's first word (0: none sent)
        self.modes = [Mode() for _ in range(MAX_MODES)]

    @property
    def fw_version_str(self):
        """The fw_version attribute: LEGO's BCD fields, empty for none."""
        v = self.fw_version
        if not v:
            return ''
        return '%x.%x.%02x.%04x' % (v >> 28 & 7, v >> 24 & 0xf, v >> 16 & 0xff, v & 0xffff)

    @property
    def driver(self):
        if self.lump:
            return LUMP_DRIVER_NAMES.get(self.type, 'lump-uart-%d' % self.type)
        return DRIVER_NAMES.get(self.type, 'ev3-uart-%d' % self.type)

    def __repr__(self):
        return 'Desc(type=%d, modes=%d, views=%d, speed=%d,\n  %s)' % (
            self.type, self.num_modes, self.views, self.speed,
            ',\n  '.join(repr(m) for m in self.modes[:self.num_modes]))


def _cstr(payload):
    n = payload.find(0)
    return payload if n < 0 else payload[:n]


def _check_string(payload, maxlen):
    s = _cstr(payload)
    if len(s) > maxlen:
        return 'string too long'
    if any(c < 0x20 or c > 0x7e for c in s):
        return 'string not printable'
    return None


def msg_len(hdr):
    kind = hdr & 0xc0
    if kind == 0:
        return 1
    plen = 1 << ((hdr >> 3) & 7)
    return plen + 3 if kind == 0x80 else plen + 2


class Parser:
    """The handshake half of ev3_uart_parser_feed(): SYNC -> INFO -> ACKED.
    feed() returns (Desc, None) once the ACK ends a handshake, or
    (None, reasons) if the bytes never make one (reasons: why each attempt
    was refused, in order)."""

    def __init__(self):
        self.state = 'sync'
        self.win = []
        self.msg = []
        self.errors = []

    def error(self, reason):
        self.errors.append(reason)
        self.state = 'sync'
        self.win = []
        self.msg = []

    def feed(self, data):
        for b in data:
            if self.state == 'sync':
                self.win.append(b)
                if len(self.win) > 3:
                    del self.win[0]
                w = self.win
                if (len(w) == 3 and w[0] == 0x40 and TYPE_MIN <= w[1] <= TYPE_MAX
                        and w[2] == es.checksum(w[:2])):
                    self.start(w[1])
            elif self.state == 'info':
                if not self.msg:
                    if b == 0xff:
                        continue
                    if b & 0xc0 == 0:
                        if b == es.SYS_ACK:
                            allm = (1 << self.desc.num_modes) - 1
                            if self.modes_done & allm != allm:
                                self.error('ACK before every mode was described')
                            else:
                                self.state = 'acked'
                                return self.desc, None
                        continue
                    if 1 << ((b >> 3) & 7) > MAX_PAYLOAD:
                        self.error('message too long')
                        continue
                self.msg.append(b)
                if len(self.msg) < msg_len(self.msg[0]):
                    continue
                msg, self.msg = bytes(self.msg), []
                self.message(msg)
        return None, self.errors or ['no complete handshake']

    def start(self, type_id):
        self.desc = Desc(type_id)
        self.cmd_seen = {es.CMD_TYPE}
        self.info_mode = None
        self.info_seen = set()
        self.modes_done = 0
        self.stash = {}
        self.msg = []
        self.win = []
        self.state = 'info'

    def message(self, msg):
        if msg[-1] != es.checksum(msg[:-1]):
            return self.error('bad checksum in handshake')
        kind = msg[0] & 0xc0
        if kind == 0x40:
            return self.cmd(msg[0] & 7, msg[1:-1])
        if kind == 0x80:
            return self.info(msg[0] & 7, msg[1], msg[2:-1])
        return self.error('DATA before ACK')

    def cmd(self, cmd, p):
        d = self.desc
        if cmd == es.CMD_MODES:
            if cmd in self.cmd_seen:
                return self.error('duplicate MODES')
            if self.info_mode is not None:
                return self.error('MODES after INFO')
            if p[0] >= MAX_EV3_MODES:
                return self.error('number of modes out of range')
            if len(p) >= 4:
                # Powered Up: the last two bytes count all modes and views.
                if p[2] >= MAX_MODES:
                    return self.error('number of modes out of range')
                p = p[2:]
                d.lump = True
            d.num_modes = p[0] + 1
            d.views = min(p[1] + 1, d.num_modes) if len(p) >= 2 else d.num_modes
        elif cmd == es.CMD_SPEED:
            if cmd in self.cmd_seen:
                return self.error('duplicate SPEED')
            if self.info_mode is not None:
                return self.error('SPEED after INFO')
            if len(p) < 4:
                return self.error('short SPEED')
            speed = struct.unpack_from('<I', p)[0]
            if not SPEED_MIN <= speed <= SPEED_MAX:
                return self.error('speed out of range')
            d.speed = speed
        elif cmd == CMD_VERSION:
            if len(p) < 8:
                return self.error('short VERSION')
            d.fw_version = struct.unpack_from('<I', p)[0]
            d.lump = True
        elif cmd == CMD_EXT_MODE:
            pass
        elif cmd == es.CMD_TYPE:
            return self.error('duplicate TYPE')
        else:
            return self.error('unexpected command')
        self.cmd_seen.add(cmd)

    def info(self, mode, itype, p):
        d = self.desc
        if itype & INFO_MODE_PLUS_8:
            itype &= ~INFO_MODE_PLUS_8
            mode += 8
            d.lump = True
        if INFO_PUP_FIRST <= itype <= INFO_PUP_LAST:
            d.lump = True       # kept or skipped (any mode), never fatal
            return
        if mode >= d.num_modes:
            return self.error('INFO for a mode out of range')
        m = d.modes[mode]
        if itype == es.INFO_NAME:
            if self.info_mode is not None and not self.modes_done & (1 << self.info_mode):
                return self.error("NAME before the previous mode's FORMAT")
            if self.modes_done & (1 << mode):
                return self.error('duplicate mode')
            err = _check_string(p, NAME_LEN)
            if err:
                return self.error(err)
            if not ord('A') <= p[0] <= ord('z'):
                return self.error('bad mode name')
            d.modes[mode] = m = Mode()
            m.name = _cstr(p).decode('ascii')
            if len(m.name) <= SHORT_NAME_LEN and len(p) >= SHORT_NAME_LEN + 1 + 6:
                d.lump = True   # capability flags after a short name
            self.stash = {es.INFO_RAW: (0, fbits(1023.0)), es.INFO_PCT: (0, fbits(100.0)),
                          es.INFO_SI: (0, fbits(1.0))}
            self.info_mode = mode
            self.info_seen = {es.INFO_NAME}
            return
        if mode != self.info_mode:
            return self.error('INFO for a mode not being described')
        if self.modes_done & (1 << mode):
            return self.error('INFO after FORMAT')
        if itype in (es.INFO_RAW, es.INFO_PCT, es.INFO_SI):
            if itype in self.info_seen:
                return self.error('duplicate range INFO')
            if len(p) < 8:
                return self.error('short range INFO')
            self.stash[itype] = struct.unpack_from('<II', p)
            self.info_seen.add(itype)
        elif itype == es.INFO_UNITS:
            if itype in self.info_seen:
                return self.error('duplicate UNITS')
            err = _check_string(p, UNITS_LEN)
            if err:
                return self.error(err)
            m.units = _cstr(p).decode('ascii')
            self.info_seen.add(itype)
        elif itype == es.INFO_FORMAT:
            self.format(mode, m, p)
        else:
            self.error('unknown INFO type')

    def format(self, mode, m, p):
        if len(p) < 4:
            return self.error('short FORMAT')
        if p[1] > es.FLOAT:
            return self.error('unknown data type')
        if not p[0] or p[0] * SIZE[p[1]] > MAX_PAYLOAD:
            return self.error('FORMAT value count out of range')
        if p[2] > MAX_FIGURES or p[3] > MAX_DECIMALS:
            return self.error('FORMAT figures or decimals out of range')
        m.n, m.t, m.fig, m.dec = p[0], p[1], p[2], p[3]
        if self.desc.type == TYPE_COLOR and mode == 4 and m.t == es.S16 and m.n == 3:
            m.n = 4
        st = self.stash
        conv = [f32_to_fixed(st[es.INFO_RAW][0], 0), f32_to_fixed(st[es.INFO_RAW][1], 0),
                f32_to_fixed(st[es.INFO_PCT][0], 0), f32_to_fixed(st[es.INFO_PCT][1], 0),
                f32_to_fixed(st[es.INFO_SI][0], m.dec), f32_to_fixed(st[es.INFO_SI][1], m.dec)]
        if None in conv:
            return self.error('range not representable')
        m.raw, m.pct, m.si = tuple(conv[0:2]), tuple(conv[2:4]), tuple(conv[4:6])
        self.modes_done |= 1 << mode


def parse(data):
    """(Desc, None) if the driver registers a sensor from `data`, else
    (None, [reasons])."""
    return Parser().feed(data)


# ---- what the driver shows, per the ABI ----------------------------------------

def read_value(m, payload, i):
    """ev3_uart_read_value(): value i of a DATA payload, or None (ERANGE)."""
    size = SIZE[m.t]
    raw = bytes(payload[i * size:(i + 1) * size])
    if m.t == es.FLOAT:
        return f32_to_fixed(struct.unpack('<I', raw)[0], m.dec)
    return int.from_bytes(raw, 'little', signed=True)


def _cdiv(a, b):
    q = abs(a) // abs(b)
    return q if (a < 0) == (b < 0) else -q


def scale_value(m, raw):
    """value<N> as the ABI describes it (ev3_uart_scale_value()): mapped
    linearly from RAW onto SI with truncating division, saturated to s32."""
    raw_span = m.raw[1] - m.raw[0]
    if (m.raw == m.si) or not raw_span:
        return raw
    v = _cdiv((raw - m.raw[0]) * (m.si[1] - m.si[0]), raw_span) + m.si[0]
    return max(-2 ** 31, min(2 ** 31 - 1, v))


# ---- IIO: which values become channels, and the known bugs ---------------------

def iio_nano(desc, mode):
    """The IIO unit factor the driver gives a mode's values, or None if the
    mode has no IIO channels (ev3_iio_chan_type())."""
    m = desc.modes[mode]
    table = IIO_LUMP_MODES if desc.lump else IIO_MODES
    if (desc.type, m.name) in table:
        return table[(desc.type, m.name)]
    if m.units in IIO_UNITS:
        return IIO_UNITS[m.units][1]
    return None


def iio_channels(desc):
    """How many IIO channels the current driver makes (before the fix)."""
    return sum(desc.modes[i].n for i in range(desc.num_modes)
               if iio_nano(desc, i) is not None)


def _scale_overflows(m, nano):
    raw_span = m.raw[1] - m.raw[0]
    si_span = m.si[1] - m.si[0]
    if m.t == es.FLOAT or not raw_span or not si_span:
        return False
    return abs(si_span) * nano // (abs(raw_span) * 10 ** m.dec) >= 2 ** 64


def _scale_nano(m, nano):
    """scale_nano as ev3_iio_scale() computes it (before the fix), or None
    where it traps."""
    raw_span = m.raw[1] - m.raw[0]
    si_span = m.si[1] - m.si[0]
    div = 10 ** m.dec
    if m.t == es.FLOAT or not raw_span or not si_span:
        return nano // div
    q = abs(si_span) * nano // (abs(raw_span) * div)
    if q >= 2 ** 64:
        return None
    if q >= 2 ** 63:
        q -= 2 ** 64                        # the u64 lands in an s64
    return -q if (si_span < 0) != (raw_span < 0) else q


def known_bugs(desc):
    """The known driver bugs `desc` triggers (names from KNOWN_BUGS)."""
    if desc is None:
        return []
    bugs = []
    if iio_channels(desc) > IIO_MAX_CHANNELS:
        bugs.append('iio-channels-overflow')
    if any(iio_nano(desc, i) is not None and _scale_overflows(desc.modes[i], iio_nano(desc, i))
           for i in range(desc.num_modes)):
        bugs.append('iio-scale-divide')
    scales = [_scale_nano(desc.modes[i], iio_nano(desc, i)) for i in range(desc.num_modes)
              if iio_nano(desc, i) is not None]
    if 0 in scales:
        bugs.append('iio-scale-zero')
    if any(v is not None and not -2 ** 31 * 10 ** 9 <= v < 2 ** 31 * 10 ** 9 for v in scales):
        bugs.append('iio-scale-wraps')
    return bugs


KNOWN_BUGS = {
    'iio-channels-overflow':
        'ev3_iio_fill_channels() writes one channel per value of every mode with an IIO '
        'unit, up to 8 x 32 = 256, into arrays of EV3_IIO_MAX_CHANNELS (65): KASAN '
        'slab-out-of-bounds in the channel array and in chan_mode/chan_index/scale_nano '
        '(a heap overflow inside struct ev3_uart_iio)',
    'iio-scale-zero':
        'ev3_iio_scale() truncates scales below 1e-9 IIO units to 0 (e.g. hPa over a RAW '
        'span of 2^31, or float/zero-span modes with many decimals: nano / 10^decimals): '
        'the channel reads 0 whatever the sensor measures',
    'iio-scale-wraps':
        'ev3_iio_scale() keeps a u64 quotient >= 2^63 in an s64 (negative), and '
        'read_raw() puts scale_nano / 10^9 in an int: scales of 2^31 or more read as '
        'wrong numbers, possibly of the wrong sign',
    'iio-scale-divide':
        'ev3_iio_scale(): mul_u64_u64_div_u64(|si_span|, nano, |raw_span| * 10^decimals) '
        'overflows 64 bits when the SI range is much wider than the RAW one (x86 divq '
        'traps: divide error in the ack work, i.e. an oops at registration)',
}


# ---- the generator ---------------------------------------------------------------

NAME_CHARS = 'ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-'
PRINTABLE = ''.join(chr(c) for c in range(0x20, 0x7f))


def gen_name(rng, type_id):
    r = rng.random()
    if r < 0.25 and type_id in REAL_NAMES:
        return rng.choice(REAL_NAMES[type_id])
    length = rng.choice([1, 2, 7, 8, 11, 11, rng.randint(1, NAME_LEN)])
    first = chr(rng.randint(ord('A'), ord('z')))
    chars = PRINTABLE if rng.random() < 0.15 else NAME_CHARS
    return first + ''.join(rng.choice(chars) for _ in range(length - 1))


def gen_units(rng):
    r = rng.random()
    if r < 0.45:
        return rng.choice(sorted(IIO_UNITS))
    if r < 0.6:
        return rng.choice(LEGO_UNITS)
    if r < 0.75:
        return ''.join(rng.choice(PRINTABLE) for _ in range(rng.randint(1, UNITS_LEN)))
    if r < 0.85:
        return ''            # UNITS message of zeros
    return None              # no UNITS message


def gen_float(rng, kind):
    """The bit pattern of one range end."""
    if kind == 'nan':
        return rng.choice(F32_NAN)
    if kind == 'inf':
        return rng.choice(F32_INF)
    if kind == 'tiny':
        return rng.choice([1, 0x00400000, 0x80000001, fbits(1e-30), fbits(-1e-20),
                           fbits(1e-3), fbits(0.5), fbits(-0.5), 0x80000000])
    if kind == 'huge':
        return fbits(rng.choice([2147483520.0, -2147483648.0, 2e9, -2e9, 1e9, 2e7, 1e7,
                                 16777216.0, 4294967296.0, 1e38, -1e38]))
    if kind == 'bits':
        return rng.getrandbits(32)
    return fbits(rng.choice([0.0, 1.0, -1.0, 100.0, 255.0, 1023.0, 1020.1875, 65535.0,
                             -32768.0, 32767.0, 180.0, -180.0, 2550.0, 10.0, 127.0,
                             -128.0, 0.1, 3.5, rng.uniform(-1e5, 1e5),
                             float(rng.randint(-1000, 1000))]))


def gen_range(rng, dec, bad):
    """(lo, hi) bit patterns, or None to leave the message out. The driver
    refuses what does not fit an s32 times 10^dec (and NaN, infinities): a
    `bad` range may be anything, the others are re-drawn until they fit."""
    if rng.random() < 0.15:
        return None
    kinds = ['normal'] * 6 + ['tiny', 'huge', 'huge']
    if bad:
        kinds = ['nan', 'inf', 'bits', 'huge']
    for _ in range(20):
        lo = gen_float(rng, rng.choice(kinds))
        shape = rng.random()
        if shape < 0.1:
            hi = lo                                             # zero span
        elif shape < 0.2:
            hi, lo = lo, gen_float(rng, rng.choice(kinds))      # maybe inverted
        else:
            hi = gen_float(rng, rng.choice(kinds))
        if bad or None not in (f32_to_fixed(lo, dec), f32_to_fixed(hi, dec)):
            return lo, hi
    return fbits(0.0), fbits(1.0)


def gen_skewed(rng, dec):
    """A RAW range of a unit or two and an SI range of millions: the widest
    scales (raw, si)."""
    raw = rng.choice([(0.0, 1.0), (0.0, 2.0), (-1.0, 1.0), (1.0, 0.0), (0.0, 0.5)])
    top = 2147483520.0 / 10 ** dec
    si = rng.choice([(0.0, top), (-top, top), (0.0, top / 100), (top, 0.0),
                     (0.0, min(top, 2e7))])
    return tuple(map(fbits, raw)), tuple(map(fbits, si))


def pow2_at_least(n):
    return 1 << es.size_code(max(n, 1))


def gen_padding(rng, n, max_size=MAX_PAYLOAD):
    """A payload size for n bytes of content (a power of two >= n)."""
    size = pow2_at_least(n)
    if rng.random() < 0.2:
        size = rng.choice([s for s in (1, 2, 4, 8, 16, 32) if size <= s <= max_size])
    return size


class GenMode:
    def __init__(self, rng, type_id, bad_prob, maximal=False, units=None):
        self.name = gen_name(rng, type_id)
        self.name_size = gen_padding(rng, len(self.name))
        self.junk_after_name = rng.random() < 0.05
        self.units = units if units is not None else gen_units(rng)
        self.units_size = gen_padding(rng, len(self.units or ''))
        self.t = es.S8 if maximal else rng.randrange(4)
        top = MAX_PAYLOAD // SIZE[self.t]
        self.n = top if maximal else rng.choice([1, top, top, rng.randint(1, top),
                                                 rng.randint(1, 8)])
        self.fig = rng.choice([0, MAX_FIGURES, rng.randint(0, MAX_FIGURES)])
        self.dec = rng.choice([0, 0, MAX_DECIMALS, rng.randint(0, MAX_DECIMALS)])
        self.ranges = {'raw': gen_range(rng, 0, rng.random() < bad_prob),
                       'pct': gen_range(rng, 0, rng.random() < bad_prob),
                       'si': gen_range(rng, self.dec, rng.random() < bad_prob)}
        if rng.random() < 0.1:
            self.ranges['raw'], self.ranges['si'] = gen_skewed(rng, self.dec)
        self.range_size = rng.choice([8] * 8 + [16, 32])
        self.format_size = rng.choice([4] * 8 + [8, 16, 32])
        self.order = ['raw', 'pct', 'si', 'units']
        rng.shuffle(self.order)
        self.pup = [] if rng.random() < 0.85 else [
            (rng.choice([0x05, 0x06, 0x07, 0x08, 0x0a, 0x0b, 0x0c, INFO_MODE_PLUS_8,
                         INFO_MODE_PLUS_8 | 1, INFO_MODE_PLUS_8 | 0x80]),
             bytes(rng.randrange(256) for _ in range(rng.choice([1, 2, 4, 8]))))
            for _ in range(rng.randint(1, 3))]


def _str_payload(s, size, rng=None, junk=False):
    b = s.encode('ascii')
    p = b + bytes(size - len(b))
    if junk and len(b) + 1 < size:
        p = p[:len(b) + 1] + bytes(rng.randrange(1, 256) for _ in range(size - len(b) - 1))
    return p


def _info(mode, itype, payload):
    """An INFO message with exactly this payload (a power of two long)."""
    m = bytes([0x80 | es.size_code(len(payload)) << 3 | mode, itype]) + payload
    return m + bytes([es.checksum(m)])


def _cmd(cmd, payload):
    m = bytes([0x40 | es.size_code(len(payload)) << 3 | cmd]) + payload
    return m + bytes([es.checksum(m)])


def gen_sensor(rng, transport='pty', bad_prob=0.0):
    """A generated sensor's handshake. bad_prob: the chance of each range
    being one the driver must refuse (NaN, infinite, too big)."""
    r = rng.random()
    if r < 0.4:
        type_id = rng.randint(TYPE_MIN, TYPE_MAX)
    elif r < 0.7:
        type_id = rng.choice([TYPE_COLOR, TYPE_US, TYPE_GYRO, TYPE_IR, 77, 71, 76])
    else:
        type_id = rng.choice([TYPE_MIN, TYPE_MAX, 88, 2, 100, rng.randint(TYPE_MIN, TYPE_MAX)])
    num_modes = rng.choice([1, 8, 8, rng.randint(1, 8), rng.randint(1, 8)])
    # Now and then every mode at its maximum: 8 modes of 32 s8 values.
    maximal = rng.random() < 0.05
    if maximal:
        num_modes = 8
    # A Powered Up device with more than 8 modes: the 4-byte MODES, modes 8
    # and up described with the MODE_PLUS_8 flag, NAME flags now and then.
    many = not maximal and rng.random() < 0.15
    if many:
        num_modes = rng.choice([9, 16, rng.randint(9, 16)])
    units = rng.choice(sorted(IIO_UNITS)) if maximal and rng.random() < 0.5 else None
    modes = [GenMode(rng, type_id, bad_prob, maximal, units) for _ in range(num_modes)]
    out = b''
    if rng.random() < 0.05:
        # Garbage before the TYPE: the parser hunts for a TYPE message.
        out += bytes(rng.randrange(256) for _ in range(rng.randint(1, 40)))
    out += _cmd(es.CMD_TYPE, bytes([type_id]))
    form = rng.random()
    views = rng.choice([num_modes, 1, rng.randint(1, num_modes), 8, 255])
    if many:
        out += _cmd(es.CMD_MODES, bytes([7, min(views, 8) - 1 & 0xff, num_modes - 1,
                                         views - 1 & 0xff]))
    elif num_modes == 1 and form < 0.3:
        pass                                                     # MODES left out
    elif form < 0.45:
        out += _cmd(es.CMD_MODES, bytes([num_modes - 1]))        # no views byte
    elif form < 0.9:
        out += _cmd(es.CMD_MODES, bytes([num_modes - 1, views - 1 & 0xff]))
    else:
        # Powered Up: modes and views, then the counts for modes 8 and up.
        out += _cmd(es.CMD_MODES, bytes([num_modes - 1, views - 1 & 0xff,
                                         rng.randrange(16), rng.randrange(16)]))
    if rng.random() < 0.8:
        if transport == 'pty' and rng.random() < 0.3:
            speed = rng.choice([SPEED_MIN, SPEED_MAX, rng.randint(SPEED_MIN, SPEED_MAX)])
        else:
            speed = rng.choice(sorted(es.BAUD))
        out += _cmd(es.CMD_SPEED, struct.pack('<I', speed))
    if rng.random() < (0.8 if many else 0.1):
        out += _cmd(CMD_VERSION, bytes(rng.randrange(256) for _ in range(8)))
    order = list(reversed(range(num_modes)))
    if rng.random() < 0.1:
        rng.shuffle(order)
    filler = rng.random() < 0.1
    for i in order:
        m = modes[i]
        # Modes 8 and up: the header holds the low 3 bits, the flag the rest.
        low, p8 = i & 7, INFO_MODE_PLUS_8 if i >= 8 else 0
        if rng.random() < 0.03:
            out += _cmd(CMD_EXT_MODE, bytes([rng.choice([0, 8])]))
        name = _str_payload(m.name, m.name_size, rng, m.junk_after_name)
        if many and len(m.name) <= SHORT_NAME_LEN and rng.random() < 0.5:
            # Powered Up capability flags after a short name.
            name = _str_payload(m.name, 6) + bytes(rng.randrange(256) for _ in range(6)) + \
                bytes(4)
        out += _info(low, es.INFO_NAME | p8, name)
        for what in m.order:
            if what == 'units':
                if m.units is not None:
                    out += _info(low, es.INFO_UNITS | p8, _str_payload(m.units, m.units_size))
            elif m.ranges[what] is not None:
                lo, hi = m.ranges[what]
                itype = {'raw': es.INFO_RAW, 'pct': es.INFO_PCT, 'si': es.INFO_SI}[what]
                out += _info(low, itype | p8,
                             struct.pack('<II', lo, hi) + bytes(m.range_size - 8))
            if filler and rng.random() < 0.3:
                out += rng.choice([b'\x00', b'\x02', b'\xff', b'\x00\xff'])
        for itype, payload in m.pup:
            if itype & INFO_MODE_PLUS_8 and (i & 7) + 8 >= num_modes and rng.random() < 0.8:
                continue        # mostly not for a mode it lacks (fatal but for 5-12)
            out += _info(low, itype, payload)
        if many and rng.random() < 0.5:
            out += _info(low, 0x05 | p8, bytes(rng.randrange(256) for _ in range(2)))
        out += _info(low, es.INFO_FORMAT | p8, bytes([m.n, m.t, m.fig, m.dec]) +
                     bytes(m.format_size - 4))
    if many and rng.random() < 0.5:
        out += _info(0, 0x06, bytes(rng.randrange(256) for _ in range(rng.choice([2, 4, 8]))))
    return out + bytes([es.SYS_ACK])


# ---- mutations of real (and generated) handshakes, checksums repaired ----------

def split_messages(data):
    """The messages of a byte stream, framed as the parser frames them."""
    out, i = [], 0
    while i < len(data):
        n = msg_len(data[i]) if data[i] != 0xff else 1
        out.append(bytearray(data[i:i + n]))
        i += n
    return out


def repair(msg):
    """Fix a message's length to its header and its checksum."""
    if msg[0] & 0xc0 == 0 or msg[0] == 0xff:
        return bytes(msg[:1])
    want = msg_len(msg[0])
    body = bytes(msg[:want - 1]).ljust(want - 1, b'\0')
    return body + bytes([es.checksum(body)])


def mutate_handshake(rng, data):
    msgs = split_messages(data)
    for _ in range(rng.randint(1, 3)):
        i = rng.randrange(len(msgs))
        m = msgs[i]
        op = rng.randrange(10)
        if op == 0 and len(m) > 2:               # flip a bit of the body
            j = rng.randrange(1, len(m) - 1)
            m[j] ^= 1 << rng.randrange(8)
        elif op == 1 and len(m) > 2:             # a body byte to an extreme
            j = rng.randrange(1, len(m) - 1)
            m[j] = rng.choice([0, 1, 0x7f, 0x80, 0xff, 8, 9, 15, 16, 32, 33, 101, 102])
        elif op == 2 and m[0] & 0xc0:            # another mode
            m[0] = m[0] & ~7 & 0xff | rng.randrange(8)
        elif op == 3 and m[0] & 0xc0:            # another payload size
            m[0] = m[0] & ~0x38 & 0xff | rng.randrange(6) << 3
        elif op == 4 and m[0] & 0xc0 == 0x80:    # another info type
            m[1] = rng.choice([0, 1, 2, 3, 4, 5, 0x0c, 0x0d, 0x20, 0x24, 0x80, 0x81, 0xa0])
        elif op == 5:                            # duplicate
            msgs.insert(i, bytearray(m))
        elif op == 6 and len(msgs) > 2:          # drop
            del msgs[i]
        elif op == 7 and len(msgs) > 2:          # swap with a neighbour
            j = min(i + 1, len(msgs) - 1)
            msgs[i], msgs[j] = msgs[j], msgs[i]
        elif op == 8 and m[0] & 0xc0 == 0x80 and m[1] in (1, 2, 3) and len(m) >= 11:
            kind = rng.choice(['nan', 'inf', 'tiny', 'huge', 'normal', 'bits'])
            struct.pack_into('<I', m, 2 + 4 * rng.randrange(2), gen_float(rng, kind))
        elif op == 9 and m[0] & 0xc0 == 0x80 and m[1] == 0x80:   # FORMAT field extremes
            j = 2 + rng.randrange(4)
            m[j] = rng.choice([0, 1, 3, 4, 8, 9, 10, 15, 16, 32, 33, 255])
        msgs = [bytearray(repair(x)) for x in msgs]
    return b''.join(bytes(x) for x in msgs)


def real_handshakes():
    return [(k, es.handshake(s)) for k, s in sorted(es.SENSORS.items())]


# ---- cases ------------------------------------------------------------------------

class Case:
    """One case: the bytes the sensor sends, what the model makes of them,
    and the values the sensor sends per mode in its data phase."""

    def __init__(self, seed, kind, data, desc, reasons, values, origin):
        self.seed, self.kind, self.data = seed, kind, data
        self.desc, self.reasons = desc, reasons
        self.values, self.origin = values, origin
        self.bugs = known_bugs(desc)
        self.rude = rude(seed)

    def describe(self):
        lines = ['seed %d: %s (%s), %d bytes' % (self.seed, self.kind, self.origin,
                                                len(self.data))]
        if self.desc:
            lines.append('model: registers as %s: %r' % (self.desc.driver, self.desc))
            lines.append('IIO channels (current driver): %d' % iio_channels(self.desc))
        else:
            lines.append('model: refused: %s' % '; '.join(self.reasons))
        if self.bugs:
            lines.append('known bugs: %s' % ', '.join(self.bugs))
        if self.rude:
            lines.append('rude sensor: %s' % ', '.join(self.rude))
        lines.append('bytes: ' + self.data.hex())
        return '\n'.join(lines)


# The share of cases whose sensor is rude (ev3_sensor's rude option: old-mode
# DATA during a SELECT, the glitch at the baud switch, unflagged garbage).
RUDE_SHARE = 0.3


def rude(seed):
    """The rude behaviours of the case of `seed` (all or none), drawn
    apart from the case's bytes, which stay what they were."""
    return es.RUDE_ALL if random.Random(seed ^ 0x7275de).random() < RUDE_SHARE else ()


def gen_values(rng, m):
    """Values a mode sends: extremes of its data type, or random."""
    if m.t == es.FLOAT:
        pool = [0.0, -0.0, 1.0, -1.5, 3.25, 1e-9, 1e9, -1e9, 2.5e9, 1e38, math.inf,
                -math.inf, math.nan]
        return [rng.choice(pool) if rng.random() < 0.6 else rng.uniform(-1e4, 1e4)
                for _ in range(m.n)]
    bits = 8 * SIZE[m.t]
    lo, hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return [rng.choice([lo, hi, 0, -1, 1, rng.randint(lo, hi)]) for _ in range(m.n)]


def case(seed, transport='pty', known='avoid'):
    """The case of `seed`. transport 'nullmodem' keeps to the speeds a tty
    has a constant for; known: 'avoid' (re-draw until no known bug is hit),
    'only' (re-draw until one is) or 'include'."""
    rng = random.Random(seed)
    for _ in range(10000):
        r = rng.random()
        if r < 0.75 or known == 'only':
            kind, origin = 'generated', 'generated'
            data = gen_sensor(rng, transport, bad_prob=0.01 if rng.random() < 0.5 else 0)
        else:
            kind = 'mutated'
            if rng.random() < 0.7:
                origin, base = rng.choice(real_handshakes())
            else:
                origin, base = 'generated', gen_sensor(rng, transport)
            data = mutate_handshake(rng, base)
        desc, reasons = parse(data)
        if desc and transport == 'nullmodem' and desc.speed not in es.BAUD:
            continue
        bugs = known_bugs(desc)
        if known == 'avoid' and bugs or known == 'only' and not bugs:
            continue
        values = {}
        if desc:
            values = {i: gen_values(rng, desc.modes[i]) for i in range(desc.num_modes)}
        return Case(seed, kind, data, desc, reasons, values, origin)
    raise RuntimeError('seed %d: no case after 10000 draws' % seed)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split('\n', 1)[1])
    ap.add_argument('--seed', type=int)
    ap.add_argument('--transport', choices=['pty', 'nullmodem'], default='pty')
    ap.add_argument('--known', choices=['avoid', 'include', 'only'], default='avoid')
    ap.add_argument('--find', metavar='BUG')
    ap.add_argument('--start', type=int, default=1)
    ap.add_argument('--limit', type=int, default=5)
    ap.add_argument('--stats', type=int, metavar='N')
    args = ap.parse_args()
    if args.seed is not None:
        print(case(args.seed, args.transport, args.known).describe())
    elif args.find:
        found = 0
        s = args.start
        while found < args.limit:
            c = case(s, args.transport, 'include')
            if c.bugs and (args.find == 'any' or args.find in c.bugs):
                print('seed %d: %s' % (s, ', '.join(c.bugs)))
                found += 1
            s += 1
    elif args.stats:
        counts = {}
        for s in range(args.start, args.start + args.stats):
            c = case(s, args.transport, args.known)
            for k in [c.kind, 'registers' if c.desc else 'refused'] + c.bugs + \
                    ([('refused: ' + c.reasons[-1])] if not c.desc else []):
                counts[k] = counts.get(k, 0) + 1
        for k in sorted(counts, key=lambda k: -counts[k]):
            print('%6d  %s' % (counts[k], k))
    else:
        ap.print_help()
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
