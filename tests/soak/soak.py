#!/usr/bin/env python3
"""Robustness soak of the LEGO drivers: runs inside the test VM.

Usage (in the VM, e.g. through tests/soak/run.sh, which boots it):
  python3 tests/soak/soak.py [--short] [--parts 1,2,3,4,5,6] [--json FILE]
                             [--cycles N] [--fuzz-seconds S] [--race-seconds S]
                             [--unplugs N] [--transactions N] [--no-kmemleak]
                             [--nxt-sequences N] [--nxt-seed N]

Parts (each reports its count and its failures):
  1  EV3 sensor plug/unplug cycles on several null-modem lines at once; each
     cycle checks the sensor registered (right driver) and then went away.
  2  random and mutated byte streams into the discipline (ptys with ldisc 29
     on the slave, and null-modem lines at wrong speeds), while a checker
     reads every sensor's attributes; afterwards a good sensor must still
     register and report the value it sends.
  3  discipline attach/detach (TIOCSETD, close, hangup) racing sysfs and IIO
     readers and mode switches, from several processes.
  4  NXT brick unplugs while clients are mid-transfer: every client must end
     with a clean errno (ENODEV last) in time, the node must go away and come
     back on the next plug.
  5  8 clients hammering one brick: every reply matched to its request.
  7  EV3 generated handshakes (tests/guest/ev3_fuzz.py): --ev3-cases cases from
     --ev3-seed (default random, printed), each through attach, registration,
     every attribute, a buffered capture, mode switches, a WRITE and a detach.
  8  the whole-driver NXT fuzzer (nxt_fuzz.py): random open/write/read/poll/
     ioctl/close sequences from 3 processes, hostile bricks, resets, unplugs.
Then a kmemleak scan (twice): any leak fails the run (--lego-leaks-only: only
leaks whose backtrace names a lego_ module, for runs after other tests).

Prints a summary table; exits 1 if any part failed, 2 on a usage error.
"""
import argparse
import errno
import fcntl
import glob
import json
import multiprocessing
import os
import random
import select
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'guest'))
sys.path.insert(0, os.path.join(HERE, '..', 'emulator'))
import ev3  # noqa: E402
import ev3_sensor as es  # noqa: E402
import nxtdev as nxt  # noqa: E402
import nxt_fuzz  # noqa: E402
from kstacks import kernel_stacks  # noqa: E402

N_TTY, N_LEGOEV3 = 0, 29
TIOCVHANGUP = 0x5437
KMEMLEAK = '/sys/kernel/debug/kmemleak'
IIO = '/sys/bus/iio/devices'
MAX_FAILURES = 20           # failures kept (with text) per part

# errnos a reader may see while a sensor goes away under it
GONE = {errno.ENODEV, errno.ENOENT, errno.ENXIO}
# what a transfer may end in when the brick is pulled mid-transfer
CLEAN_UNPLUG = {errno.ENODEV, errno.ESHUTDOWN, errno.EPROTO, errno.EIO, errno.ETIMEDOUT,
                errno.EPIPE, errno.ECONNRESET}

FULL = dict(cycles=1000, lines=8, fuzz_seconds=600, fuzz_workers=4, race_seconds=180,
            unplugs=500, transactions=500, ev3_cases=10000)
SHORT = dict(cycles=30, lines=4, fuzz_seconds=60, fuzz_workers=3, race_seconds=20,
             unplugs=24, transactions=80, ev3_cases=200)
FULL.update(nxt_sequences=10000, nxt_seed=None)
SHORT.update(nxt_sequences=200, nxt_seed=None)

CTX = multiprocessing.get_context('fork')


class Part:
    def __init__(self, number, name):
        self.number, self.name = number, name
        self.count = 0
        self.failures = 0
        self.messages = []
        self.info = {}
        self.seconds = 0.0

    def fail(self, msg):
        self.failures += 1
        if len(self.messages) < MAX_FAILURES:
            self.messages.append(msg)
        print('soak: part %d: FAIL: %s' % (self.number, msg), flush=True)

    def merge(self, res):
        self.count += res['count']
        self.failures += res['failures']
        for m in res['messages']:
            if len(self.messages) < MAX_FAILURES:
                self.messages.append(m)
        for k, v in res.get('info', {}).items():
            self.info[k] = self.info.get(k, 0) + v

    def as_dict(self):
        return dict(part=self.number, name=self.name, count=self.count, failures=self.failures,
                    messages=self.messages, info=self.info, seconds=round(self.seconds, 1))


def child_result():
    return {'count': 0, 'failures': 0, 'messages': [], 'info': {}}


def child_fail(res, msg):
    res['failures'] += 1
    if len(res['messages']) < MAX_FAILURES:
        res['messages'].append(msg)


def bump(res, key, n=1):
    res['info'][key] = res['info'].get(key, 0) + n



def run_children(part, targets, timeout):
    """Run each (fn, args) in a forked process; fn(res, *args) fills res.
    A child still running after `timeout` seconds is a hang: its kernel
    stacks are reported and it is killed."""
    q = CTX.Queue()

    def wrap(fn, args):
        res = child_result()
        try:
            fn(res, *args)
        except Exception:
            child_fail(res, 'exception: ' + traceback.format_exc(limit=4))
        q.put(res)

    procs = [CTX.Process(target=wrap, args=(fn, args)) for fn, args in targets]
    for p in procs:
        p.start()
    deadline = time.monotonic() + timeout
    got = 0
    while got < len(procs) and time.monotonic() < deadline:
        try:
            part.merge(q.get(timeout=1))
            got += 1
        except Exception:
            pass
    for p in procs:
        p.join(max(0.1, deadline - time.monotonic()))
        if p.is_alive():
            part.fail('process %d hung (> %d s); kernel stacks:\n%s'
                      % (p.pid, timeout, kernel_stacks(p.pid)))
            p.kill()
            p.join(5)
        elif p.exitcode:
            part.fail('process %d exited with %d' % (p.pid, p.exitcode))
    while got < len(procs):
        try:
            part.merge(q.get(timeout=1))
            got += 1
        except Exception:
            break


# ---- modules ---------------------------------------------------------------

def module_path(name):
    for mod in os.environ.get('LEGO_MODULES', '').split():
        if os.path.basename(mod) == name + '.ko':
            return mod
    raise LookupError('%s.ko not in LEGO_MODULES (run in the test VM)' % name)


def ensure_modules(pairs):
    if not os.path.isdir('/sys/module/lego_ev3_uart'):
        subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)
    if not os.path.isdir('/sys/module/lego_nullmodem'):
        ko = os.path.join(os.environ['LEGO_BUILD'], 'tests/kmod/lego_nullmodem.ko')
        subprocess.run(['insmod', ko, 'pairs=%d' % pairs], check=True)
    nxt.load_driver()


def nullmodem_pairs():
    with open('/sys/module/lego_nullmodem/parameters/pairs') as f:
        return int(f.read())


# ---- sanity of what the EV3 driver reports ---------------------------------

def check_sensor(path, res):
    """check_sensor_dir() on the sensor now called `path`."""
    try:
        sd = ev3.SensorDir(path)
    except OSError as e:
        if e.errno in GONE:
            bump(res, 'reads_raced_removal')
            return None
        raise
    with sd:
        return check_sensor_dir(sd, res)


def check_sensor_dir(sd, res):
    """Read every attribute of one sensor (an ev3.SensorDir, so that a
    sensor that goes and a new one that takes its name cannot mix); insane
    values are failures. The sensor may vanish meanwhile (ENODEV, ENOENT):
    that ends the check."""
    path = sd.path
    attr = sd.read
    try:
        driver = attr('driver_name')
        address = attr('address')
        modes = attr('modes').split()
        mode = attr('mode')
        num = int(attr('num_values'))
        dec = int(attr('decimals'))
        attr('units')
        values = [int(attr('value%d' % i)) for i in range(num)]
        attr('bin_data', binary=True)
    except OSError as e:
        if e.errno in GONE:
            bump(res, 'reads_raced_removal')
            return None
        child_fail(res, '%s: read failed: %s' % (path, os.strerror(e.errno)))
        return None
    except ValueError as e:
        child_fail(res, '%s: not a number: %s' % (path, e))
        return None
    bad = []
    if not driver or not address:
        bad.append('empty driver_name or address')
    if not modes or mode not in modes:
        bad.append('mode %r not in modes %r' % (mode, modes))
    if not 0 <= num <= 32:
        bad.append('num_values %d' % num)
    if not 0 <= dec <= 15:
        bad.append('decimals %d' % dec)
    if any(abs(v) > 2 ** 31 for v in values):
        bad.append('values %r' % values)
    if bad:
        child_fail(res, '%s (%s): %s' % (path, driver, '; '.join(bad)))
    bump(res, 'sensor_reads')
    return modes


def check_iio(dev, res):
    name = '?'
    try:
        name = ev3.read_attr(dev, 'name')
        for raw in glob.glob(dev + '/in_*_raw'):
            with open(raw) as f:
                int(f.read())
            bump(res, 'iio_reads')
    except OSError as e:
        if e.errno in GONE or e.errno == errno.EBUSY:
            return
        child_fail(res, '%s: read failed: %s' % (dev, os.strerror(e.errno)))
    except ValueError as e:
        child_fail(res, '%s (%s): not a number: %s' % (dev, name, e))


def sensors():
    return glob.glob(ev3.CLASS + '/sensor*')


def set_ldisc(fd, num):
    fcntl.ioctl(fd, termios.TIOCSETD, struct.pack('i', num))


def quiet_thread_errors():
    """Emulator threads whose tty is closed under them die with OSError:
    expected in the races, not worth a traceback."""
    def hook(args):
        if not issubclass(args.exc_type, OSError):
            sys.__excepthook__(args.exc_type, args.exc_value, args.exc_traceback)
    threading.excepthook = hook


def good_sensor_works(res, kind='us', value=123):
    """A well-behaved sensor on a fresh pty registers and reports its value."""
    master, slave = os.openpty()
    address = 'pts' + os.ttyname(slave).split('/')[-1]
    emu = None
    try:
        set_ldisc(slave, N_LEGOEV3)
        emu = es.EmulatedSensor(master, kind, boot_delay=0.05)
        emu.start()
        path = ev3.find_sensor(address, timeout=20)
        if not path:
            child_fail(res, 'a good %s sensor did not register on %s' % (kind, address))
            return False
        emu.set_values(0, [value])
        got = ev3.wait_value(path, 0, value, timeout=5)
        if got != value:
            child_fail(res, 'a good %s sensor reports %r, not %d' % (kind, got, value))
            return False
        return True
    finally:
        os.close(slave)
        if emu:
            emu.stop()
        os.close(master)


# ---- part 1: plug/unplug cycles --------------------------------------------

KINDS = ['color', 'us', 'gyro', 'ir', 'fcl-humidity', 'gyro-old']


def plug_worker(res, pair, cycles, seed):
    line = ev3.Line(pair)
    rng = random.Random(seed)
    line.attach()
    kind = KINDS[pair % len(KINDS)]
    want = es.SENSORS[kind].driver
    emu = line.plug(kind, boot_delay=0.05, seed=seed)
    last = None
    try:
        for i in range(cycles):
            # Held open: the name may be taken by another line's sensor
            # as soon as this one goes.
            sd = ev3.open_sensor(line.address, timeout=20)
            if not sd:
                child_fail(res, '%s cycle %d: %s did not register (%s)'
                           % (line.address, i, kind, emu.events[-4:]))
                emu.unplug()
                time.sleep(1.5)
                emu.plug()
                continue
            path = sd.path
            try:
                driver = sd.read('driver_name')
            except OSError as e:
                if e.errno not in GONE:
                    raise
                # Lost again at once (an emulator starved of CPU in a slow
                # guest misses its keep-alives): nothing to check.
                bump(res, 'lost_before_read')
                driver = None
            if driver is not None and driver != want:
                child_fail(res, '%s cycle %d: driver_name %r, want %r'
                           % (line.address, i, driver, want))
            if last == path:
                bump(res, 'same_name_reused')
            # Sometimes read and switch mode before pulling the cable.
            if rng.random() < 0.2:
                check_sensor_dir(sd, res)
            emu.unplug()
            with sd:
                if not sd.wait_gone(10):
                    child_fail(res, '%s cycle %d: %s still there 10 s after unplug'
                               % (line.address, i, path))
            res['count'] += 1
            last = path
            emu.plug()
    finally:
        line.close()


def part_plug(p, cycles, lines):
    pairs = nullmodem_pairs()
    lines = max(1, min(lines, pairs))
    per = [cycles // lines + (1 if i < cycles % lines else 0) for i in range(lines)]
    p.info['lines'] = lines
    # About 3 s a cycle; a hang is anything much longer.
    run_children(p, [(plug_worker, (i, per[i], 100 + i)) for i in range(lines)],
                 timeout=60 + 20 * max(per))


# ---- part 2: random and mutated streams ------------------------------------

def mutate(data, rng):
    data = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(5)
        if not data:
            break
        i = rng.randrange(len(data))
        if op == 0:                             # bit flips
            for _ in range(rng.randint(1, 3)):
                j = rng.randrange(len(data))
                data[j] ^= 1 << rng.randrange(8)
        elif op == 1:                           # truncation
            del data[i:]
        elif op == 2:                           # duplication
            j = min(len(data), i + rng.randint(1, 40))
            data[i:i] = data[i:j]
        elif op == 3:                           # deletion
            del data[i:i + rng.randint(1, 20)]
        else:                                   # insertion
            data[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 20)))
    return bytes(data)


def random_data_msgs(rng, n):
    out = b''
    for _ in range(n):
        mode = rng.randrange(8)
        size = 1 << rng.randrange(6)
        payload = bytes(rng.randrange(256) for _ in range(size))
        msg = es.data_msg(mode, payload, bad_checksum=rng.random() < 0.2)
        out += msg
    return out


def stream_for(kind, rng):
    """One test stream: (bytes to send, bytes to send after a pause in which
    the discipline may ACK a handshake)."""
    sdef = es.SENSORS[rng.choice(sorted(es.SENSORS))]
    hs = es.handshake(sdef)
    if kind == 'random':
        return bytes(rng.randrange(256) for _ in range(rng.randint(1, 600))), b''
    if kind == 'mutated':
        return mutate(hs, rng), mutate(random_data_msgs(rng, 10), rng)
    if kind == 'garbage-after-ack':
        # A valid sensor that suddenly sends garbage and bad messages.
        tail = bytes(rng.randrange(256) for _ in range(rng.randint(1, 300)))
        return hs, random_data_msgs(rng, 20) + tail
    # A valid handshake, then valid DATA of random modes and sizes.
    m = rng.randrange(len(sdef.modes))
    mode = sdef.modes[m]
    vals = [rng.randrange(-100, 100) for _ in range(mode.n)]
    return hs, b''.join(es.data_msg(m, es.pack_values(mode, vals)) for _ in range(30))


def drain(fd):
    try:
        while select.select([fd], [], [], 0)[0]:
            if not os.read(fd, 4096):
                break
    except OSError:
        pass


def write_all(fd, data, deadline):
    view = memoryview(data)
    while view and time.monotonic() < deadline:
        try:
            view = view[os.write(fd, view[:256]):]
        except BlockingIOError:
            drain(fd)
            select.select([], [fd], [], 0.1)


def pty_fuzz_worker(res, seconds, seed):
    rng = random.Random(seed)
    deadline = time.monotonic() + seconds
    kinds = ['random', 'mutated', 'garbage-after-ack', 'valid-data']
    while time.monotonic() < deadline:
        master, slave = os.openpty()
        try:
            set_ldisc(slave, N_LEGOEV3)
            os.set_blocking(master, False)
            for _ in range(rng.randint(1, 30)):
                if time.monotonic() > deadline:
                    break
                kind = rng.choice(kinds)
                first, second = stream_for(kind, rng)
                write_all(master, first, deadline)
                # Give the discipline time to ACK a handshake.
                time.sleep(rng.choice([0, 0.005, 0.03, 0.1]))
                drain(master)
                write_all(master, second, deadline)
                drain(master)
                res['count'] += 1
                bump(res, 'bytes', len(first) + len(second))
                bump(res, 'streams_' + kind)
                if rng.random() < 0.1:
                    time.sleep(rng.uniform(0.1, 1.2))    # let keep-alives time out
                    drain(master)
        finally:
            # Detach in different ways: back to N_TTY, or by closing.
            if rng.random() < 0.5:
                try:
                    set_ldisc(slave, N_TTY)
                except OSError:
                    pass
            os.close(slave)
            os.close(master)
            bump(res, 'attach_cycles')


SPEEDS = sorted(es.BAUD)


def nullmodem_fuzz_worker(res, pair, seconds, seed):
    """Speed mismatches: valid and mutated handshakes and data sent at the
    wrong speed through the null modem, which garbles them as a wire would."""
    rng = random.Random(seed)
    deadline = time.monotonic() + seconds
    line = ev3.Line(pair)
    line.attach()
    far = os.open(line.far, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        attrs = termios.tcgetattr(far)
        attrs[0] = attrs[1] = attrs[3] = 0
        attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL
        while time.monotonic() < deadline:
            sdef = es.SENSORS[rng.choice(sorted(es.SENSORS))]
            hs = es.handshake(sdef)
            case = rng.randrange(4)
            if case == 0:       # handshake at a wrong speed
                speeds, data = [rng.choice(SPEEDS[1:])], [hs]
            elif case == 1:     # good handshake, data at a wrong speed
                speeds, data = [2400, rng.choice(SPEEDS)], [hs, random_data_msgs(rng, 40)]
            elif case == 2:     # mutated handshake at 2400, then a break
                speeds, data = [2400], [mutate(hs, rng)]
            else:               # random speed, random bytes
                speeds, data = [rng.choice(SPEEDS)], [bytes(rng.randrange(256)
                                                            for _ in range(200))]
            for baud, chunk in zip(speeds, data):
                attrs[4] = attrs[5] = es.BAUD[baud]
                termios.tcsetattr(far, termios.TCSANOW, attrs)
                write_all(far, chunk, deadline)
                # Wait for the null modem to pace it out, answering nothing.
                while time.monotonic() < deadline:
                    try:
                        termios.tcdrain(far)
                        break
                    except OSError:
                        time.sleep(0.05)
                time.sleep(0.02)
                drain(far)
            if case == 2:
                termios.tcsendbreak(far, 0)
            res['count'] += 1
            bump(res, 'wrong_speed_streams')
    finally:
        os.close(far)
        line.close()


def checker(res, stop):
    while not stop.is_set():
        for path in sensors():
            check_sensor(path, res)
        for dev in glob.glob(IIO + '/iio:device*'):
            check_iio(dev, res)
        stop.wait(0.3)


def checker_worker(res, seconds):
    """While the streams run: read every sensor's attributes and IIO values,
    and keep a good sensor on its own pty whose values must always be ones it
    sent (or 0 before its first DATA). Afterwards a fresh good sensor must
    register and report its value."""
    stop = threading.Event()
    t = threading.Timer(seconds, stop.set)
    t.start()
    master, slave = os.openpty()
    address = 'pts' + os.ttyname(slave).split('/')[-1]
    set_ldisc(slave, N_LEGOEV3)
    emu = es.EmulatedSensor(master, 'us', boot_delay=0.05)
    emu.start()
    sent = {0}
    value = 1000
    try:
        while not stop.is_set():
            for path in sensors():
                check_sensor(path, res)
            for dev in glob.glob(IIO + '/iio:device*'):
                check_iio(dev, res)
            sd = ev3.open_sensor(address, timeout=0.2)
            if sd:
                try:
                    with sd:
                        got = int(sd.read('value0'))
                except OSError as e:
                    if e.errno not in GONE:
                        child_fail(res, 'good sensor: value0: %s' % os.strerror(e.errno))
                    got = None
                if got is not None and got not in sent:
                    child_fail(res, 'good sensor reports %d, never sent (sent %d..%d)'
                               % (got, min(sent), max(sent)))
                elif got == value:
                    bump(res, 'good_sensor_values')
                value = 1000 + (value - 999) % 1500
                sent.add(value)
                emu.set_values(0, [value])
            else:
                bump(res, 'good_sensor_not_registered')
            stop.wait(0.3)
    finally:
        os.close(slave)
        emu.stop()
        os.close(master)
    if good_sensor_works(res):
        bump(res, 'good_sensor_after')


def part_fuzz_concurrent(p, seconds, workers):
    """Streams into ptys and a null modem, and the sanity checker, at the
    same time; then a good sensor must still work."""
    quiet_thread_errors()
    pairs = nullmodem_pairs()
    targets = [(pty_fuzz_worker, (seconds, 1000 + i)) for i in range(workers)]
    targets.append((nullmodem_fuzz_worker, (pairs - 1, seconds, 2000)))
    targets.append((checker_worker, (seconds,)))
    run_children(p, targets, timeout=seconds + 180)


# ---- part 3: attach/detach racing readers and mode switches -----------------

def attacher(res, seconds, seed):
    quiet_thread_errors()
    rng = random.Random(seed)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        master, slave = os.openpty()
        emu = None
        closed = set()
        try:
            set_ldisc(slave, N_LEGOEV3)
            emu = es.EmulatedSensor(master, rng.choice(KINDS), boot_delay=0.01,
                                    seed=rng.randrange(1 << 30))
            emu.start()
            time.sleep(rng.choice([0, 0.01, 0.1, 0.3, 0.6, 1.0, 2.0]))
            how = rng.randrange(4)
            if how == 0:
                set_ldisc(slave, N_TTY)          # detach, tty stays open
                bump(res, 'detach_setd')
            elif how == 1:
                os.close(slave)                  # the discipline stays till the master goes
                closed.add(slave)
                bump(res, 'detach_close')
            elif how == 2:
                fcntl.ioctl(slave, TIOCVHANGUP)  # hangup: ldisc reset to N_TTY
                bump(res, 'detach_hangup')
            else:
                set_ldisc(slave, N_LEGOEV3)      # re-set the same discipline
                set_ldisc(slave, N_TTY)
                bump(res, 'detach_reset')
            res['count'] += 1
        except OSError as e:
            if e.errno not in (errno.EIO,):
                child_fail(res, 'attach/detach: %s' % os.strerror(e.errno))
        finally:
            if emu:
                emu.stopping.set()
            for fd in (slave, master):
                if fd not in closed:
                    os.close(fd)
            if emu:
                emu.join(5)
                if emu.is_alive():
                    child_fail(res, 'emulator thread stuck after detach')


def reader(res, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for path in sensors():
            check_sensor(path, res)
        for dev in glob.glob(IIO + '/iio:device*'):
            check_iio(dev, res)
        bump(res, 'reader_sweeps')


def switcher(res, seconds, seed):
    rng = random.Random(seed)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        paths = sensors()
        if not paths:
            time.sleep(0.02)
            continue
        path = rng.choice(paths)
        sd = None
        try:
            # Held open, so the modes read and the mode written are of
            # one sensor even if its name is reused meanwhile.
            sd = ev3.SensorDir(path)
            modes = sd.read('modes').split()
            sd.write('mode', rng.choice(modes))
            bump(res, 'mode_switches')
        except OSError as e:
            if e.errno in GONE or e.errno in (errno.ETIMEDOUT, errno.EINTR):
                bump(res, 'switch_' + errno.errorcode[e.errno])
            else:
                child_fail(res, '%s: mode write: %s' % (path, os.strerror(e.errno)))
        finally:
            if sd:
                sd.close()


def part_race(p, seconds):
    targets = [(attacher, (seconds, 3000 + i)) for i in range(4)]
    targets += [(reader, (seconds,)) for _ in range(2)]
    targets += [(switcher, (seconds, 4000 + i)) for i in range(2)]
    run_children(p, targets, timeout=seconds + 120)


# ---- part 4: brick unplugs mid-transfer -------------------------------------

VERSIONS_REPLY = b'\x02\x88\x00\x7c\x01\x1d\x01'


def brick_unplug_loop(p, udc, serial, cycles, seed, lock):
    rng = random.Random(seed)
    brick = nxt.Brick(udc, serial)
    for i in range(cycles):
        try:
            brick.plug(timeout=20)
        except AssertionError as e:
            with lock:
                p.fail('%s cycle %d: the brick did not come back: %s' % (udc, i, e))
            brick.unplug()
            time.sleep(1)
            continue
        results = []
        started = threading.Event()

        def client(k):
            errs, ok = [], 0
            try:
                f = brick.open()
            except OSError as e:
                results.append((k, [e.errno], 0, None))
                return
            try:
                nxt.set_timeout(f, 2000)
                while True:
                    if k % 2:
                        err, reply = nxt.transact(f, b'\x01\x88')
                        if not err and reply != VERSIONS_REPLY:
                            results.append((k, errs, ok, 'wrong reply %r' % reply))
                            return
                    else:
                        try:
                            os.write(f, b'\x01\x88')
                            reply, err = os.read(f, 64), 0
                            if reply != VERSIONS_REPLY:
                                results.append((k, errs, ok, 'wrong reply %r' % reply))
                                return
                        except OSError as e:
                            err = e.errno
                    started.set()
                    if err:
                        errs.append(err)
                        if err == errno.ENODEV:
                            break
                        if err not in CLEAN_UNPLUG:
                            break
                    else:
                        ok += 1
                results.append((k, errs, ok, None))
            finally:
                os.close(f)

        threads = [threading.Thread(target=client, args=(k,), daemon=True) for k in range(3)]
        for t in threads:
            t.start()
        started.wait(5)
        time.sleep(rng.uniform(0, 0.3))
        brick.unplug()
        t0 = time.monotonic()
        for t in threads:
            t.join(max(0.1, 15 - (time.monotonic() - t0)))
        with lock:
            p.count += 1
            if any(t.is_alive() for t in threads):
                p.fail('%s cycle %d: a client hung after the unplug' % (udc, i))
            for k, errs, ok, bad in results:
                p.info['transfers_ok'] = p.info.get('transfers_ok', 0) + ok
                for e in errs:
                    name = 'errno_' + errno.errorcode.get(e, str(e))
                    p.info[name] = p.info.get(name, 0) + 1
                if bad:
                    p.fail('%s cycle %d client %d: %s' % (udc, i, k, bad))
                elif not errs or errs[-1] != errno.ENODEV:
                    p.fail('%s cycle %d client %d: ended with %s, not ENODEV'
                           % (udc, i, k, [errno.errorcode.get(e, e) for e in errs]))
                elif any(e not in CLEAN_UNPLUG for e in errs):
                    p.fail('%s cycle %d client %d: unexpected errno %s'
                           % (udc, i, k, [errno.errorcode.get(e, e) for e in errs]))
        if not brick.wait_gone(10):
            with lock:
                p.fail('%s cycle %d: the node outlived the brick' % (udc, i))


def brick_unplug_thread(p, udc, serial, cycles, seed, lock):
    try:
        brick_unplug_loop(p, udc, serial, cycles, seed, lock)
    except Exception:
        with lock:
            p.fail('%s: exception: %s' % (udc, traceback.format_exc(limit=6)))


def part_unplug(p, unplugs):
    lock = threading.Lock()
    # The brick emulator installs its signal handler from the main thread.
    nxt.nxt_brick._ensure_wake_handler()
    half = [unplugs - unplugs // 2, unplugs // 2]
    specs = [('dummy_udc.0', '0016530A0B01'), ('dummy_udc.1', '0016530A0B02')]
    threads = [threading.Thread(target=brick_unplug_thread,
                                args=(p, udc, serial, n, 5000 + i, lock), daemon=True)
               for i, ((udc, serial), n) in enumerate(zip(specs, half)) if n]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60 + 30 * max(half))
        if t.is_alive():
            p.fail('the unplug loop hung')
    if p.count != unplugs:
        p.fail('%d unplugs done of %d' % (p.count, unplugs))


# ---- part 5: 8 clients on one brick -----------------------------------------

def hammer_client(res, node, index, count, start):
    os.nice(5)
    f = os.open(node, os.O_RDWR)
    start.wait()
    try:
        nxt.set_timeout(f, 5000)
        for i in range(count):
            kind, err, ok = nxt.mixed_request(f, index, i)
            if err:
                bump(res, 'lost_' + errno.errorcode.get(err, str(err)))
                child_fail(res, 'client %d request %d: %s' % (index, i, os.strerror(err)))
            elif not ok:
                bump(res, 'mismatched')
                child_fail(res, 'client %d request %d (kind %d): mismatched reply'
                           % (index, i, kind))
            res['count'] += 1
    finally:
        os.close(f)


def part_hammer(p, per_client, clients=8):
    brick = nxt.Brick('dummy_udc.0', '0016530A0B03')
    brick.plug(timeout=20)
    try:
        start = CTX.Event()
        before = brick.emu.commands
        lost_before = brick.emu.replies_lost
        targets = [(hammer_client, (brick.node, i, per_client, start)) for i in range(clients)]
        threading.Timer(2, start.set).start()
        t0 = time.monotonic()
        run_children(p, targets, timeout=120 + per_client * clients * 0.2)
        elapsed = time.monotonic() - t0
        p.info['transactions_per_s'] = round(p.count / max(elapsed, 0.1))
        if brick.emu.commands - before != clients * per_client:
            p.fail('the brick got %d commands, the clients sent %d'
                   % (brick.emu.commands - before, clients * per_client))
        if brick.emu.replies_lost != lost_before:
            p.fail('the brick dropped %d unread replies' % (brick.emu.replies_lost - lost_before))
    finally:
        brick.unplug()
        if not brick.wait_gone(10):
            p.fail('the node outlived the brick')


# ---- part 7: generated EV3 handshakes -------------------------------------------

def part_ev3_fuzz(p, cases, seed):
    import ev3_fuzz
    if seed is None:
        seed = random.SystemRandom().randrange(1 << 40)
    print('soak: part 7: %d cases from seed %d (--ev3-seed %d to run them again), '
          'known bugs: %s' % (cases, seed, seed, ev3_fuzz.DEFAULT_KNOWN), flush=True)
    p.info['seed'] = seed
    plan = ev3_fuzz.plan_for(cases, seed, pty_workers=3, nullmodem_lines=[0, 1],
                             nullmodem_share=0.02)
    res = ev3_fuzz.run_many(plan, ev3_fuzz.DEFAULT_KNOWN)
    p.count += res['count']
    for k, v in res['info'].items():
        p.info[k] = p.info.get(k, 0) + v
    for f in res['failures']:
        p.fail(f)
    if res['count'] < cases:
        p.fail('%d cases run of %d' % (res['count'], cases))


# ---- part 8: the whole-driver NXT fuzzer -------------------------------------

def part_nxt_fuzz(p, sequences, seed):
    """nxt_fuzz.py's run of `sequences` sequences (seed: random, printed)."""
    if seed is None:
        seed = random.SystemRandom().randrange(1 << 32)
    fz = nxt_fuzz.run(sequences, seed, workers=3, per_epoch=100,
                      log=lambda m: print('soak: part 8: ' + m, flush=True))
    p.count = fz.sequences
    p.info.update(seed='%#x' % seed, epochs=fz.epochs, calls=fz.calls,
                  **{k: v for k, v in fz.info.items() if not k.startswith('profile_')})
    for m in fz.failures:
        p.fail('%s (run seed %#x)' % (m, seed))
    if fz.failed_epochs:
        print('soak: part 8: replay: ' + fz.replay_command(fz.failed_epochs[0]), flush=True)


# ---- kmemleak ---------------------------------------------------------------

def kmemleak_available():
    return os.access(KMEMLEAK, os.W_OK)


def kmemleak_clear():
    """Forget what is there now (boot-time objects), so that only leaks made
    by the soak are reported."""
    if kmemleak_available():
        with open(KMEMLEAK, 'w') as f:
            f.write('scan')
        with open(KMEMLEAK, 'w') as f:
            f.write('clear')


def kmemleak_scan(lego_only=False):
    """Scan twice (an object is reported once it stayed unreferenced over two
    scans) and return the reports: all, or only those whose backtrace names
    a lego_ module."""
    for _ in range(2):
        with open(KMEMLEAK, 'w') as f:
            f.write('scan')
        time.sleep(6)
    with open(KMEMLEAK) as f:
        text = f.read()
    blocks, cur = [], []
    for line in text.splitlines():
        if line.startswith('unreferenced object') and cur:
            blocks.append('\n'.join(cur))
            cur = []
        cur.append(line)
    if cur:
        blocks.append('\n'.join(cur))
    if lego_only:
        blocks = [b for b in blocks if 'lego_' in b]
    return blocks


# ---- main ----------------------------------------------------------------------

def run(parts, params, lego_leaks_only=False, kmemleak=True):
    results = []
    names = {1: 'EV3 plug/unplug cycles', 2: 'random/mutated streams',
             3: 'attach/detach races', 4: 'brick unplugs mid-transfer',
             5: '8 clients, one brick', 7: 'EV3 generated handshakes',
             8: 'NXT whole-driver fuzzer'}
    for n in parts:
        p = Part(n, names[n])
        t0 = time.monotonic()
        print('soak: part %d: %s ...' % (n, p.name), flush=True)
        try:
            if n == 1:
                part_plug(p, params['cycles'], params['lines'])
            elif n == 2:
                part_fuzz_concurrent(p, params['fuzz_seconds'], params['fuzz_workers'])
            elif n == 3:
                part_race(p, params['race_seconds'])
            elif n == 4:
                part_unplug(p, params['unplugs'])
            elif n == 5:
                part_hammer(p, params['transactions'])
            elif n == 7:
                part_ev3_fuzz(p, params['ev3_cases'], params.get('ev3_seed'))
            elif n == 8:
                part_nxt_fuzz(p, params['nxt_sequences'], params['nxt_seed'])
        except Exception:
            p.fail('exception: ' + traceback.format_exc(limit=6))
        p.seconds = time.monotonic() - t0
        print('soak: part %d: %d done, %d failed, %.0f s %s' % (n, p.count, p.failures,
                                                                p.seconds, p.info), flush=True)
        results.append(p)
    if kmemleak:
        p = Part(max(names) + 1, 'kmemleak scan')
        t0 = time.monotonic()
        if not kmemleak_available():
            p.fail('%s is not writable (kmemleak missing or debugfs not mounted)' % KMEMLEAK)
        else:
            leaks = kmemleak_scan(lego_leaks_only)
            p.count = 1
            for b in leaks:
                p.fail('leak:\n' + b)
                print(b, flush=True)
            p.info['leaks'] = len(leaks)
        p.seconds = time.monotonic() - t0
        results.append(p)
    return results


def table(results):
    lines = ['%-4s %-30s %8s %8s %8s' % ('part', 'what', 'count', 'failed', 'seconds')]
    for p in results:
        lines.append('%-4d %-30s %8d %8d %8.0f' % (p.number, p.name, p.count, p.failures,
                                                  p.seconds))
        for k in sorted(p.info):
            lines.append('%4s   %-28s %8s' % ('', k, p.info[k]))
    return '\n'.join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split('\n', 2)[2])
    ap.add_argument('--short', action='store_true', help='a few dozen cycles each, 60 s of streams')
    ap.add_argument('--parts', default='1,2,3,4,5,7,8')
    ap.add_argument('--json', metavar='FILE', help='also write the results as JSON')
    ap.add_argument('--cycles', type=int)
    ap.add_argument('--lines', type=int)
    ap.add_argument('--fuzz-seconds', type=float)
    ap.add_argument('--race-seconds', type=float)
    ap.add_argument('--unplugs', type=int)
    ap.add_argument('--transactions', type=int, help='per client, in part 5')
    ap.add_argument('--ev3-cases', type=int, help='generated EV3 handshakes, in part 7')
    ap.add_argument('--ev3-seed', type=lambda v: int(v, 0), help='first seed of part 7 (default: random)')
    ap.add_argument('--nxt-sequences', type=int, help='part 8: sequences (10000)')
    ap.add_argument('--nxt-seed', type=lambda v: int(v, 0), help='part 8: run seed')
    ap.add_argument('--no-kmemleak', action='store_true')
    ap.add_argument('--lego-leaks-only', action='store_true')
    args = ap.parse_args()
    if os.environ.get('LEGO_IN_VM') != '1':
        print('soak.py runs inside the test VM: use tests/soak/run.sh', file=sys.stderr)
        return 2
    try:
        parts = sorted({int(x) for x in args.parts.split(',')})
        assert parts and all(1 <= x <= 5 or x in (7, 8) for x in parts)
    except (ValueError, AssertionError):
        print('soak.py: --parts takes numbers 1 to 5, 7 and 8, e.g. 1,3', file=sys.stderr)
        return 2
    params = dict(SHORT if args.short else FULL, ev3_seed=None)
    for k in params:
        v = getattr(args, k, None)
        if v is not None:
            params[k] = v
    ensure_modules(pairs=8)
    if not args.no_kmemleak and not args.lego_leaks_only:
        kmemleak_clear()
    t0 = time.monotonic()
    results = run(parts, params, args.lego_leaks_only, not args.no_kmemleak)
    total = time.monotonic() - t0
    print()
    print(table(results))
    failed = sum(p.failures for p in results)
    print('soak: %s in %.0f s (%s), %d failure(s)' % ('PASS' if not failed else 'FAIL', total,
                                                     'short' if args.short else 'full', failed))
    for p in results:
        for m in p.messages:
            print('part %d: %s' % (p.number, m))
    if args.json:
        with open(args.json, 'w') as f:
            json.dump({'short': args.short, 'params': params, 'seconds': round(total),
                       'parts': [p.as_dict() for p in results]}, f, indent=1)
    return 1 if failed else 0


if __name__ == '__main__':
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    sys.exit(main())
