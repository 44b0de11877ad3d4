"""Emulated LEGO MINDSTORMS EV3 UART sensors.

Each emulator plays one sensor on the sensor end of a serial line (in the
tests: the far end of a lego_nullmodem pair, which paces bytes at the baud
rate each end has set and garbles bytes sent at the wrong speed). It behaves
like the real sensors described in shared/research (uart-peers.md,
ev3dev.md):

- reset: a line break (the real sensor holds TX low ~500 ms), then the whole
  handshake back to back at 2400 baud, byte for byte as the real sensors send
  it (names padded to 8 or 16 bytes, 8-byte ranges and units, 4-byte FORMAT,
  modes from highest to lowest, ACK last);
- waits 80 ms for the host's ACK, else starts over (80 ms of the time the
  emulator was able to watch the line: see wait_ack());
- data phase at 57600 baud: answers every NACK with a DATA message, sends on
  its own at the sensor's cadence (on change, or continuously), resets when
  no NACK came for a second;
- SELECT switches mode after the sensor's own delay; WRITE 0x11 resets the
  gyro angle; the gyro goes on in the old mode until it has switched (see
  'old-mode' below: real gyros send an old-mode DATA message just after a
  SELECT, and the new mode's first 10 to 15 ms later, uart-peers.md 3.4);
- Powered Up devices take values for a mode that takes them (MAPPING out
  flags: a light's brightness) as EXT_MODE + DATA, in the mode they are in
  (Pybricks sends them only then), and then send those values in that
  mode's DATA; values for another mode are ignored (lump_writes has them
  all, lump_write_modes the mode the device was in). A WRITE of
  0x20 + n, a combination index and n mode/value bytes sets up a combined
  mode, if the device offers that combination (MODE_COMBOS): the device
  answers with the same WRITE, then sends the values one after the other
  in DATA messages with the header of the mode it is in, continuously,
  until a SELECT ends it (recorded from a Technic Large motor: Pybricks,
  lib/pbio/test/src/uartdev.c before commit ae927acbd);
- Powered Up devices that can (the SPIKE colour and distance sensors, not
  the BOOST colour and distance sensor) listen at 115200 baud while they
  hold TX low after a reset, and answer the host's fast sync probe (SPEED
  115200 sent at 115200) with ACK, then send their handshake at 115200;
  without a probe they go on at 2400 like the others;
- quirks: the colour sensor's RGB-RAW frames with a wrong checksum and a
  fourth value, the infrared sensor's "00 ff" in its handshake and its stale
  values for ~1.1 s after a mode switch, the ultrasonic sensor's US-DC-IN
  frames tagged mode 5, modes that stop answering keep-alives (COL-CAL,
  IR-S-ALT, IR-CAL) and so make the host drop the sensor.

The `hostile` option sends garbage, truncated and oversized messages, bad
checksums and absurd handshake values before a valid handshake.

The `rude` option (off by default, so that tests that measure something
else precisely keep a polite sensor) adds what real sensors do on a real
wire and a host must survive (shared/research/uart-peers.md 1.7, 3.2, 3.4;
ev3dev.md 1.9), each on its own or all of them (rude=True):

- 'old-mode': while a SELECT is being carried out the sensor goes on in the
  old mode: one DATA message of the old mode right after the SELECT (one
  that was on its way, as seen with the gyro), then the old mode's cadence
  and NACK replies until the switch; the new mode's first message is a
  spontaneous one (the ultrasonic sensor's US-DC-IN: tagged mode 5);
- 'glitch': one byte, 0xfe, 0xfc or 0xff, at the new speed right after the
  switch to the data phase's speed (the glitch frame the JV captures show
  at the baud switch);
- 'garbage': bursts of random bytes, any value, at the line's speed (so
  the host's UART flags none of them): a few before the handshake's TYPE,
  and 1 to 3 before about one DATA message in 20. A burst never holds a
  message the host could take (a TYPE, or a DATA or EXT_MODE message with a
  right checksum, or the RGB-RAW header of type 29, which hosts do not check), nor one
  that would run past the message it precedes: an XOR checksum lets one
  such message in 65536 through on any host, and a test could not tell it
  from a driver's bug. No 0x04 before the handshake either: on a line that
  carries no speed (a pty) the host's fast sync probe would take it for a
  Powered Up device's ACK, which no EV3 sensor sends.

Two test aids go beyond a real sensor:

- stream(): in the data phase, one write of a long run of DATA frames of the
  current mode whose first value counts up by one per frame. The tty driver
  underneath paces them (the null modem at the baud rate: 4-byte frames at
  57600 baud are 1440 a second), however slowly Python runs, so the host's
  every-sample path can be tested at the sensor's real rate.
- host_tty: on a line that carries no baud rate (two QEMU UARTs joined by a
  socket), the emulator watches the speed of the host's end with tcgetattr
  and garbles what it sends while the two speeds differ, as a wire would.
  A socket cannot carry framing errors, so the garbage is made of 0x00 and
  0xff bytes only, which can never form a message.
"""
import errno
import fcntl
import math
import os
import random
import select
import struct
import sys
import termios
import threading
import time

SYS_SYNC, SYS_NACK, SYS_ACK = 0x00, 0x02, 0x04
CMD_TYPE, CMD_MODES, CMD_SPEED, CMD_SELECT, CMD_WRITE = 0, 1, 2, 3, 4
CMD_EXT_MODE, CMD_VERSION = 6, 7                       # Powered Up only
INFO_NAME, INFO_RAW, INFO_PCT, INFO_SI, INFO_UNITS, INFO_FORMAT = 0, 1, 2, 3, 4, 0x80
INFO_MAPPING, INFO_MODE_COMBOS, INFO_MODE_PLUS_8 = 0x05, 0x06, 0x20  # Powered Up only
S8, S16, S32, FLOAT = 0, 1, 2, 3

BAUD = {2400: termios.B2400, 9600: termios.B9600, 19200: termios.B19200,
        38400: termios.B38400, 57600: termios.B57600, 115200: termios.B115200,
        230400: termios.B230400, 460800: termios.B460800}
SPEED_OF = {v: k for k, v in BAUD.items()}
FAST = 115200
# The host's fast sync probe, SPEED 115200 (sent at 115200).
PROBE = bytes([0x52, 0x00, 0xc2, 0x01, 0x00, 0x6e])
# Line break on and off (asm-generic/ioctls.h; Python's termios lacks them).
TIOCSBRK, TIOCCBRK = 0x5427, 0x5428


def checksum(data):
    c = 0xff
    for b in data:
        c ^= b
    return c


def size_code(n):
    code = 0
    while (1 << code) < n:
        code += 1
    return code


def pad(payload):
    size = 1 << size_code(len(payload))
    return bytes(payload) + bytes(size - len(payload))


def cmd_msg(cmd, payload):
    p = pad(payload)
    m = bytes([0x40 | size_code(len(p)) << 3 | cmd]) + p
    return m + bytes([checksum(m)])


def info_msg(mode, itype, payload):
    p = pad(payload)
    m = bytes([0x80 | size_code(len(p)) << 3 | mode, itype]) + p
    return m + bytes([checksum(m)])


def data_msg(mode, payload, bad_checksum=False):
    p = pad(payload)
    m = bytes([0xc0 | size_code(len(p)) << 3 | mode]) + p
    c = checksum(m)
    return m + bytes([c ^ 0x5a if bad_checksum else c])


def data_frame(sdef, mode, payload, bad_checksum=False):
    """A DATA message of `mode` as the device sends it: a Powered Up device
    puts an EXT_MODE message (0 or 8) before every one, and the header
    carries the mode's low 3 bits."""
    ext = b''
    if getattr(sdef, 'lump', False):
        ext = cmd_msg(CMD_EXT_MODE, [mode & 8])
    return ext + data_msg(mode & 7, payload, bad_checksum)


def f32(x):
    return struct.pack('<f', x)


class Mode:
    """One mode: what the sensor says about it and how it sends data."""

    def __init__(self, name, raw, si, units, n, t, fig, dec, cadence='change',
                 period=0.1, first_reply=0.002, deaf=False, pct=None, mapping=None,
                 flags=None):
        """Powered Up modes only: pct, the PCT range sent (else none);
        mapping, the (in, out) flags of the MAPPING INFO (out non-zero: the
        host may write values); flags, the 6 capability bytes sent after a
        short NAME."""
        self.name, self.raw, self.si, self.units = name, raw, si, units
        self.pct, self.mapping, self.flags = pct, mapping, flags
        self.n, self.t, self.fig, self.dec = n, t, fig, dec
        self.cadence = cadence          # 'change', 'continuous' or 'nack'
        self.period = period            # seconds between spontaneous frames
        self.first_reply = first_reply  # SELECT to the first new-mode frame
        self.deaf = deaf                # stops answering keep-alives


class SensorDef:
    """raw_handshake: bytes to send as the handshake instead of the one
    handshake() builds (e.g. a generated one, tests/emulator/ev3_gen.py);
    quirks=False: none of the real sensors' quirks in the data phase."""

    def __init__(self, type_id, driver, views, modes, speed=57600, raw_handshake=None,
                 quirks=True, lump=False, version=None, combos=(), fast_sync=False,
                 old_mode=False):
        """lump: a Powered Up device (LUMP): the handshake in its form
        (see handshake()), and an EXT_MODE message before every DATA
        message; version: (firmware, hardware) for the VERSION message;
        combos: the MODE_COMBOS bitmaps sent after mode 0's FORMAT;
        fast_sync: answers the host's SPEED 115200 probe (see
        EmulatedSensor.listen_for_probe()); old_mode: goes on in the old
        mode while it carries out a SELECT, as the `rude` option's
        'old-mode' (a quirk: not with quirks=False)."""
        self.type, self.driver, self.views = type_id, driver, views
        self.modes, self.speed = modes, speed
        self.raw_handshake, self.quirks = raw_handshake, quirks
        self.lump, self.version, self.combos = lump, version, combos
        self.fast_sync = fast_sync
        self.old_mode = old_mode


COLOR = SensorDef(29, 'lego-ev3-color', 3, [
    Mode('COL-REFLECT', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
    Mode('COL-AMBIENT', (0, 100), (0, 100), 'pct', 1, S8, 3, 0),
    Mode('COL-COLOR', (0, 8), (0, 8), 'col', 1, S8, 2, 0),
    Mode('REF-RAW', (0, 1020.1875), (0, 1020.1875), None, 2, S16, 4, 0,
         cadence='continuous', period=0.003),
    Mode('RGB-RAW', (0, 1020.1875), (0, 1020.1875), None, 3, S16, 4, 0,
         cadence='continuous', period=0.005),
    Mode('COL-CAL', (0, 65535), (0, 65535), None, 4, S16, 5, 0, cadence='nack', deaf=True),
])

US = SensorDef(30, 'lego-ev3-us', 3, [
    Mode('US-DIST-CM', (0, 2550), (0, 255), 'cm', 1, S16, 5, 1, 'continuous', 0.022, 0.002),
    Mode('US-DIST-IN', (0, 1000), (0, 100), 'inch', 1, S16, 5, 1, 'continuous', 0.022, 0.002),
    Mode('US-LISTEN', (0, 1), (0, 1), None, 1, S8, 1, 0, 'nack'),
    Mode('US-SI-CM', (0, 2550), (0, 255), 'cm', 1, S16, 5, 1, 'nack', first_reply=0.061),
    Mode('US-SI-IN', (0, 1000), (0, 100), 'inch', 1, S16, 5, 1, 'nack', first_reply=0.061),
    Mode('US-DC-CM', (0, 2550), (0, 255), 'cm', 1, S16, 5, 1, 'continuous', 0.022, 0.002),
    Mode('US-DC-IN', (0, 1000), (0, 100), 'inch', 1, S16, 5, 1, 'continuous', 0.022, 0.002),
])


def _gyro(new):
    rate = 500 if new else 440
    cal = (-32768, 32767) if new else (0, 65535)
    modes = [
        Mode('GYRO-ANG', (-180, 180), (-180, 180), 'deg', 1, S16, 4, 0,
             'continuous', 0.0015, 0.015),
        Mode('GYRO-RATE', (-rate, rate), (-rate, rate), 'd/s', 1, S16, 3, 0,
             'continuous', 0.0019, 0.015),
        Mode('GYRO-FAS', (-2000, 2000), (-2000, 2000), None, 1, S16, 4, 0,
             'continuous', 0.0028, 0.015),
        Mode('GYRO-G&A', (-180, 180), (-180, 180), None, 2, S16, 5, 0,
             'continuous', 0.0029, 0.015),
        Mode('GYRO-CAL', cal, cal, None, 4, S16, 5, 0, 'nack', first_reply=0.0013),
    ]
    if new:
        modes += [
            Mode('TILT-RATE', (-500, 500), (-500, 500), 'd/s', 1, S16, 3, 0,
                 'continuous', 0.0019, 0.015),
            Mode('TILT-ANG', (-180, 180), (-180, 180), 'deg', 1, S16, 3, 0,
                 'continuous', 0.0019, 0.015),
        ]
    # The one sensor seen sending its old mode after a SELECT (uart-peers.md 3.4).
    return SensorDef(32, 'lego-ev3-gyro', 2, modes, old_mode=True)


GYRO = _gyro(True)
GYRO_OLD = _gyro(False)

IR = SensorDef(33, 'lego-ev3-ir', 3, [
    Mode('IR-PROX', (0, 100), (0, 100), 'pct', 1, S8, 3, 0, first_reply=0.03),
    Mode('IR-SEEK', (-100, 100), (-100, 100), 'pct', 8, S8, 3, 0, first_reply=0.03),
    Mode('IR-REMOTE', (0, 10), (0, 10), 'btn', 4, S8, 3, 0, first_reply=0.03),
    Mode('IR-REM-A', (0, 65535), (0, 65535), None, 1, S16, 6, 0, first_reply=0.03),
    Mode('IR-S-ALT', (0, 100), (0, 100), 'pct', 4, S8, 3, 0, deaf=True),
    Mode('IR-CAL', (0, 65535), (0, 65535), None, 2, S16, 5, 0, deaf=True),
])

# A third-party sensor: FatcatLab's humidity sensor (type 77).
FCL_HUMIDITY = SensorDef(77, 'fcl-humidity', 3, [
    Mode('CENTIGRADE', (-400, 1250), (-40, 125), 'C', 1, S16, 4, 1),
    Mode('FAHRENHEIT', (-400, 2570), (-40, 257), 'F', 1, S16, 4, 1),
    Mode('HUMIDITY', (0, 1000), (0, 100), '%RH', 1, S16, 4, 1),
], speed=9600)

# Powered Up (LUMP) devices. The BOOST colour and distance sensor is
# byte for byte the handshake a logic analyser recorded (Pybricks'
# lib/pbio/test/src/test_lump.c; research/uart-peers.md): handshake(BOOST_CDS)
# gives exactly those bytes (tests/emulator/test_lump_defs.py checks it).
# The SPIKE colour and distance sensors: mode numbers, names, value counts
# and types, and which modes take values (MAPPING out) as Pybricks'
# lib/lego/lego/device.h gives them; their ranges, units, figures, version
# and capability flags are not recorded anywhere we know of and are ours.
_RW = (0x00, 0x04)      # MAPPING of a mode the host writes to (BOOST: COL O, IR Tx)

BOOST_CDS = SensorDef(37, 'lego-boost-color-dist', 8, [
    Mode('COLOR', (0, 10), (0, 10), 'IDX', 1, S8, 3, 0, pct=(0, 100), mapping=(0xc4, 0)),
    Mode('PROX', (0, 10), (0, 10), 'DIS', 1, S8, 3, 0, pct=(0, 100), mapping=(0x50, 0)),
    Mode('COUNT', (0, 100), (0, 100), 'CNT', 1, S32, 4, 0, pct=(0, 100), mapping=(0x08, 0)),
    Mode('REFLT', (0, 100), (0, 100), 'PCT', 1, S8, 3, 0, pct=(0, 100), mapping=(0x10, 0)),
    Mode('AMBI', (0, 100), (0, 100), 'PCT', 1, S8, 3, 0, pct=(0, 100), mapping=(0x10, 0)),
    Mode('COL O', (0, 10), (0, 10), 'IDX', 1, S8, 3, 0, pct=(0, 100), mapping=_RW),
    Mode('RGB I', (0, 1023), (0, 1023), 'RAW', 3, S16, 5, 0, pct=(0, 100), mapping=(0x10, 0),
         cadence='continuous', period=0.01, first_reply=0.03),
    Mode('IR Tx', (0, 65535), (0, 65535), 'N/A', 1, S16, 5, 0, pct=(0, 100), mapping=_RW),
    Mode('SPEC 1', (0, 255), (0, 255), 'N/A', 4, S8, 3, 0, pct=(0, 100), mapping=(0, 0),
         first_reply=0.03),
    Mode('DEBUG', (0, 1023), (0, 10), 'N/A', 2, S16, 5, 0, pct=(0, 100), mapping=(0x10, 0),
         first_reply=0.03),
    Mode('CALIB', (0, 65535), (0, 65535), 'N/A', 8, S16, 5, 0, pct=(0, 100),
         mapping=(0x10, 0), cadence='nack', first_reply=0.03),
], speed=115200, lump=True, version=(0x10000000, 0x10000000), combos=(0x004f,))

_NOFLAGS = bytes(6)


def _spike(name, units, n, t, rng=(0, 100), fig=4, writable=False, **kw):
    flags = _NOFLAGS if len(name) <= 5 else None
    return Mode(name, rng, rng, units, n, t, fig, 0, pct=(0, 100),
                mapping=_RW if writable else (0x10, 0), flags=flags, **kw)


SPIKE_COLOR = SensorDef(61, 'lego-spike-color', 8, [
    _spike('COLOR', 'IDX', 1, S8, (-1, 10)),
    _spike('REFLT', 'PCT', 1, S8),
    _spike('AMBI', 'PCT', 1, S8),
    _spike('LIGHT', 'PCT', 3, S8, writable=True),
    _spike('RREFL', 'RAW', 2, S16, (0, 1024)),
    _spike('RGB I', 'RAW', 4, S16, (0, 1024), cadence='continuous', period=0.01,
           first_reply=0.03),
    _spike('HSV', 'RAW', 3, S16, (0, 360)),
    _spike('SHSV', 'RAW', 4, S16, (0, 360)),
    _spike('DEBUG', 'RAW', 2, S16, (0, 1023)),
    _spike('CALIB', 'RAW', 7, S16, (0, 65535), cadence='nack'),
], speed=115200, lump=True, version=(0x10000000, 0x10000000), combos=(0x00e3,),
    fast_sync=True)

SPIKE_DIST = SensorDef(62, 'lego-spike-ultrasonic', 8, [
    _spike('DISTL', 'cm', 1, S16, (0, 250), fig=5, cadence='continuous', period=0.03),
    _spike('DISTS', 'cm', 1, S16, (0, 32), fig=4, cadence='continuous', period=0.03),
    _spike('SINGL', 'cm', 1, S16, (0, 250), fig=5, cadence='nack', first_reply=0.05),
    _spike('LISTN', 'ST', 1, S8, (0, 1), fig=1),
    _spike('TRAW', 'UC', 1, S32, (0, 14577), fig=5),
    _spike('LIGHT', 'PCT', 4, S8, writable=True),
    _spike('PING', 'PCT', 1, S8, (0, 1), fig=1),
    _spike('ADRAW', 'PCT', 1, S16, (0, 1024), fig=4),
    _spike('CALIB', 'PCT', 7, S16, (0, 65535), fig=5, cadence='nack'),
], speed=115200, lump=True, version=(0x10000000, 0x10000000), fast_sync=True)

# The Technic Large motor (type 46): the handshake a logic analyser recorded
# (Pybricks, lib/pbio/test/src/uartdev.c before commit ae927acbd, "info
# messages captured from Technic Large Linear Motor"), sent as it is; the
# modes below are what it says (tests/emulator/test_lump_defs.py checks).
TECHNIC_L_RECORDED = bytes.fromhex(
    '402e91490503b05200c201006e5f0400000000000010b4a50053544154530000'
    '0000000504000000001a9d010000000000ff7f47a49d02000000000000c842ea'
    '9d030000000000ff7f47a695044d494e00248d0500007795800e010500e0a400'
    '43414c494200224000000504000000007d9c010000000000006145469c020000'
    '00000000c842eb9c03000000000000614544940443414c00218c050000769480'
    '02010500eda30041504f53000022000000050400000000729b01000034c30000'
    '3343e29b02000048c300004843e69b03000034c300003343e09304444547002e'
    '8b05323271938001010300efa200504f5300000024000000050400000000349a'
    '010000b4c30000b443e49a020000c8c20000c842e79a030000b4c30000b443e6'
    '9204444547002f8a05286830928001020b00e5a1005350454544002100000005'
    '04000000003999010000c8c20000c842e799020000c8c20000c842e499030000'
    'c8c20000c842e59104504354002d8905307033918001000400eba000504f5745'
    '5200300000000504000000003198010000c8c20000c842e698020000c8c20000'
    'c842e598030000c8c20000c842e49004504354002c8805005022908001000400'
    'ea88060e007fa0080040002e0947383336363630000000007aa00988130000fa'
    '00000010270000be050000bba00a983a000096000000983a000000000000c398'
    '0b00000000000000006c900c000000006304')

TECHNIC_L = SensorDef(46, 'lego-technic-l-motor', 4, [
    Mode('POWER', (-100, 100), (-100, 100), 'PCT', 1, S8, 4, 0, pct=(-100, 100),
         mapping=(0x00, 0x50)),
    Mode('SPEED', (-100, 100), (-100, 100), 'PCT', 1, S8, 4, 0, pct=(-100, 100),
         mapping=(0x30, 0x70), cadence='continuous', period=0.02),
    Mode('POS', (-360, 360), (-360, 360), 'DEG', 1, S32, 11, 0, pct=(-100, 100),
         mapping=(0x28, 0x68), cadence='continuous', period=0.02),
    Mode('APOS', (-180, 179), (-180, 179), 'DEG', 1, S16, 3, 0, pct=(-200, 200),
         mapping=(0x32, 0x32), cadence='continuous', period=0.02),
    Mode('CALIB', (0, 3600), (0, 3600), 'CAL', 2, S16, 5, 0, pct=(0, 100), mapping=(0, 0)),
    Mode('STATS', (0, 65535), (0, 65535), 'MIN', 14, S16, 5, 0, pct=(0, 100), mapping=(0, 0)),
], speed=115200, raw_handshake=TECHNIC_L_RECORDED, lump=True, combos=(0x000e,))

SENSORS = {'color': COLOR, 'us': US, 'gyro': GYRO, 'gyro-old': GYRO_OLD, 'ir': IR,
           'fcl-humidity': FCL_HUMIDITY, 'boost-cds': BOOST_CDS, 'spike-color': SPIKE_COLOR,
           'spike-dist': SPIKE_DIST, 'technic-l': TECHNIC_L}

IR_STALE_TIME = 1.1
# A combined mode's DATA messages come continuously, this often.
COMBO_PERIOD = 0.01
# The `rude` option's behaviours (see the top of the file).
RUDE_OLD_MODE, RUDE_GLITCH, RUDE_GARBAGE = 'old-mode', 'glitch', 'garbage'
RUDE_ALL = (RUDE_OLD_MODE, RUDE_GLITCH, RUDE_GARBAGE)
# What the host reads when the sensor's UART is reprogrammed (uart-peers.md 1.7).
GLITCH_BYTES = (0xfe, 0xfc, 0xff)
# Data phase garbage: a burst before this share of DATA messages, of 1 to
# GARBAGE_MAX bytes; before a handshake, 1 to GARBAGE_SYNC_MAX bytes.
GARBAGE_SHARE = 0.05
GARBAGE_MAX = 3
GARBAGE_SYNC_MAX = 6
# Bytes written at a time when the emulator paces a line itself (pace=True).
PACE_CHUNK = 4
# The host's ACK must come within ACK_WAIT of the handshake's end; the
# emulator watches for it in waits of ACK_SLICE (see wait_ack()).
ACK_WAIT = 0.080
ACK_SLICE = 0.005


def lump_handshake(s):
    """A Powered Up device's handshake, in the shape the BOOST colour and
    distance sensor sends it: the 4-byte MODES when it has more than 8 modes
    (the first two bytes for EV3 hosts), VERSION after SPEED, modes 8 and up
    with the MODE_PLUS_8 flag, names and units padded to a power of two
    (4 characters: no NUL), or a short name, NUL and 6 flag bytes in 16;
    RAW, PCT, SI, UNITS, MAPPING, FORMAT per mode; MODE_COMBOS after mode
    0's FORMAT."""
    nm, views = len(s.modes), s.views
    out = cmd_msg(CMD_TYPE, [s.type])
    if nm > 8:
        out += cmd_msg(CMD_MODES, [7, min(views, 8) - 1, nm - 1, views - 1])
    else:
        out += cmd_msg(CMD_MODES, [nm - 1, views - 1])
    out += cmd_msg(CMD_SPEED, struct.pack('<I', s.speed))
    if s.version:
        out += cmd_msg(CMD_VERSION, struct.pack('<II', *s.version))
    for i in reversed(range(nm)):
        m = s.modes[i]
        low, plus8 = i & 7, INFO_MODE_PLUS_8 if i >= 8 else 0
        name = m.name.encode()
        if m.flags is not None:
            name = name.ljust(6, b'\0') + bytes(m.flags)
        out += info_msg(low, INFO_NAME | plus8, name)
        out += info_msg(low, INFO_RAW | plus8, f32(m.raw[0]) + f32(m.raw[1]))
        if m.pct:
            out += info_msg(low, INFO_PCT | plus8, f32(m.pct[0]) + f32(m.pct[1]))
        out += info_msg(low, INFO_SI | plus8, f32(m.si[0]) + f32(m.si[1]))
        if m.units:
            out += info_msg(low, INFO_UNITS | plus8, m.units.encode() + b'\0')
        if m.mapping:
            out += info_msg(low, INFO_MAPPING | plus8, bytes(m.mapping))
        out += info_msg(low, INFO_FORMAT | plus8, [m.n, m.t, m.fig, m.dec])
    if s.combos:
        out += info_msg(0, INFO_MODE_COMBOS, struct.pack('<%dH' % len(s.combos), *s.combos))
    return out + bytes([SYS_ACK])


def handshake(s):
    """The bytes a real sensor sends from TYPE to its ACK."""
    if getattr(s, 'raw_handshake', None) is not None:
        return s.raw_handshake
    if getattr(s, 'lump', False):
        return lump_handshake(s)
    out = cmd_msg(CMD_TYPE, [s.type])
    out += cmd_msg(CMD_MODES, [len(s.modes) - 1, s.views - 1])
    out += cmd_msg(CMD_SPEED, struct.pack('<I', s.speed))
    for i in reversed(range(len(s.modes))):
        m = s.modes[i]
        name = m.name.encode()
        # Up to 7 characters + NUL in 8 bytes, exactly 8 with no NUL, else 16.
        out += info_msg(i, INFO_NAME, name + bytes(8 - len(name) if len(name) <= 8 else 16 - len(name)))
        out += info_msg(i, INFO_RAW, f32(m.raw[0]) + f32(m.raw[1]))
        out += info_msg(i, INFO_SI, f32(m.si[0]) + f32(m.si[1]))
        if m.units:
            out += info_msg(i, INFO_UNITS, m.units.encode().ljust(8, b'\0'))
        elif s.type == 33:
            out += bytes([SYS_SYNC, 0xff])  # the IR sensor's quirk
        out += info_msg(i, INFO_FORMAT, [m.n, m.t, m.fig, m.dec])
    return out + bytes([SYS_ACK])


def pack_values(mode, values):
    fmt = {S8: 'b', S16: 'h', S32: 'i', FLOAT: 'f'}[mode.t]
    return struct.pack('<%d%s' % (len(values), fmt), *values)


def wrap_value(mode, v):
    """v as the mode's data type holds it (counters wrap around)."""
    if mode.t == FLOAT:
        return float(v)
    bits = {S8: 8, S16: 16, S32: 32}[mode.t]
    v &= (1 << bits) - 1
    return v - (1 << bits) if v >> (bits - 1) else v


def garble(data, wbaud, rbaud, rng):
    """What a reader at `rbaud` makes of `data` sent at `wbaud`: a faster
    writer's bytes mostly vanish into the reader's longer bit times (about
    one 0xff per `wbaud / rbaud` bytes); a slower writer's zero bits each
    read as a 0x00 frame. Only 0x00 and 0xff, so never a valid message."""
    out = bytearray()
    if wbaud > rbaud:
        ratio = -(-wbaud // rbaud)
        for _ in data:
            if rng.randrange(ratio) == 0:
                out.append(0xff)
    else:
        for b in data:
            bits = [0] + [(b >> k) & 1 for k in range(8)]   # start bit, LSB first
            out += bytes(sum(1 for k, x in enumerate(bits) if not x and (k == 0 or bits[k - 1])))
    return bytes(out)


class EmulatedSensor(threading.Thread):
    """Plays one sensor on the tty at `path` (or an open tty's fd) until
    stop() is called."""

    def __init__(self, path, kind, hostile=False, seed=1, boot_delay=0.5, period_scale=1.0,
                 host_tty=None, retry_delay=None, fast_sync=None, pace=False, gate=None,
                 flaky=False, ignore_select=False, rude=None, old_mode=None):
        """period_scale > 1 slows the spontaneous cadence of continuous modes
        (NACK replies stay immediate): several emulators in one Python
        process inside an emulated machine cannot all keep real cadences
        and still answer every keep-alive in time.

        host_tty: the host's end of a line that carries no baud rate (a
        socket between two UARTs); what is sent is garbled while the host
        end's speed differs from ours.

        fast_sync: False makes a device that answers the fast sync probe
        ignore it (None: as its definition says).

        pace: on a line that paces nothing (a pty), write at the pace of
        the speed we are at, PACE_CHUNK bytes at a time on the wire's
        schedule, and return from send() when the last byte would have
        left, as tcdrain() does on a UART.

        ignore_select: SELECT messages are not carried out (the host's mode
        changes are never confirmed).

        flaky: a broken device (set or cleared at any time): after each
        handshake that the host answers, one good DATA message and seven
        with a bad checksum, then a reset.

        gate: a function called once, in the emulator's thread, right
        before the first handshake's first byte (or, for a device that
        syncs fast, before it first listens for the probe), after the
        reset: a test can so attach the host and have the sensor talk
        within the same millisecond.

        rude: True for all of RUDE_ALL, or some of their names (see the top
        of the file); None or () for a polite sensor.

        old_mode: False makes a sensor whose definition says it goes on in
        the old mode during a SELECT (the gyro) switch at once and be quiet
        meanwhile, True makes any sensor go on (as rude='old-mode'); None:
        as its definition says."""
        super().__init__(daemon=True)
        if rude is True:
            rude = RUDE_ALL
        elif isinstance(rude, str):
            rude = (rude,)
        self.rude = frozenset(rude or ())
        if not self.rude <= set(RUDE_ALL):
            raise ValueError('rude: %s' % ', '.join(sorted(self.rude - set(RUDE_ALL))))
        self.old_mode_frames = 0    # old-mode frames sent while a SELECT was pending
        self.glitches = 0           # (rude) glitch bytes sent at the baud switch
        self.garbage_bytes = 0      # (rude) random bytes sent in the data phase
        self.sync_garbage_bytes = 0     # (rude) and before handshakes
        self.rude_rng = random.Random(seed ^ 0x7275de)
        self.host_tty = host_tty
        self.host_fd = None
        self.speed = 0
        self.garbled = 0            # bytes sent while the speeds differed
        self.stream_req = None
        self.period_scale = period_scale
        self.sdef = SENSORS[kind] if isinstance(kind, str) else kind
        self.fast_sync = getattr(self.sdef, 'fast_sync', False) if fast_sync is None \
            else fast_sync
        if old_mode is None:
            old_mode = RUDE_OLD_MODE in self.rude or \
                (getattr(self.sdef, 'old_mode', False) and getattr(self.sdef, 'quirks', True))
        self.old_mode = old_mode
        self.pace = pace
        self.flaky = flaky
        self.ignore_select = ignore_select
        self.flaky_resets = 0
        self.gate = gate
        self.handshake_starts = []  # monotonic time of each handshake's first byte
        self.sync_speeds = []       # the speed of each handshake sent
        self.fast_syncs = 0         # probes answered
        self.path, self.hostile, self.boot_delay = path, hostile, boot_delay
        self.retry_delay = retry_delay  # boot delay after an unanswered handshake
        self.attempts = 0
        self.rng = random.Random(seed)
        self.lock = threading.Lock()
        self.values = {i: [0] * m.n for i, m in enumerate(self.sdef.modes)}
        if self.sdef.type == 29 and self.sdef.quirks:
            self.values[4] = [0, 0, 0, 0]     # RGB-RAW sends four values
        self.mode = 0
        self.stopping = threading.Event()
        self.unplugged = threading.Event()
        self.events = []        # (time, what) for the tests
        self.handshakes = 0
        self.frames_sent = 0
        self.writes = []
        self.lump_writes = []       # (mode, payload) a Powered Up host sent
        self.lump_write_modes = []  # the mode the device was in for each
        self.combo = None           # ((mode, index), ...) of a combined mode
        self.combo_setups = []      # the combined modes set up
        self.changed = True
        self.stale_until = 0.0
        self.fd = None

    # ---- control from the tests ----

    def set_values(self, mode, values):
        with self.lock:
            self.values[mode] = list(values)
            self.changed = True

    def set_many(self, by_mode):
        """Set the values of several modes at once ({mode: values}): a
        combined DATA message has all or none of them."""
        with self.lock:
            for mode, values in by_mode.items():
                self.values[mode] = list(values)
            self.changed = True

    def stop(self):
        self.stopping.set()
        self.join(5)

    def stream(self, count, start=0, timeout=10.0):
        """Send `count` DATA frames of the current mode in one write, the
        first value counting from `start` (wrapping at the data type's
        range), the others 0. Waits until the tty driver has taken them all
        (the last few kilobytes may still be on their way) and returns
        (mode, first value, monotonic time the write started, time it
        ended), or None if the sensor was not in its data phase in
        `timeout` seconds."""
        mode = self.mode
        m = self.sdef.modes[mode]
        rest = pack_values(m, [0] * (len(self.values[mode]) - 1))
        # Built here, not in the sensor's thread, which must keep answering.
        frames = b''.join(data_frame(self.sdef, mode,
                                     pack_values(m, [wrap_value(m, start + i)]) + rest)
                          for i in range(count))
        req = {'count': count, 'start': start, 'mode': mode, 'frames': frames,
               'done': threading.Event()}
        self.stream_req = req
        if not req['done'].wait(timeout) and 'result' not in req:
            self.stream_req = None
            return None
        return req.get('result')

    def unplug(self):
        """Go silent, as if the cable were pulled (the thread keeps running)."""
        self.unplugged.set()

    def plug(self):
        self.unplugged.clear()

    def log(self, what):
        self.events.append((time.monotonic(), what))

    # ---- the wire ----

    def set_speed(self, baud):
        if baud not in BAUD:
            # No constant for it: only a pty, which has no speed, can
            # play such a sensor.
            self.speed = baud
            return
        attrs = termios.tcgetattr(self.fd)
        attrs[4] = attrs[5] = BAUD[baud]
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        self.speed = baud

    def host_speed(self):
        """The host end's speed, if we watch it (else ours)."""
        if self.host_fd is None:
            return self.speed
        return SPEED_OF.get(termios.tcgetattr(self.host_fd)[5], 0)

    def send(self, data):
        if self.unplugged.is_set():
            return
        host = self.host_speed()
        if host != self.speed:
            self.garbled += len(data)
            data = garble(data, self.speed, host, self.rng)
        if self.pace and self.speed:
            self.send_paced(data)
            return
        view = memoryview(data)
        while view:
            view = view[os.write(self.fd, view):]

    def send_paced(self, data):
        """send() on a line that paces nothing: each chunk when a wire at
        our speed would have taken it (10 bits a byte), on an absolute
        schedule, so that a late wake-up does not slow the rest."""
        byte = 10.0 / self.speed
        t0 = time.monotonic()
        for i in range(0, len(data), PACE_CHUNK):
            left = t0 + i * byte - time.monotonic()
            if left > 0:
                time.sleep(left)
            view = memoryview(data[i:i + PACE_CHUNK])
            while view:
                view = view[os.write(self.fd, view):]
        left = t0 + len(data) * byte - time.monotonic()
        if left > 0:
            time.sleep(left)

    def wait_gate(self):
        """Call the test's gate (see __init__), once."""
        gate, self.gate = self.gate, None
        if gate is not None:
            gate()

    def read(self, timeout):
        r, _, _ = select.select([self.fd], [], [], max(timeout, 0))
        if not r:
            return b''
        try:
            data = os.read(self.fd, 256)
        except OSError as e:
            # A pty master whose far end nobody holds open reads EIO: a
            # cable with no host on it, so nothing arrives.
            if e.errno != errno.EIO:
                raise
            time.sleep(max(timeout, 0))
            return b''
        return b'' if self.unplugged.is_set() else data

    def read_pending(self):
        """True if input is waiting to be read (never while unplugged)."""
        if self.unplugged.is_set():
            return False
        return bool(select.select([self.fd], [], [], 0)[0])

    # ---- behaviour ----

    def run(self):
        if isinstance(self.path, int):      # an open tty, e.g. a pty master
            self.fd = os.dup(self.path)
        else:
            self.fd = os.open(self.path, os.O_RDWR | os.O_NOCTTY)
        if self.host_tty:
            # Only for tcgetattr; works with the discipline attached.
            self.host_fd = os.open(self.host_tty, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        attrs = termios.tcgetattr(self.fd)
        attrs[0] = 0                                   # iflag: raw
        attrs[1] = 0                                   # oflag
        attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL
        attrs[3] = 0                                   # lflag: raw
        attrs[6][termios.VMIN] = 0
        attrs[6][termios.VTIME] = 0
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        try:
            while not self.stopping.is_set():
                if self.unplugged.is_set():
                    time.sleep(0.01)
                    continue
                if self.connect():
                    self.data_phase()
        finally:
            os.close(self.fd)
            if self.host_fd is not None:
                os.close(self.host_fd)

    def connect(self):
        """Reset, handshake at 2400 baud (or at 115200 after the host's
        fast sync probe); True once the host ACKed."""
        with self.lock:
            self.mode = 0
            self.combo = None
        delay = self.boot_delay
        if self.attempts and self.retry_delay is not None:
            delay = self.retry_delay
        self.attempts += 1
        speed = 2400
        # Built before the reset: after a fast sync it goes out at once.
        hs = handshake(self.sdef)
        if self.fast_sync:
            speed = self.listen_for_probe(delay)
        else:
            self.set_speed(2400)
            termios.tcsendbreak(self.fd, 0)
            self.stopping.wait(delay)
        if speed == 2400:
            termios.tcflush(self.fd, termios.TCIFLUSH)
            self.wait_gate()
        if self.hostile:
            self.send_hostile()
        if RUDE_GARBAGE in self.rude and speed == 2400:
            self.send(self.sync_garbage(hs))
        self.handshake_starts.append(time.monotonic())
        self.send(hs)
        termios.tcdrain(self.fd)
        self.sync_speeds.append(speed)
        self.log('handshake sent' if speed == 2400 else 'handshake sent at %d' % speed)
        if self.wait_ack():
            self.handshakes += 1
            switch = self.speed != self.sdef.speed
            self.set_speed(self.sdef.speed)
            if switch and RUDE_GLITCH in self.rude:
                glitch = self.rude_rng.choice(GLITCH_BYTES)
                self.send(bytes([glitch]))
                self.glitches += 1
                self.log('glitch %02x' % glitch)
            return True
        return False

    def sync_garbage(self, hs):
        """(rude) Random bytes for before the handshake `hs`, none of
        which starts a TYPE message the host could take (see the top of
        the file), and no 0x04."""
        r = self.rude_rng
        while True:
            junk = bytes(r.choice([b for b in range(256) if b != SYS_ACK])
                         for _ in range(r.randint(1, GARBAGE_SYNC_MAX)))
            data = junk + hs[:2]
            if not any(data[i] == 0x40 and data[i + 2] == checksum(data[i:i + 2])
                       for i in range(len(junk))):
                self.sync_garbage_bytes += len(junk)
                return junk

    def takes(self, data, i):
        """(rude) The length of the message the host would take at
        data[i] in the data phase if the bytes were there, 0 if none
        starts there; -1 for the colour sensor's RGB-RAW header, whose
        checksum nobody checks (hosts know it by the type: a generated
        sensor of type 29 too)."""
        h = data[i]
        if h == 0x46 and getattr(self.sdef, 'lump', False):
            n = 3
        elif h & 0xc0 == 0xc0 and (h >> 3) & 7 <= 5:
            n = (1 << ((h >> 3) & 7)) + 2
        else:
            return 0
        if h == 0xdc and self.sdef.type == 29 and not getattr(self.sdef, 'lump', False):
            return -1
        return n

    def data_garbage(self, msg):
        """(rude) b'', or, before about one message in 20, a burst of
        random bytes to send before `msg`: none starts a message the host
        could take or one that runs past `msg` (see the top of the file)."""
        r = self.rude_rng
        if RUDE_GARBAGE not in self.rude or r.random() >= GARBAGE_SHARE:
            return b''
        while True:
            junk = bytes(r.randrange(256) for _ in range(r.randint(1, GARBAGE_MAX)))
            data = junk + msg
            ok = True
            for i in range(len(junk)):
                n = self.takes(data, i)
                if n < 0 or i + n > len(data) or \
                        (n and data[i + n - 1] == checksum(data[i:i + n - 1])):
                    ok = False
                    break
            if ok:
                self.garbage_bytes += len(junk)
                return junk

    def listen_for_probe(self, delay):
        """The reset of a device that can sync fast: TX held low (a
        break, which the host sees) for `delay` seconds while it listens at
        115200 baud for SPEED 115200. It answers one with ACK at once and
        returns 115200 (its handshake follows at that speed), else it
        returns 2400, at 2400 baud.

        A real device answers within a millisecond, the host waits 30 ms.
        Python in the emulated test machine takes 4 to 15 ms, and more when
        another thread of the test holds the interpreter lock: it is handed
        over every 5 ms by default, every 0.5 ms from here on."""
        if sys.getswitchinterval() > 0.0005:
            sys.setswitchinterval(0.0005)
        self.set_speed(FAST)
        termios.tcflush(self.fd, termios.TCIFLUSH)
        try:
            fcntl.ioctl(self.fd, TIOCSBRK)
        except OSError:
            pass                    # a tty with no break (a pty)
        self.wait_gate()
        deadline = time.monotonic() + delay
        buf = b''
        try:
            while not self.stopping.is_set():
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                buf = buf[-(len(PROBE) - 1):] + self.read(min(left, 0.05))
                if PROBE in buf:
                    self.send(bytes([SYS_ACK]))
                    self.fast_syncs += 1
                    self.log('fast sync: ACK to SPEED 115200')
                    return FAST
        finally:
            try:
                fcntl.ioctl(self.fd, TIOCCBRK)
            except OSError:
                pass
        self.set_speed(2400)
        return 2400

    def wait_ack(self):
        """The sensor waits 80 ms for the host's ACK, on its own clock.

        A real sensor's UART holds the ACK the moment it arrives, whatever
        the host does next. This emulator only sees it once the guest has
        run the tty's receive work and this thread, and the host's driver
        registers the sensor right after its ACK: on a one-CPU guest under
        KASAN that takes ~70 ms in a kernel thread that does not yield, and
        the ACK reached this thread 83-237 ms after our last byte left.
        So the 80 ms are counted in short waits, each counting for no more
        than it asked: time this thread could not run is not time the
        sensor watched the line. A host that is really late (its ACK not
        there after 80 ms of watching) is still refused."""
        watched = 0.0
        start = time.monotonic()
        while watched < ACK_WAIT:
            ask = min(ACK_SLICE, ACK_WAIT - watched)
            t = time.monotonic()
            data = self.read(ask)
            watched += min(time.monotonic() - t, ask)
            if SYS_ACK in data:
                self.log('acked after %.1f ms (%.1f ms watched)'
                         % ((time.monotonic() - start) * 1e3, watched * 1e3))
                return True
        self.log('no ack in %.0f ms watched (%.1f ms passed)'
                 % (watched * 1e3, (time.monotonic() - start) * 1e3))
        return False

    def frame(self, mode, spontaneous, old=False):
        """Send a DATA message of `mode`; `old`: (rude) of the old mode
        while a SELECT is pending."""
        m = self.sdef.modes[mode]
        with self.lock:
            values = list(self.values[mode])
            stale = self.stale_until > time.monotonic() and self.sdef.quirks
            combo = self.combo
            if combo:
                payload = b''.join(pack_values(self.sdef.modes[cm], [self.values[cm][ci]])
                                   for cm, ci in combo)
        if combo:
            msg = data_frame(self.sdef, mode, payload)
            self.send(msg)
            self.frames_sent += 1
            return
        if stale:
            # IR: leftovers of the previous mode until it settles.
            values = [self.rng.randrange(-128, 127) if m.t == S8 else self.rng.randrange(0, 3000)
                      for _ in values]
        tag = mode
        # US-DC-IN tags its own frames with mode 5 (US-DC-CM).
        if self.sdef.type == 30 and mode == 6 and spontaneous and self.sdef.quirks:
            tag = 5
        bad = (self.sdef.type == 29 and mode == 4 and self.sdef.quirks and
               self.rng.random() < 0.99)
        msg = data_frame(self.sdef, tag, pack_values(m, values), bad_checksum=bad)
        self.send(self.data_garbage(msg) + msg)
        self.frames_sent += 1
        if old:
            self.old_mode_frames += 1

    def flaky_data(self):
        """A broken device's data phase: one good frame, seven bad (after
        the 20 ms a real sensor may take, so that the host is at our speed)."""
        time.sleep(0.02)
        m = self.sdef.modes[self.mode]
        payload = pack_values(m, self.values[self.mode])
        self.send(data_frame(self.sdef, self.mode, payload))
        for _ in range(7):
            self.send(data_frame(self.sdef, self.mode, payload, bad_checksum=True))
        termios.tcdrain(self.fd)
        self.flaky_resets += 1
        self.log('flaky reset')

    def data_phase(self):
        if self.flaky:
            self.flaky_data()
            return
        last_nack = time.monotonic()
        next_spont = 0.0
        pending = None              # (time, mode) of a SELECT being carried out
        deaf = False
        buf = b''
        quiet = False
        looked = False
        host_ext = 0                # the host's last EXT_MODE (Powered Up)
        # (the gyro, or rude) the old mode goes on while a SELECT is pending.
        old = self.old_mode
        self.changed = True
        while not self.stopping.is_set():
            now = time.monotonic()
            # No keep-alive for a second: reset. But read what is waiting
            # first, once: this thread may not have run for a while (see
            # wait_ack()), and a keep-alive may be in it.
            if now - last_nack > 1.0:
                if looked or not self.read_pending():
                    self.log('watchdog reset')
                    return
                looked = True
            if self.unplugged.is_set():
                time.sleep(0.01)
                continue
            mode = self.mode
            m = self.sdef.modes[mode]
            if pending and now >= pending[0]:
                with self.lock:
                    self.mode = mode = pending[1]
                    if self.sdef.type == 33:
                        self.stale_until = now + IR_STALE_TIME
                m = self.sdef.modes[mode]
                pending = None
                deaf = m.deaf
                # A rude sensor's first message of the new mode is one it
                # sends on its own, not a NACK reply.
                self.frame(mode, old)
                self.log('mode %d' % mode)
                next_spont = now + m.period * self.period_scale
            elif self.stream_req is not None and not deaf and not pending:
                quiet = self.send_stream(self.stream_req)
            elif self.combo and not deaf and not pending:
                if now >= next_spont:
                    self.frame(mode, True)
                    next_spont = now + COMBO_PERIOD * self.period_scale
            elif not deaf and (not pending or old):
                if m.cadence == 'continuous' and now >= next_spont:
                    self.frame(mode, True, old=bool(pending))
                    next_spont = now + m.period * self.period_scale
                elif m.cadence == 'change' and self.changed:
                    self.changed = False
                    self.frame(mode, True, old=bool(pending))
            wait = 0.05
            if quiet:
                wait = 0
            elif pending:
                wait = pending[0] - now
                if old and m.cadence == 'continuous' and not deaf:
                    wait = min(wait, next_spont - now)
            elif (m.cadence == 'continuous' or self.combo) and not deaf:
                wait = next_spont - now
            buf += self.read(min(wait, 0.05))
            while buf:
                b = buf[0]
                if b == SYS_NACK:
                    buf = buf[1:]
                    last_nack = time.monotonic()
                    looked = False
                    if not deaf and (not pending or old) and not quiet:
                        self.frame(self.mode, False, old=bool(pending))
                elif b == 0x43:             # SELECT
                    if len(buf) < 3:
                        break
                    if checksum(buf[:2]) == buf[2] and buf[1] < len(self.sdef.modes) and \
                            not self.ignore_select:
                        new = buf[1]
                        with self.lock:
                            self.combo = None       # a SELECT ends a combined mode
                        pending = (time.monotonic() + self.sdef.modes[new].first_reply, new)
                        if old and not deaf and new != self.mode:
                            # One of the old mode's that was on its way.
                            self.frame(self.mode, True, old=True)
                    buf = buf[3:]
                elif b == 0x46:             # EXT_MODE (Powered Up host)
                    if len(buf) < 3:
                        break
                    if checksum(buf[:2]) == buf[2]:
                        host_ext = buf[1] & 8
                    buf = buf[3:]
                elif b & 0xc0 == 0xc0 and getattr(self.sdef, 'lump', False):
                    # Powered Up: values for a mode (after EXT_MODE).
                    size = 1 << ((b >> 3) & 7)
                    if len(buf) < size + 2:
                        break
                    if checksum(buf[:size + 1]) == buf[size + 1]:
                        self.on_lump_data((b & 7) + host_ext, bytes(buf[1:size + 1]))
                    buf = buf[size + 2:]
                elif b & 0xc7 == 0x44:      # WRITE
                    size = 1 << ((b >> 3) & 7)
                    if len(buf) < size + 2:
                        break
                    if checksum(buf[:size + 1]) == buf[size + 1]:
                        self.on_write(buf[1:size + 1])
                        if self.on_combo(buf[1:size + 1]):
                            self.send(bytes(buf[:size + 2]))    # its answer
                            next_spont = 0.0
                    buf = buf[size + 2:]
                else:
                    buf = buf[1:]           # garbage, or an ACK repeated
            quiet = False

    def send_stream(self, req):
        """Serve a stream() request; True if it was sent. The keep-alives
        that came meanwhile count as answered by the stream."""
        self.stream_req = None
        if req['mode'] != self.mode:
            req['done'].set()           # the mode changed since: no stream
            return False
        t0 = time.monotonic()
        self.send(req['frames'])
        t1 = time.monotonic()
        self.frames_sent += req['count']
        self.log('streamed %d frames' % req['count'])
        req['result'] = (req['mode'], req['start'], t0, t1)
        req['done'].set()
        return True

    def on_lump_data(self, mode, payload):
        """Values a Powered Up host sent for `mode`: taken if the device is
        in that mode and it takes values (MAPPING out flags)."""
        self.lump_writes.append((mode, payload))
        self.lump_write_modes.append(self.mode)
        if mode >= len(self.sdef.modes) or mode != self.mode:
            self.log('values for mode %d ignored in mode %d' % (mode, self.mode))
            return
        m = self.sdef.modes[mode]
        size = {S8: 1, S16: 2, S32: 4, FLOAT: 4}[m.t]
        if not m.mapping or not m.mapping[1] or len(payload) < m.n * size:
            return
        fmt = {S8: 'b', S16: 'h', S32: 'i', FLOAT: 'f'}[m.t]
        self.set_values(mode, struct.unpack_from('<%d%s' % (m.n, fmt), payload))
        self.log('values for mode %d' % mode)

    def on_combo(self, payload):
        """A WRITE that sets up a combined mode the device offers: True if
        it was one."""
        combos = getattr(self.sdef, 'combos', ())
        if not getattr(self.sdef, 'lump', False) or payload[0] & 0xf0 != 0x20:
            return False
        n = payload[0] & 0x0f
        if not n or len(payload) < n + 2 or payload[1] >= len(combos):
            return False
        entries = tuple((e >> 4, e & 0xf) for e in payload[2:2 + n])
        for mode, index in entries:
            if mode >= len(self.sdef.modes) or not combos[payload[1]] >> mode & 1 or \
                    index >= self.sdef.modes[mode].n:
                return False
        with self.lock:
            self.combo = entries
        self.combo_setups.append((payload[1], entries))
        self.log('combined mode %d: %s' % (payload[1], entries))
        return True

    def on_write(self, payload):
        self.writes.append(bytes(payload))
        if self.sdef.type == 32 and payload[0] == 0x11:
            with self.lock:
                self.values[0] = [0]        # gyro angle reset
                self.changed = True
            self.log('angle reset')

    def send_hostile(self):
        """Everything a broken or malicious sensor could send."""
        r = self.rng
        junk = [bytes(r.randrange(256) for _ in range(64)),
                bytes([0x40, 0x1d]),                                  # truncated TYPE
                cmd_msg(CMD_TYPE, [29])[:2] + b'\x00',                # bad checksum
                cmd_msg(CMD_TYPE, [29]) + bytes([0xb0, 0x00]) + bytes(70),   # 64-byte INFO
                cmd_msg(CMD_TYPE, [29]) + cmd_msg(CMD_MODES, [200, 200]),   # absurd modes
                cmd_msg(CMD_TYPE, [29]) + cmd_msg(CMD_SPEED, struct.pack('<I', 10**9)),
                cmd_msg(CMD_TYPE, [29]) + info_msg(0, INFO_NAME, b'X' * 16),  # no NUL
                cmd_msg(CMD_TYPE, [29]) + info_msg(0, INFO_NAME, b'M\0') +
                info_msg(0, INFO_SI, f32(0) + f32(math.nan)) +
                info_msg(0, INFO_FORMAT, [1, 0, 2, 0]) + bytes([SYS_ACK]),  # NaN range
                cmd_msg(CMD_TYPE, [29]) + info_msg(0, INFO_NAME, b'M\0') +
                info_msg(0, INFO_FORMAT, [200, 1, 2, 0]) + bytes([SYS_ACK]),  # count overflow
                bytes([0xc0, 0x01, 0x02, 0xff] * 8),                   # DATA before ACK
                ]
        for j in junk:
            self.send(j)
        termios.tcdrain(self.fd)
        self.log('hostile sent')


def main():
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('tty', help='the sensor end of the line, e.g. /dev/ttyNM1')
    ap.add_argument('sensor', choices=sorted(SENSORS))
    ap.add_argument('--hostile', action='store_true')
    ap.add_argument('--seconds', type=float, default=0, help='run this long (0: forever)')
    ap.add_argument('--host-tty', metavar='TTY',
                    help='the host end of a line with no baud rate (e.g. /dev/ttyS1 when two '
                    'QEMU UARTs share a socket): garble what is sent while its speed differs')
    ap.add_argument('--stream', type=int, default=0, metavar='N',
                    help='once connected, send N DATA frames of mode 0 back to back in one '
                    'write, the value counting 0, 1, 2...')
    args = ap.parse_args()
    s = EmulatedSensor(args.tty, args.sensor, hostile=args.hostile, host_tty=args.host_tty)
    s.start()
    try:
        t0 = time.monotonic()
        if args.stream:
            while s.is_alive() and not s.handshakes:
                time.sleep(0.05)
            time.sleep(0.2)
            print('stream:', s.stream(args.stream, timeout=args.stream / 100 + 10), flush=True)
        while s.is_alive() and (not args.seconds or time.monotonic() - t0 < args.seconds):
            if s.sdef.type in (32, 30):
                s.set_values(0, [int(50 * math.sin(time.monotonic()))])
            time.sleep(0.1)
    finally:
        s.stop()


if __name__ == '__main__':
    main()
