#!/usr/bin/env python3
"""Whole-driver fuzzing of the EV3 line discipline with generated handshakes.

Each case (tests/emulator/ev3_gen.py: case(seed)) is played by an emulated
sensor on a pty or on a null-modem line, and goes through attach,
registration (or a refusal with a log line), reading every sysfs and IIO
attribute, a buffered capture, mode switches, a WRITE, and a detach; the
kernel log must stay free of splats. On a null-modem line the driver's ACK
deadline and keep-alive period are checked too, from the null modem's
kernel timestamps (wire.py). Runs inside the test VM.

What a case may get away with, each counted on its own (the test bounds
them): a sensor lost mid-case for want of data (an emulator starved of
CPU), only when the kernel log says so for its port; a mode write that
times out on a null-modem line whose DATA messages take 100 ms or more
(the emulated sensor's answers queue up), only with the driver's log line.
Anything else that differs from the model or the ABI fails the case.

Usage (in the VM):
  python3 tests/guest/ev3_fuzz.py --seed S [--count N] [--transport pty|nullmodem]
                                  [--known avoid|include|only] [--workers W] [-v]
Replay of one failed case, from the host:
  tests/vm-run -- python3 tests/guest/ev3_fuzz.py --seed S --transport T --known K
Exit status 1 if any case failed.
"""
import argparse
import errno
import fcntl
import glob
import math
import multiprocessing
import os
import random
import re
import signal
import struct
import sys
import termios
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, '..', 'emulator'))
import ev3  # noqa: E402
import kmsg  # noqa: E402
from kstacks import kernel_stacks  # noqa: E402
import ev3_gen as gen  # noqa: E402
import ev3_sensor as es  # noqa: E402
import wire  # noqa: E402

N_TTY, N_LEGOEV3 = 0, 29
TIOCVHANGUP = 0x5437
IIO = '/sys/bus/iio/devices'
CASE_TIMEOUT = 90           # seconds: a case still running is a hang
REGISTER_TIMEOUT = 15.0     # a handshake the model accepts must register by then
REFUSE_WAIT = 0.6           # how long a refused handshake is given to register anyway
GONE_TIMEOUT = 10.0
# The patterns of tests/scan-console.py: any of them in the kernel log fails the case.
SPLAT = re.compile(r'\bBUG: |\bWARNING: |\bOops\b|general protection fault|Kernel panic|'
                   r'KASAN: |UBSAN: |possible circular locking dependency|'
                   r'possible recursive locking|inconsistent lock state|'
                   r'blocked for more than|sleeping function called from invalid context|'
                   r'suspected memory leak|ODEBUG: |stack-protector|Call Trace:|'
                   r'divide error')
DEFAULT_KNOWN = 'include'   # the driver has the fixes (see KNOWN_BUGS)


def tokens(desc):
    """The modes as the "modes" attribute lists them (ev3_uart_mode_token()):
    spaces shown as '_', and modes that would be shown alike as '#N'."""
    subst = [m.name.replace(' ', '_') for m in desc.modes[:desc.num_modes]]
    return ['#%d' % i if subst.count(s) > 1 else s for i, s in enumerate(subst)]


class CaseFailure(Exception):
    pass


class Hang(Exception):
    pass


class SensorLost(Exception):
    """The driver dropped the sensor for want of data (an emulator starved
    of CPU), and said so in the log for its port: the case ends with the
    detach checks."""


# The driver's lines for a lost sensor (ev3_uart_event(), ev3_uart_reset()): the
# reason, then the loss; only a loss for want of data is the emulator's.
LOST_REASON = 'no data from the sensor'


def lost_lines(address, lines):
    """The reasons the log gives for sensors lost on `address` in `lines`:
    the last reason line before each "<address>: <driver> disconnected".
    A sensor may be lost while it registers: the reason comes first, then
    "... connected as ..." and "reconnected after: <reason>" (the work
    that registers it holds up the one that drops it)."""
    pre = re.compile(r'(?:^|: )%s: (.*)$' % re.escape(address))
    reasons, last = [], None
    for line in lines:
        m = pre.search(line)
        if not m:
            continue
        text = m.group(1)
        if text.endswith(' disconnected'):
            reasons.append(last)
        elif ' connected as ' in text:
            continue
        else:
            last = text.split('reconnected after: ', 1)[-1]
    return reasons


SCALE_MIN_NANO = 1000                       # ev3_uart_chan.c
SCALE_MAX_NANO = (2 ** 31 - 1) * 10 ** 9 + 10 ** 9 - 1


def _mul_div(a, b, c):
    """ev3_uart_mul_div(), rounded: None where the quotient needs > 64 bits."""
    q = (a * b + c // 2) // c
    return q if q < 2 ** 64 else None


def chan_shown(m, nano):
    """Whether the driver gives a value of mode m (with IIO units of `nano`
    per SI unit) a channel: ev3_uart_chan_scale() leaves out a value whose
    scale or offset IIO cannot show, or whose scale would be mostly
    rounding."""
    dec = min(m.dec, gen.MAX_DECIMALS)
    if m.t == es.FLOAT:
        for d in range(dec, -1, -1):
            if d == 0 or nano // 10 ** d >= SCALE_MIN_NANO:
                break
        scale = (nano + 10 ** d // 2) // 10 ** d
        return SCALE_MIN_NANO <= scale <= SCALE_MAX_NANO
    raw_span, si_span = m.raw[1] - m.raw[0], m.si[1] - m.si[0]
    if not raw_span or not si_span:
        scale = _mul_div(nano, 1, 10 ** dec)
        return scale is not None and SCALE_MIN_NANO <= scale <= SCALE_MAX_NANO
    scale = _mul_div(abs(si_span), nano, abs(raw_span) * 10 ** dec)
    if scale is None or not SCALE_MIN_NANO <= scale <= SCALE_MAX_NANO:
        return False
    neg = (si_span < 0) != (raw_span < 0)
    off = _mul_div(abs(m.si[0]) * abs(raw_span), 10 ** 6, abs(si_span))
    if off is None:
        return False
    offset = -off if (m.si[0] < 0) != neg else off
    offset -= m.raw[0] * 10 ** 6
    if not -2 ** 63 <= offset < 2 ** 63:
        return False
    q = abs(offset) // 10 ** 6
    q = -q if offset < 0 else q                  # div_s64_rem truncates
    return -2 ** 31 <= q <= 2 ** 31 - 1


def model_channels(d, mode):
    """How many IIO channels the driver gives mode `mode` of d."""
    nano = gen.iio_nano(d, mode)
    if nano is None:
        return 0
    m = d.modes[mode]
    return m.n if chan_shown(m, nano) else 0


def model_stages(c):
    """The stages the model says case c reaches if nothing is lost: a set
    of 'registered', 'refused', 'values' (sysfs values checked), 'iio' (an
    IIO device), 'captured' (scans of mode 0), 'switched' (a mode switch),
    'written' (a WRITE), 'detached'. The IIO channels as the driver makes
    them (ev3_uart_chans_build(), chan_shown()). None where the model cannot tell
    (a case that hits a known driver bug: what the fixed driver makes of
    it is not modelled)."""
    if c.desc is None:
        return {'refused'}
    if c.bugs:
        return None
    d = c.desc
    st = {'registered', 'values', 'written', 'detached'}
    if any(model_channels(d, i) for i in range(d.num_modes)):
        st.add('iio')
        if model_channels(d, 0):
            st.add('captured')
    if d.num_modes > 1:
        st.add('switched')
    return st


def replay_command(seed, transport, known):
    return ('tests/vm-run -- python3 tests/guest/ev3_fuzz.py --seed %d --transport %s '
            '--known %s   (the case: python3 tests/emulator/ev3_gen.py --seed %d '
            '--transport %s --known %s)' % (seed, transport, known, seed, transport, known))


# ---- attribute reads with the ABI's errnos ------------------------------------------

def try_read(sd, name, binary=False):
    """(value, None) or (None, errno)."""
    try:
        return sd.read(name, binary), None
    except OSError as e:
        return None, e.errno


def try_write(sd, name, value, binary=False):
    try:
        fd = os.open(name, os.O_WRONLY, dir_fd=sd.fd)
        try:
            os.write(fd, value if binary else value.encode())
        finally:
            os.close(fd)
        return None
    except OSError as e:
        return e.errno


def read_path(path, binary=False):
    try:
        with open(path, 'rb' if binary else 'r') as f:
            return f.read() if binary else f.read().strip(), None
    except OSError as e:
        return None, e.errno


def ename(e):
    return errno.errorcode.get(e, str(e)) if e else 'ok'


# ---- one case ---------------------------------------------------------------------

class Runner:
    """Plays cases on one transport: 'pty' (a fresh pty per case) or
    'nullmodem' (null-modem pair `pair`)."""

    concurrent = False      # other processes run cases at the same time

    def __init__(self, transport, known, pair=0, verbose=False):
        self.transport, self.known, self.pair = transport, known, pair
        self.verbose = verbose
        self.kmsg = kmsg.Kmsg(writable=True)
        self.info = {}
        self.step_times = []

    @property
    def step(self):
        """The step of the case being played (named in failures)."""
        return self._step

    @step.setter
    def step(self, name):
        self._step = name
        self.step_times.append((name, time.monotonic()))

    def step_profile(self):
        """'step=seconds ...' of the last case, for --verbose."""
        marks = self.step_times + [('', time.monotonic())]
        return ' '.join('%s=%.1f' % (a[0].replace(' ', '_'), b[1] - a[1])
                        for a, b in zip(marks, marks[1:]))

    def bump(self, key, n=1):
        self.info[key] = self.info.get(key, 0) + n

    def extreme(self, key, v):
        """Keep the least (key ending in _min) or greatest (_max) value."""
        if key in self.info:
            v = min(v, self.info[key]) if key.endswith('_min') else max(v, self.info[key])
        self.info[key] = v

    def run(self, seed):
        """Run the case of `seed`; None if it passed, else the failure text."""
        c = gen.case(seed, self.transport, self.known)
        self.kmsg.read()
        self.kmsg.mark('ev3fuzz: case seed=%d transport=%s known=%s %s%s' % (
            seed, self.transport, self.known, c.kind,
            ' bugs=' + ','.join(c.bugs) if c.bugs else ''))
        self.step_times = []
        self.step = 'setup'
        self._seen = []
        self._sd = None
        self.stages = set()
        self.excuses = set()
        self.wire_since = None
        err = None
        old = signal.signal(signal.SIGALRM, self._alarm)
        signal.alarm(CASE_TIMEOUT)
        try:
            self._run(c)
        except CaseFailure as e:
            err = str(e)
        except Hang:
            err = 'hang: the case took more than %d s (in step %s)' % (CASE_TIMEOUT, self.step)
        except Exception:
            err = 'exception in step %s: %s' % (self.step, traceback.format_exc(limit=5))
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)
        self.step_times.append(('checks', time.monotonic()))
        splats = [line for line in self.kmsg.texts() if SPLAT.search(line)]
        if splats:
            err = (err + '\n' if err else '') + 'kernel splat:\n  ' + '\n  '.join(splats[:20])
        if not err and self.wire_since is not None:
            err = self._check_wire(c)
        self.bump('cases')
        self.bump('cases_' + c.kind)
        for ex in self.excuses:
            self.bump('excused_' + ex)
        want = model_stages(c)
        if want is not None:
            self.bump('model_cases')
            for st in want:
                self.bump('model_' + st)
            for st in want & self.stages:
                self.bump('reached_' + st)
            missed = want - self.stages
            for st in missed:
                self.bump(('excused_miss_' if self.excused(st) else 'missed_') + st)
            unexcused = sorted(st for st in missed if not self.excused(st))
            if unexcused and not err:
                err = ('the model says the case reaches %s; it reached %s only'
                       % (', '.join(unexcused), ', '.join(sorted(self.stages)) or 'none'))
        if err:
            return ('seed %d (%s, %s): %s\n  %s\n  replay: %s'
                    % (seed, c.kind, self.transport, err,
                       c.describe().replace('\n', '\n  '),
                       replay_command(seed, self.transport, self.known)))
        return None

    # What a tolerated event excuses: the stages after it.
    EXCUSES = {'lost': {'values', 'iio', 'captured', 'switched', 'written'},
               'iio_ambiguous': {'iio', 'captured'},
               'mode_timeout': {'switched'}}

    def excused(self, stage):
        return any(stage in self.EXCUSES[ex] for ex in self.excuses)

    def _alarm(self, signum, frame):
        raise Hang()

    def fail(self, msg):
        raise CaseFailure('step %s: %s' % (self.step, msg))

    def check(self, cond, msg):
        if not cond:
            if ('ENODEV' in msg or 'ENOENT' in msg) and self._sd is not None:
                # Lost? Only if the directory is gone and the log says, for
                # this port, that the sensor sent no data. Counted; the test
                # bounds how often.
                gone = self._sd.wait_gone(10)
                self.kmsg_lines()
                reasons = lost_lines(self.address, self._seen)
                if gone and reasons and reasons[-1] == LOST_REASON:
                    raise SensorLost()
                self.fail('%s (the sensor %s; the log says for %s: %s)' % (
                    msg, 'is gone' if gone else 'is still there', self.address,
                    ', '.join('lost after %r' % r for r in reasons) or 'no loss'))
            self.fail(msg)

    # -- the line --

    def _open_line(self):
        if self.transport == 'pty':
            master, slave = os.openpty()
            self.master, self.host = master, slave
            self.address = 'pts' + os.ttyname(slave).split('/')[-1]
            self.far = master
        else:
            ev3.load_nullmodem()
            if wire.available():
                self.wire_since = wire.head()
            self.master = None
            self.host = os.open('/dev/ttyNM%d' % (2 * self.pair),
                                os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            self.address = 'ttyNM%d' % (2 * self.pair)
            self.far = '/dev/ttyNM%d' % (2 * self.pair + 1)
            self._flush_line()
        fcntl.ioctl(self.host, termios.TIOCSETD, struct.pack('i', N_LEGOEV3))

    def _flush_line(self):
        """Nothing of an earlier case is left on the null-modem line: the
        null modem sends at the line's speed, so a handshake the last
        case's sensor sent again just before it stopped can still be on
        its way, and the next case's driver would sync on it (a sensor of
        the wrong type registered). Both ends are flushed before the
        discipline is attached."""
        far = os.open(self.far, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            termios.tcflush(far, termios.TCIOFLUSH)
        finally:
            os.close(far)
        termios.tcflush(self.host, termios.TCIOFLUSH)

    def _detach(self, rng, emu):
        """Detach in one of the ways a user can; returns how."""
        how = rng.choice(['close', 'setd', 'hangup'] if self.transport == 'pty'
                         else ['close', 'setd'])
        if how == 'setd':
            fcntl.ioctl(self.host, termios.TIOCSETD, struct.pack('i', N_TTY))
        elif how == 'hangup':
            fcntl.ioctl(self.host, TIOCVHANGUP)
        if how == 'close':
            os.close(self.host)
            self.host = None
            if self.master is not None:
                # A pty is released (its discipline closed) only once both
                # its ends are: the far end goes too, the emulated sensor's
                # copy of it first.
                emu.stopping.set()
                emu.join(5)
                os.close(self.master)
                self.master = None
        return how

    def _check_wire(self, c):
        """The driver's ACKs and keep-alives on the null-modem line, from
        the null modem's timestamps: None, or what is wrong."""
        recs, lost = wire.read(self.wire_since)
        errors, conns = wire.check(recs, 2 * self.pair, self.detached_ns, lost)
        registered = 'registered' in self.stages
        if registered and not conns:
            errors.append('a sensor registered, but no ACK of the driver is on the wire')
        if c.desc is None and conns:
            errors.append('the driver ACKed a handshake the model refuses: %r' % conns)
        self.bump('wire_handshakes', len(conns))
        self.bump('wire_keepalives', sum(len(x.nacks) for x in conns))
        for x in conns:
            if x.ack_delay_ms is not None:
                self.extreme('wire_ack_ms_min', round(x.ack_delay_ms))
                self.extreme('wire_ack_ms_max', round(x.ack_delay_ms))
            for p in x.periods_ms():
                self.extreme('wire_period_ms_min', round(p))
                self.extreme('wire_period_ms_max', round(p))
        if errors:
            return 'timing on the wire:\n  ' + '\n  '.join(errors)
        return None

    def _close_line(self):
        for fd in (self.host, self.master):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.host = self.master = None

    def _emulator(self, c):
        d = c.desc
        if d is None:
            modes = [es.Mode('X', (0, 1), (0, 1), None, 1, es.S8, 1, 0)]
            views, speed = 1, 2400
        else:
            modes = [es.Mode(m.name, (0, 1), (0, 1), None, m.n, m.t, m.fig, m.dec,
                             first_reply=0.002)
                     for m in d.modes[:d.num_modes]]
            views, speed = d.views, d.speed
        sdef = es.SensorDef(d.type if d else 0, d.driver if d else '?', views, modes,
                            speed=speed, raw_handshake=c.data, quirks=False,
                            lump=bool(d and d.lump))
        emu = es.EmulatedSensor(self.far, sdef, seed=c.seed, boot_delay=0.05,
                                retry_delay=1.0, rude=c.rude)
        if c.rude:
            self.bump('rude_sensors')
        # The values belong to the described modes; a case without a
        # description (the driver must refuse it) sends the stand-in's zeros.
        for i, vals in (c.values.items() if d else ()):
            emu.values[i] = list(vals)
        return emu

    def _run(self, c):
        rng = random.Random(c.seed ^ 0x5eed)
        self.master = self.host = None
        self.detached_ns = None
        emu = None
        sd = None
        self.iio_before = set(glob.glob(IIO + '/iio:device*'))
        try:
            self.step = 'attach'
            self._open_line()
            emu = self._emulator(c)
            emu.start()
            self.step = 'registration'
            if c.desc is None:
                sd = self._expect_refusal(c)
                if sd is None:
                    return
            else:
                sd = ev3.open_sensor(self.address, timeout=REGISTER_TIMEOUT)
                self.check(sd, 'the model accepts the handshake but no sensor registered '
                           'in %.0f s (emulator: %s)' % (REGISTER_TIMEOUT, emu.events[-3:]))
                # Published (values in sysfs) once its IIO device is
                # registered too: seconds for hundreds of channels on the
                # debug kernel (ev3.wait_registered()).
                self.check(ev3.wait_registered(self.address, timeout=REGISTER_TIMEOUT)
                           is not False, '%s not published %.0f s after its class device appeared'
                           % (sd.path, REGISTER_TIMEOUT))
                self.bump('registered')
                self.bump(self.transport + '_registered')
                self.stages.add('registered')
            iio = None
            try:
                self.step = 'sysfs'
                self._sd = sd
                self._check_sysfs(c, sd, emu, 0)
                self.stages.add('values')
                self.step = 'iio'
                iio = self._find_iio(c, sd)
                if iio:
                    self.stages.add('iio')
                    self._check_iio(c, sd, iio, emu)
                    self.step = 'buffer'
                    self._capture(c, sd, iio, emu)
                self.step = 'mode switches'
                self._switch_modes(c, sd, emu, rng, iio)
                self.step = 'write'
                self._write(sd, emu, rng)
                self.stages.add('written')
            except SensorLost:
                self.bump('sensor_lost_' + self.step.replace(' ', '_'))
                self.excuses.add('lost')
            self.step = 'detach'
            self.detached_ns = time.monotonic_ns()
            how = self._detach(rng, emu)
            self.bump('detach_' + how)
            self.check(sd.wait_gone(GONE_TIMEOUT),
                       'the sensor is still there %.0f s after the detach (%s)'
                       % (GONE_TIMEOUT, how))
            if iio:
                self.check(ev3.wait_gone(iio, GONE_TIMEOUT),
                           'the IIO device %s outlived the detach (%s)' % (iio, how))
            self.stages.add('detached')
        finally:
            if sd:
                sd.close()
            if emu:
                emu.stopping.set()
            self._close_line()
            if emu:
                emu.join(5)
                if emu.is_alive():
                    # It would go on writing into the next case's line.
                    emu.join(30)
                    self.check(not emu.is_alive(), 'the emulated sensor did not stop in 35 s')

    # -- registration --

    def _expect_refusal(self, c):
        """The model refuses the handshake: the driver must not crash and
        must say why in the log, and must not register a sensor."""
        wait = REFUSE_WAIT
        if self.transport == 'nullmodem':
            wait += len(c.data) * 10 / 2400         # the handshake's time on the line
        sd = ev3.open_sensor(self.address, timeout=wait)
        if sd:
            self.bump('registered_despite_model')
            sd.close()
            self.fail('the driver registered %s, which the model refuses (%s)'
                      % (sd.path, '; '.join(c.reasons)))
        self.bump('refused')
        self.stages.add('refused')
        # pr_info_ratelimited: a burst of refusals may hide the line.
        logged = any(self.address + ':' in line or 'callbacks suppressed' in line
                     for line in self.kmsg_lines())
        # Bytes that never make a whole handshake have nothing to report.
        # The rate limit (10 lines in 5 s) says "callbacks suppressed" only
        # when its next line gets through, which may be after this case:
        # with several processes refusing at once, an unlogged refusal is
        # counted, and fails only when it is alone in its 5 s.
        if not logged and c.reasons != ['no complete handshake']:
            if self.concurrent:
                self.bump('refused_unlogged')
            else:
                self.fail('refused (model: %s) without a log line for %s'
                          % (c.reasons[-1], self.address))
        return None

    def kmsg_lines(self):
        lines = self.kmsg.texts()
        self._seen += lines
        splats = [line for line in lines if SPLAT.search(line)]
        if splats:
            self.fail('kernel splat:\n  ' + '\n  '.join(splats[:20]))
        return lines

    # -- sysfs --

    def _check_sysfs(self, c, sd, emu, mode):
        d = c.desc
        m = d.modes[mode]
        names = tokens(d)
        want = {'address': self.address, 'driver_name': d.driver,
                'commands': '', 'fw_version': d.fw_version_str}
        for attr, value in want.items():
            got, e = try_read(sd, attr)
            self.check(e is None, '%s: %s' % (attr, ename(e)))
            self.check(got == value, '%s reads %r, want %r' % (attr, got, value))
        got, e = try_read(sd, 'modes')
        self.check(e is None and got == ' '.join(names),
                   'modes reads %r (%s), want %r' % (got, ename(e), ' '.join(names)))
        self._check_mode_fields(sd, m, names[mode])
        for attr in ('poll_ms', 'text_value'):
            _, e = try_read(sd, attr)
            self.check(e == errno.EOPNOTSUPP, '%s: %s, want EOPNOTSUPP' % (attr, ename(e)))
        _, e = try_read(sd, 'direct', binary=True)
        self.check(e == errno.EOPNOTSUPP, 'direct read: %s, want EOPNOTSUPP' % ename(e))
        e = try_write(sd, 'command', 'RESET')
        self.check(e == errno.EINVAL, 'command write: %s, want EINVAL' % ename(e))
        _, e = try_read(sd, 'uevent')
        self.check(e is None, 'uevent: %s' % ename(e))
        self._check_values(c, sd, emu, mode)

    def _check_mode_fields(self, sd, m, token):
        want = {'mode': token, 'num_values': str(m.n), 'decimals': str(m.dec),
                'units': m.units, 'bin_data_format': gen.FORMATS[m.t]}
        for attr, value in want.items():
            got, e = try_read(sd, attr)
            self.check(e is None, '%s: %s' % (attr, ename(e)))
            # strip(): sysfs adds a newline; names and units may end in spaces
            self.check(got == value.strip(), '%s reads %r, want %r' % (attr, got, value))

    def _check_values(self, c, sd, emu, mode):
        """bin_data carries the payload the sensor sent; value<N> the ABI's
        mapping of it; ENXIO past num_values; ERANGE only for floats."""
        m = c.desc.modes[mode]
        emu.set_values(mode, emu.values[mode])      # sent again: the last frame may be older
        payload = es.pack_values(es.Mode('', 0, 0, None, m.n, m.t, 0, 0), emu.values[mode])
        deadline = time.monotonic() + 5
        while True:
            data, e = try_read(sd, 'bin_data', binary=True)
            self.check(e is None, 'bin_data: %s' % ename(e))
            self.check(len(data) == gen.MAX_PAYLOAD, 'bin_data is %d bytes' % len(data))
            if data[:len(payload)] == payload:
                break
            if time.monotonic() > deadline:
                self.fail('bin_data %s never showed the values sent (%s)'
                          % (data.hex(), payload.hex()))
            time.sleep(0.02)
        self.bump('values_seen')
        for i in range(8):
            got, e = try_read(sd, 'value%d' % i)
            if i >= m.n:
                self.check(e == errno.ENXIO, 'value%d with num_values %d: %s, want ENXIO'
                           % (i, m.n, ename(e)))
                continue
            raw = gen.read_value(m, payload, i)
            if raw is None:
                self.check(e == errno.ERANGE, 'value%d of %r: %s, want ERANGE'
                           % (i, emu.values[mode][i], got if e is None else ename(e)))
                continue
            self.check(e is None, 'value%d: %s' % (i, ename(e)))
            want = gen.scale_value(m, raw)
            self.check(got == str(want), 'value%d reads %s, want %d (raw %d, sent %r)'
                       % (i, got, want, raw, emu.values[mode][i]))

    # -- IIO --

    def _find_iio(self, c, sd):
        """The sensor's IIO device: the one with its driver name and modes
        (ptys have no device to be the parent). The sensor is published
        after its IIO device is registered, or after the log line that says
        why it has none: no wait for one then."""
        modes = ' '.join(tokens(c.desc))
        said = ' %s: ' % os.path.basename(sd.path)      # dev_warn(&sd->dev, ...)
        deadline = time.monotonic() + 3
        while True:
            found = []
            for dev in glob.glob(IIO + '/iio:device*'):
                if (read_path(dev + '/name')[0] == c.desc.driver and
                        read_path(dev + '/modes')[0] == modes):
                    found.append(dev)
            if len(found) == 1:
                return found[0]
            if len(found) > 1:
                self.bump('iio_ambiguous')
                self.excuses.add('iio_ambiguous')
                return None
            self.kmsg_lines()
            if any(said in line and 'no IIO device' in line for line in self._seen) or \
                    time.monotonic() > deadline:
                break
            time.sleep(0.05)
        # The driver carries on without IIO if it cannot register it: that
        # must be said in the log.
        self.bump('no_iio_device')
        if not any(said in line and 'no IIO device' in line for line in self._seen):
            self.fail('no IIO device and no "no IIO device" log line')
        return None

    def _iio_channels(self, iio):
        return sorted(os.path.basename(p)[:-4] for p in glob.glob(iio + '/in_*_raw'))

    def _check_iio(self, c, sd, iio, emu):
        d = c.desc
        names = tokens(d)
        got, e = read_path(iio + '/mode')
        self.check(e is None and got == names[0],
                   'IIO mode reads %r (%s), want %r' % (got, ename(e), names[0]))
        chans = self._iio_channels(iio)
        self.bump('iio_channels', len(chans))
        total = sum(m.n for m in d.modes[:d.num_modes])
        self.check(len(chans) <= total, '%d IIO channels for %d values in all modes'
                   % (len(chans), total))
        current = 0
        m0 = d.modes[0]
        raw_span, si_span = m0.raw[1] - m0.raw[0], m0.si[1] - m0.si[0]
        for ch in chans:
            busy = read_path('%s/%s_raw' % (iio, ch))[1] == errno.EBUSY
            for what in ('scale', 'offset'):
                v, e = read_path('%s/%s_%s' % (iio, ch, what))
                if e == errno.ENOENT:
                    continue
                self.check(e is None, '%s_%s: %s' % (ch, what, ename(e)))
                try:
                    x = float(v)
                except ValueError:
                    self.fail('%s_%s reads %r, not a number' % (ch, what, v))
                self.check(math.isfinite(x), '%s_%s reads %r' % (ch, what, v))
                if what == 'scale':
                    self.check(x != 0, '%s_scale reads %r: zero' % (ch, v))
                if what == 'scale' and not busy and m0.t != es.FLOAT and raw_span and si_span:
                    # (raw + offset) * scale grows with raw iff SI grows with RAW.
                    self.check((x > 0) == ((si_span > 0) == (raw_span > 0)),
                               '%s_scale reads %s for RAW %s and SI %s' % (ch, v, m0.raw, m0.si))
            v, e = read_path('%s/%s_raw' % (iio, ch))
            if e == errno.EBUSY:
                continue                    # a channel of another mode
            if e == errno.ERANGE and d.modes[0].t == es.FLOAT:
                current += 1
                continue
            self.check(e is None, '%s_raw: %s' % (ch, ename(e)))
            try:
                int(v)
            except ValueError:
                self.fail('%s_raw reads %r, not an integer' % (ch, v))
            current += 1
        self.check(current <= d.modes[0].n, '%d IIO channels readable in mode %s of %d values'
                   % (current, names[0], d.modes[0].n))
        got, e = read_path(iio + '/modes')
        self.check(e is None, 'IIO modes: %s' % ename(e))

    def _capture(self, c, sd, iio, emu):
        """A buffered capture of the current mode's channels: well-formed
        scans with increasing timestamps, or a clean errno."""
        scan = iio + '/scan_elements'
        chans = []
        for p in sorted(glob.glob(scan + '/in_*_en')):
            ch = os.path.basename(p)[:-3]
            if ch == 'in_timestamp':
                continue
            v, e = read_path('%s/%s_raw' % (iio, ch))
            if e != errno.EBUSY:
                chans.append(ch)
        if not chans:
            self.bump('capture_no_channels')
            return
        num = iio.rsplit('iio:device', 1)[1]
        enabled = []
        try:
            for ch in chans:
                with open('%s/%s_en' % (scan, ch), 'w') as f:
                    f.write('1')
                enabled.append(ch)
            with open(scan + '/in_timestamp_en', 'w') as f:
                f.write('1')
            enabled.append('in_timestamp')
            with open(iio + '/buffer/length', 'w') as f:
                f.write('64')
        except OSError as e:
            self.check(False, 'enabling scan elements: %s' % ename(e.errno))
        # Geometry of one scan, from the _index and _type files.
        elems = []
        for ch in enabled:
            v, e = read_path('%s/%s_index' % (scan, ch))
            self.check(e is None, '%s_index: %s' % (ch, ename(e)))
            idx = int(v)
            t, e = read_path('%s/%s_type' % (scan, ch))
            self.check(e is None, '%s_type: %s' % (ch, ename(e)))
            mt = re.match(r'([lb]e):([su])(\d+)/(\d+)>>(\d+)$', t)
            self.check(mt, '%s_type reads %r' % (ch, t))
            elems.append((idx, ch, int(mt.group(4)) // 8))
        elems.sort()
        offs, pos = [], 0
        for idx, ch, size in elems:
            pos = (pos + size - 1) // size * size
            offs.append((ch, pos, size))
            pos += size
        largest = max(s for _, _, s in elems)
        scan_size = (pos + largest - 1) // largest * largest
        fd = os.open('/dev/iio:device' + num, os.O_RDONLY | os.O_NONBLOCK)
        data = b''
        try:
            # The channels are those of the current mode, and no other
            # buffer holds the sensor: the driver has nothing to switch, so
            # no errno (EINVAL, EBUSY, ETIMEDOUT) is right here.
            try:
                with open(iio + '/buffer/enable', 'w') as f:
                    f.write('1')
            except OSError as e:
                self.check(False, 'buffer enable with the channels of the current mode: %s'
                           % ename(e.errno))
            emu.stream(16, timeout=3)
            deadline = time.monotonic() + 4
            while time.monotonic() < deadline and len(data) < scan_size * 8:
                data += ev3.drain(fd, 0.3)
            try:
                with open(iio + '/buffer/enable', 'w') as f:
                    f.write('0')
            except OSError as e:
                # ENOENT: the sensor was lost during the capture (check()
                # makes that a SensorLost once its directory is gone).
                self.check(False, 'buffer disable: %s' % ename(e.errno))
            data += ev3.drain(fd, 0.2)
        finally:
            os.close(fd)
            for ch in enabled:
                try:
                    with open('%s/%s_en' % (scan, ch), 'w') as f:
                        f.write('0')
                except OSError:
                    pass
        self.check(len(data) % scan_size == 0, 'read %d bytes of %d-byte scans'
                   % (len(data), scan_size))
        self.check(data, 'no scan in 4 s of a sensor sending (scan of %s)' % enabled)
        ts_off = [o for ch, o, _ in offs if ch == 'in_timestamp'][0]
        stamps = [struct.unpack_from('<q', data, i + ts_off)[0]
                  for i in range(0, len(data), scan_size)]
        if not all(b > a for a, b in zip(stamps, stamps[1:])):
            # ev3_uart_msg_time() backdates a batch's messages at the line
            # speed and follows a clock set back by more than a second: a
            # pty hands over the 16-frame stream in one batch, which at a
            # low speed is more than a second of line time.
            frame = 2 + gen.pow2_at_least(gen.SIZE[c.desc.modes[0].t] * c.desc.modes[0].n)
            backdated = self.transport == 'pty' and 16 * frame * 10 / c.desc.speed > 1.0
            if backdated and self.known == 'avoid':
                self.bump('known_timestamps_backwards')
            else:
                self.fail('timestamps not increasing: %s' % stamps[:10])
        self.bump('captured_scans', len(stamps))
        self.stages.add('captured')

    # -- modes --

    def _switch_modes(self, c, sd, emu, rng, iio):
        d = c.desc
        e = try_write(sd, 'mode', 'NO SUCH MODE' if 'NO SUCH MODE' not in
                      [m.name for m in d.modes[:d.num_modes]] else 'ZZZZZZZZZZZZ')
        self.check(e == errno.EINVAL, 'writing an unknown mode: %s, want EINVAL' % ename(e))
        e = try_write(sd, 'mode', '#%d' % d.num_modes)
        self.check(e == errno.EINVAL, 'writing an unknown mode: %s, want EINVAL' % ename(e))
        count = 1 if d.type == gen.TYPE_IR else rng.randint(1, 3)
        cur = 0
        for k in range(count):
            if d.num_modes == 1:
                break
            mode = rng.randrange(d.num_modes)
            # As "modes" lists it, or as the sensor named it if unique.
            name = tokens(d)[mode]
            if rng.random() < 0.3 and \
                    [m.name for m in d.modes[:d.num_modes]].count(d.modes[mode].name) == 1:
                name = d.modes[mode].name
            first = mode
            use_iio = iio and rng.random() < 0.3
            if use_iio:
                try:
                    with open(iio + '/mode', 'w') as f:
                        f.write(name)
                    e = None
                except OSError as err:
                    e = err.errno
            else:
                e = try_write(sd, 'mode', name)
            saturated = self.saturated(d, cur)
            if saturated:
                self.bump('mode_switches_saturated')
            if e == errno.ETIMEDOUT and saturated:
                # The current mode's messages (one per NACK, every 100 ms)
                # take 100 ms or more on this line: the emulated sensor's
                # answers queue up in its tty, and the first message of
                # the new mode can wait longer than the driver's 3 x 250
                # ms. The driver must say so, and keep a mode it has.
                self.kmsg_lines()
                self.check(any('mode %s not confirmed by the sensor' % d.modes[first].name in line
                               or 'callbacks suppressed' in line for line in self._seen),
                           'mode %r timed out without the log line' % name)
                got, e = try_read(sd, 'mode')
                self.check(e is None and got in (tokens(d)[cur], tokens(d)[first]),
                           'mode reads %r (%s) after a timed-out switch from %r to %r'
                           % (got, ename(e), tokens(d)[cur], tokens(d)[first]))
                self.bump('mode_timeout_saturated')
                self.excuses.add('mode_timeout')
                # Which mode the sensor ends in is not known: no more switches.
                break
            self.check(e is None, 'mode %r (%d) through %s: %s' % (
                name, first, 'IIO' if use_iio else 'sysfs', ename(e)))
            self.bump('mode_switches')
            self.stages.add('switched')
            cur = first
            self._check_mode_fields(sd, d.modes[first], tokens(d)[first])
            self._check_values(c, sd, emu, first)

    def saturated(self, d, mode):
        """Whether the DATA messages of `mode` take 100 ms or more on the
        line (so that the sensor's answers to the keep-alives queue up)."""
        if self.transport == 'pty':
            return False
        m = d.modes[mode]
        return (2 + gen.pow2_at_least(gen.SIZE[m.t] * m.n)) * 10 / d.speed >= 0.1

    def _write(self, sd, emu, rng):
        n = rng.choice([1, 2, 3, 5, 8, 16, 31, 32, rng.randint(1, 32)])
        payload = bytes(rng.randrange(256) for _ in range(n))
        before = len(emu.writes)
        e = try_write(sd, 'direct', payload, binary=True)
        self.check(e is None, 'WRITE of %d bytes: %s' % (n, ename(e)))
        e = try_write(sd, 'direct', bytes(33), binary=True)
        self.check(e == errno.EINVAL, 'WRITE of 33 bytes: %s, want EINVAL' % ename(e))
        deadline = time.monotonic() + 3
        while len(emu.writes) == before and time.monotonic() < deadline:
            time.sleep(0.02)
        self.check(len(emu.writes) > before, 'the sensor never got the WRITE')
        got = emu.writes[before]
        want = payload + bytes(es.pad(payload).__len__() - n)
        self.check(got == want, 'the sensor got WRITE %s, want %s' % (got.hex(), want.hex()))
        self.bump('writes')


# ---- many cases, in worker processes -----------------------------------------------

CTX = multiprocessing.get_context('fork')



def _quiet_thread_errors():
    def hook(args):
        if not issubclass(args.exc_type, OSError):
            sys.__excepthook__(args.exc_type, args.exc_value, args.exc_traceback)
    threading.excepthook = hook


def worker(q, current, transport, known, pair, seeds, verbose, max_failures):
    _quiet_thread_errors()
    r = Runner(transport, known, pair, verbose)
    failures = []
    done = 0
    t0 = time.monotonic()
    for seed in seeds:
        current.value = seed
        err = r.run(seed)
        done += 1
        if err:
            failures.append(err)
            print('ev3fuzz: FAIL %s' % err, flush=True)
            if len(failures) >= max_failures:
                break
        elif verbose:
            print('ev3fuzz: seed %d ok: %s' % (seed, r.step_profile()), flush=True)
        if done % 500 == 0:
            print('ev3fuzz: %s worker: %d cases, %d failed, %.0f s'
                  % (transport, done, len(failures), time.monotonic() - t0), flush=True)
    current.value = -1
    q.put({'count': done, 'failures': failures, 'info': r.info})


def run_many(plan, known, verbose=False, timeout_per_case=CASE_TIMEOUT, max_failures=20):
    """plan: [(transport, pair, [seeds])]; each runs in its own process.
    Returns {'count', 'failures': [text], 'info': {counter: n}}. A worker
    stuck past its time is a hang: reported with its case and kernel stacks."""
    q = CTX.Queue()
    procs = []
    Runner.concurrent = len(plan) > 1       # inherited by the forked workers
    for transport, pair, seeds in plan:
        current = CTX.Value('q', -1)
        p = CTX.Process(target=worker, args=(q, current, transport, known, pair, seeds,
                                             verbose, max_failures))
        p.start()
        procs.append((p, current, transport, len(seeds)))
    total = {'count': 0, 'failures': [], 'info': {}}

    def merge(res):
        total['count'] += res['count']
        total['failures'] += res['failures']
        for k, v in res['info'].items():
            if k in total['info'] and k.endswith('_min'):
                v = min(v, total['info'][k])
            elif k in total['info'] and k.endswith('_max'):
                v = max(v, total['info'][k])
            else:
                v += total['info'].get(k, 0)
            total['info'][k] = v

    got = 0
    while got < len(procs):
        try:
            merge(q.get(timeout=1))
            got += 1
            continue
        except Exception:
            pass
        alive = [x for x in procs if x[0].is_alive()]
        if not alive:
            break
        # Each case must end within CASE_TIMEOUT; the worker's alarm turns a
        # slow case into a failure, so a worker stuck longer is in the kernel.
        for p, current, transport, n in alive:
            cur = current.value
            stamp = getattr(p, '_stamp', None)
            if stamp is None or stamp[0] != cur:
                p._stamp = (cur, time.monotonic())
            elif time.monotonic() - stamp[1] > timeout_per_case + 60:
                total['failures'].append(
                    'seed %d (%s): hung for more than %d s; kernel stacks:\n%s\n  replay: %s'
                    % (cur, transport, timeout_per_case + 60, kernel_stacks(p.pid),
                       replay_command(cur, transport, known)))
                p.kill()
    for p, _, _, _ in procs:
        p.join(5)
    while True:
        try:
            merge(q.get(timeout=0.5))
        except Exception:
            break
    return total


def plan_for(count, seed, pty_workers=2, nullmodem_lines=(), nullmodem_share=0.0):
    """Split `count` cases with seeds seed, seed+1, ... between pty workers
    and null-modem lines (nullmodem_share of them on the lines)."""
    seeds = list(range(seed, seed + count))
    nm = int(round(count * nullmodem_share)) if nullmodem_lines else 0
    plan = []
    nm_seeds, pty_seeds = seeds[:nm], seeds[nm:]
    for i, pair in enumerate(nullmodem_lines):
        plan.append(('nullmodem', pair, nm_seeds[i::len(nullmodem_lines)]))
    for i in range(pty_workers):
        plan.append(('pty', 0, pty_seeds[i::pty_workers]))
    return [p for p in plan if p[2]]


STAGES = ['registered', 'refused', 'values', 'iio', 'captured', 'switched', 'written',
          'detached']
# The tolerances, each bounded on its own (a share of the cases it can
# happen in, and at least this many).
LOST_SHARE, LOST_MIN = 0.05, 1              # of the sensors registered
AMBIGUOUS_MAX = 1                           # two identical sensors at once
# Of the switches off a saturated mode: its answers to the keep-alives
# (10 a second, each longer on the line than 100 ms) queue up in the
# emulated sensor's tty for as long as the mode lasts, so that any of
# them may time out; each one is checked on its own (log line, mode).
TIMEOUT_SHARE, TIMEOUT_MIN = 1.0, 1


def verdict(res, count):
    """What is wrong with a run beyond its cases' own failures: the model
    and the driver disagreed on a registration, a stage the generator says
    the cases reach was reached less often than that (less the cases
    excused by a tolerated event), a tolerance exceeded its bound, or a
    null-modem case had no handshake timed on the wire. A list of texts."""
    info = res['info']
    errs = []
    if res['count'] != count:
        errs.append('%d cases run of %d' % (res['count'], count))
    if info.get('registered_despite_model', 0):
        errs.append('%d sensors registered that the model refuses'
                    % info['registered_despite_model'])
    for st in STAGES:
        model = info.get('model_' + st, 0)
        reached = info.get('reached_' + st, 0)
        excused = info.get('excused_miss_' + st, 0)
        if reached < model - excused:
            errs.append('stage %s: reached in %d cases, the generator says %d (%d excused)'
                        % (st, reached, model, excused))
        if count >= 100 and not model:
            errs.append('stage %s: the generator made no case that reaches it' % st)
    lost = sum(v for k, v in info.items() if k.startswith('sensor_lost_'))
    bound = max(LOST_MIN, int(LOST_SHARE * info.get('registered', 0)))
    if lost > bound:
        errs.append('%d sensors lost for want of data, more than %d' % (lost, bound))
    if info.get('iio_ambiguous', 0) > AMBIGUOUS_MAX:
        errs.append('%d IIO devices ambiguous, more than %d'
                    % (info['iio_ambiguous'], AMBIGUOUS_MAX))
    bound = max(TIMEOUT_MIN, int(TIMEOUT_SHARE * info.get('mode_switches_saturated', 0)))
    if info.get('mode_timeout_saturated', 0) > bound:
        errs.append('%d mode switches timed out on saturated lines, more than %d'
                    % (info['mode_timeout_saturated'], bound))
    if info.get('nullmodem_registered', 0) > info.get('wire_handshakes', 0):
        errs.append('%d sensors registered on the null modem, %d handshakes timed on the wire'
                    % (info['nullmodem_registered'], info.get('wire_handshakes', 0)))
    return errs


def ensure_modules():
    if not os.path.isdir('/sys/module/lego_ev3_uart'):
        import subprocess
        for mod in os.environ.get('LEGO_MODULES', '').split():
            if os.path.basename(mod) == 'lego_ev3_uart.ko':
                subprocess.run(['insmod', mod], check=True)
    ev3.load_nullmodem()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split('\n', 2)[2])
    ap.add_argument('--seed', type=int, help='first seed (default: random, printed)')
    ap.add_argument('--count', type=int, default=1)
    ap.add_argument('--transport', choices=['pty', 'nullmodem', 'both'], default='pty')
    ap.add_argument('--known', choices=['avoid', 'include', 'only'], default=DEFAULT_KNOWN)
    ap.add_argument('--workers', type=int, default=1, help='pty worker processes')
    ap.add_argument('-v', '--verbose', action='store_true')
    args = ap.parse_args()
    if os.environ.get('LEGO_IN_VM') != '1':
        print('ev3_fuzz.py runs inside the test VM (tests/vm-run)', file=sys.stderr)
        return 2
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(1 << 40)
    print('ev3fuzz: %d case(s) from seed %d, %s, known bugs: %s'
          % (args.count, seed, args.transport, args.known), flush=True)
    ensure_modules()
    if args.transport == 'pty':
        plan = plan_for(args.count, seed, args.workers)
    elif args.transport == 'nullmodem':
        plan = plan_for(args.count, seed, 0, [0], 1.0)
    else:
        plan = plan_for(args.count, seed, args.workers, [0], 0.1)
    t0 = time.monotonic()
    res = run_many(plan, args.known, args.verbose)
    print('ev3fuzz: %d case(s), %d failed, %.0f s; %s'
          % (res['count'], len(res['failures']), time.monotonic() - t0,
             ' '.join('%s=%d' % kv for kv in sorted(res['info'].items()))), flush=True)
    for f in res['failures']:
        print('ev3fuzz: FAIL %s' % f)
    bad = verdict(res, args.count)
    for f in bad:
        print('ev3fuzz: FAIL (run) %s' % f)
    return 1 if res['failures'] or bad else 0


if __name__ == '__main__':
    sys.exit(main())
