"""Fault injection on the drivers' failure paths (issue 29).

Each sweep makes the Nth fault-injectable call of one operation fail, for
N = 1, 2, ... until the operation completes without a failure injected
(at most MAX_N), under the test kernel's KASAN, lockdep and kmemleak:

- EV3: loading lego_ev3_uart, attaching the discipline to a null-modem
  tty, and a sensor's registration after its handshake (class device and
  IIO device);
- NXT: loading the core lego_nxt and lego_nxt_usb, the probe of an
  emulated brick, an open of /dev/nxtN with one transaction, and attaching
  lego_nxt_serial to a pty.

Only slab allocations can fail (the test kernel has CONFIG_FAILSLAB, no
FAIL_PAGE_ALLOC), and only those made with our code on the stack:
failslab's stack filter (require-start, require-end) is set to the
module's text; while the module is not loaded yet, to do_one_initcall(),
which is on the stack exactly while a module's init function runs (not
while the module loader allocates for itself: failing those makes the
kernel dump a stack, which the console scan takes for a splat, and tests
the loader, not us); for the registration, to ev3_uart_sensor_create().
kmemleak's own records of each allocation are left out (kmemleak_text()).

How the Nth call is made to fail:

- in the test's own thread (insmod by finit_module(), TIOCSETD, a write
  to the driver's "bind" file, open() and ioctl() of /dev/nxtN):
  /proc/thread-self/fail-nth, which honours failslab's stack filter. The
  probe runs in the writer of "bind"; the USB core's hub thread runs the
  same probe when a brick is plugged in, out of fail-nth's reach;
- in a kernel worker (the registration runs in the port's work, ev3_uart_ack()):
  failslab with probability 100, times 1 and an interval that makes its
  call counter reach a multiple of it at the Nth call (Counter).

After each injected failure: the operation failed with a clean errno, or
went on without the part that failed (a log line says so), or the kernel's
code absorbed the failure; the kernel log has no splat (the console scan's
patterns, tests/scan-console.py); nothing is left (the operation works
again without injection; for the registration, see its test). At the end
the modules unload and load again, and kmemleak finds no leak that names
our modules. Each sweep prints (and records in the JUnit properties) the N
it reached, the failures injected, what came of them, and its time.
"""
import ctypes
import errno
import fcntl
import glob
import importlib.util
import os
import platform
import struct
import termios
import threading
import time

import pytest

import ev3
import nxtdev as nxt
import tracing
from conftest import loaded, module_path, wait_for
from ev3 import ev3_sensor
from kmsg import Kmsg

MAX_N = 400
DEBUGFS = '/sys/kernel/debug'
FAILSLAB = DEBUGFS + '/failslab'
KMEMLEAK = DEBUGFS + '/kmemleak'
EV3 = 'lego_ev3_uart'
NXT = 'lego_nxt_usb'
NXT_CORE = 'lego_nxt'
NXT_SERIAL = 'lego_nxt_serial'
N_TTY, N_LEGOEV3, N_LEGONXT = 0, 29, 8
SERIAL = '0016530FA017'
VERSIONS_REPLY = b'\x02\x88\x00\x7c\x01\x1d\x01'     # firmware 1.29

_scan = importlib.util.spec_from_file_location(
    'scan_console', os.path.join(os.path.dirname(__file__), '..', 'scan-console.py'))
scan_console = importlib.util.module_from_spec(_scan)
_scan.loader.exec_module(scan_console)


# ---- the kernel's fault injection ----------------------------------------

def _write(path, value):
    with open(path, 'w') as f:
        f.write(str(value))


def _read(path):
    with open(path) as f:
        return f.read().strip()


class Failslab:
    """/sys/kernel/debug/failslab, set up for the sweeps and put back as it
    was by restore()."""

    KNOBS = ('probability', 'interval', 'times', 'space', 'verbose', 'task-filter',
             'ignore-gfp-wait', 'cache-filter', 'stacktrace-depth', 'require-start',
             'require-end', 'reject-start', 'reject-end')

    def __init__(self):
        self.saved = {k: _read(os.path.join(FAILSLAB, k)) for k in self.KNOBS}
        self.fds = {k: os.open(os.path.join(FAILSLAB, k), os.O_RDWR) for k in self.KNOBS}
        self.now = {}
        # Off first; then sleeping allocations too (GFP_KERNEL is most of
        # ours), no message (verbose 2 dumps a stack, which the console
        # scan takes for a splat), every task, the whole stack.
        self.set(probability=0, times=1, interval=1, space=0, verbose=0,
                 task_filter='N', ignore_gfp_wait='N', cache_filter='N',
                 stacktrace_depth=32, reject_start=0, reject_end=0)

    def set(self, **knobs):
        """Write knobs in the order given (times and interval are written
        even if unchanged: the kernel changes times)."""
        for k, v in knobs.items():
            k = k.replace('_', '-')
            if self.now.get(k) != str(v) or k in ('times', 'interval'):
                # debugfs's attribute files cannot seek; a write takes
                # the whole value, wherever the file is.
                os.write(self.fds[k], str(v).encode())
                self.now[k] = str(v)

    def get(self, knob):
        return int(_read(os.path.join(FAILSLAB, knob)), 0)

    def require(self, start, end):
        """Fail only calls with a return address in [start, end) on the
        stack, and none of kmemleak's own (see kmemleak_text())."""
        reject = kmemleak_text()
        self.set(require_start=0, require_end=end, reject_start=0, reject_end=reject[1])
        self.set(require_start=start, reject_start=reject[0])

    def restore(self):
        self.set(probability=0)
        for k in self.KNOBS:
            if k != 'probability':
                os.write(self.fds[k], self.saved[k].encode())
        os.write(self.fds['probability'], self.saved['probability'].encode())
        for fd in self.fds.values():
            os.close(fd)


class Counter:
    """failslab's call counter, known exactly, to make the Nth call from
    now on fail in whatever task makes it (fail-nth reaches only the
    calling thread).

    With probability 100, times 1 and interval I, the call that takes the
    counter to a multiple of I fails; the counter counts the calls that
    pass every other filter (task, stack) while the interval is over 1,
    up to that failure (times 0 then stops it). It cannot be read or
    reset. So it is worked out once: by opening /proc/version, whose
    open() makes one call under seq_open() (the stack filter set to it, and
    task-filter to this thread with our make-it-fail), until an open
    fails, with three coprime intervals in turn: their residues give it
    (Chinese remainder theorem), if it is below 97 * 101 * 103 (it counts
    only what fault injection counted since the boot). From then on it
    is kept: before each operation one more open must fail with interval
    count + 1 (else it is not where it should be: it is worked out again,
    at most MAX_RESYNCS times, then the test fails), and
    interval count + N makes the Nth call fail; an operation that failed
    so counted N."""

    MODULI = (97, 101, 103)
    # Times the counter may be found off and worked out again in one sweep.
    # It happened once in about ten runs of make check (off at N=91 of the
    # EV3 registration's sweep, after 90 attempts where it was right), for a
    # reason not found: an allocation that passed the filters outside what
    # the test accounts for. Each time is printed with how far off it was.
    MAX_RESYNCS = 2

    def __init__(self, fs):
        self.fs = fs
        self.count = None
        self.resyncs = []

    def _trigger(self, interval):
        """Set up the /proc/version opens with interval."""
        fs = self.fs
        fs.set(probability=0, times=1, interval=interval, task_filter='Y')
        fs.require(*symbol_range('seq_open'))
        fs.set(probability=100)

    def _open_fails(self):
        try:
            os.close(os.open('/proc/version', os.O_RDONLY))
            return False
        except OSError as e:
            assert e.errno == errno.ENOMEM, e
            return True

    def work_out(self):
        opens, residues = 0, []
        for m in self.MODULI:
            self._trigger(m)
            for _ in range(m):
                opens += 1
                if self._open_fails():
                    break
            else:
                pytest.fail('no open of /proc/version failed with interval %d' % m)
            residues.append((-opens) % m)       # count0 + opens = 0 (mod m)
        total = 1
        for m in self.MODULI:
            total *= m
        count0 = sum(r * (total // m) * pow(total // m, -1, m)
                     for r, m in zip(residues, self.MODULI)) % total
        self.count = count0 + opens

    def arm(self, n, text):
        """Make the nth call from now on under [text] fail, in any task."""
        if self.count is None:
            self.work_out()
        self._trigger(self.count + 1)
        if not self._open_fails():
            expected = self.count
            self.work_out()
            self.resyncs.append((n, self.count - expected))
            print("failslab's counter before N=%d: %+d calls off (%d times now)"
                  % (n, self.count - expected, len(self.resyncs)))
            assert len(self.resyncs) <= self.MAX_RESYNCS, \
                "failslab's counter was off %d times (N, calls): %s" % (len(self.resyncs),
                                                                    self.resyncs)
            self._trigger(self.count + 1)
            assert self._open_fails(), "failslab's counter is not at %d" % self.count
        self.count += 1
        fs = self.fs
        fs.set(probability=0)
        fs.require(*text)
        fs.set(task_filter='N', interval=self.count + n, times=1, probability=100)

    def disarm(self, n):
        """Whether the failure was injected (the counter counted n calls);
        if not, the counter is lost (it counted the operation's calls)."""
        injected = self.fs.get('times') == 0
        self.fs.set(probability=0)
        if injected:
            self.count += n
        else:
            self.count = None
        return injected


class FailNth:
    """/proc/thread-self/fail-nth of the calling thread: the Nth call in it
    that may fail (and passes failslab's stack filter) fails."""

    def __init__(self):
        self.fd = os.open('/proc/thread-self/fail-nth', os.O_RDWR)

    def arm(self, n):
        os.pwrite(self.fd, str(n).encode(), 0)

    def disarm(self):
        """True if the failure was injected; disarms."""
        left = int(os.pread(self.fd, 32, 0))
        os.pwrite(self.fd, b'0', 0)
        return left == 0

    def close(self):
        os.close(self.fd)


def module_text(name):
    """[start, end) of a loaded module's core text: its executable sections
    (from the .ko's section headers) at the addresses in
    /sys/module/NAME/sections. The init sections are left out (freed once
    the module is live)."""
    with open(module_path(name), 'rb') as f:
        elf = f.read()
    assert elf[:4] == b'\x7fELF' and elf[4] == 2 and elf[5] == 1, 'not a 64-bit LE ELF'
    shoff, = struct.unpack_from('<Q', elf, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from('<HHH', elf, 0x3a)

    def header(i):
        return struct.unpack_from('<IIQQQQ', elf, shoff + i * shentsize)
    strtab = header(shstrndx)[4]
    spans = []
    for i in range(shnum):
        name_off, _, flags, _, _, size = header(i)
        sec = elf[strtab + name_off:elf.index(b'\0', strtab + name_off)].decode()
        if flags & 6 != 6 or sec.startswith('.init') or not size:   # SHF_ALLOC|SHF_EXECINSTR
            continue
        path = '/sys/module/%s/sections/%s' % (name, sec)
        if os.path.exists(path):
            start = int(_read(path), 16)
            spans.append((start, start + size))
    assert spans, 'no text section of %s in sysfs' % name
    start, end = min(s for s, _ in spans), max(e for _, e in spans)
    assert start and end - start < 1 << 24, (name, hex(start), hex(end))
    return start, end


_symbols = {}


def symbol_range(symbol):
    """[start, end) of a kernel text symbol (to the next text symbol)."""
    if symbol not in _symbols:
        _symbols[symbol] = _symbol_range(symbol)
    return _symbols[symbol]


def module_symbol_range(module, symbol):
    """[start, end) of a function of a loaded module (to its next symbol)."""
    addrs, start = [], None
    tag = '[%s]' % module
    with open('/proc/kallsyms') as f:
        for line in f:
            fields = line.split()
            if len(fields) < 4 or fields[3] != tag:
                continue
            a = int(fields[0], 16)
            if fields[1] in 'tT':
                addrs.append(a)
                if fields[2] == symbol:
                    start = a
    assert start, '%s of %s not in /proc/kallsyms' % (symbol, module)
    following = [a for a in addrs if a > start]
    end = min(following) if following else module_text(module)[1]
    assert end - start < 1 << 16, (hex(start), hex(end))
    return start, end


def _symbol_range(symbol):
    addrs, start = [], None
    with open('/proc/kallsyms') as f:
        for line in f:
            fields = line.split()
            if len(fields) < 3 or fields[1] not in 'tT' or '[' in line:
                continue
            a = int(fields[0], 16)
            addrs.append(a)
            if fields[2] == symbol:
                start = a
    assert start, '%s not in /proc/kallsyms (or its address hidden)' % symbol
    end = min(a for a in addrs if a > start)
    return start, end


def kmemleak_text():
    """kmemleak's code that allocates its own record of each allocation.

    kmemleak_alloc() records every slab allocation in an object of its own,
    allocated right after it (the slab's post-alloc hook), with the same
    stack above: every allocation we make is two calls that may fail. When
    kmemleak's fails, it takes one from its emergency pool instead, and
    nothing else happens: half of every sweep would test kmemleak, and the
    pool would drain. The stack filter leaves those calls out (reject-start
    and reject-end): __alloc_object() makes them, __create_object() calls
    it (it may be inlined there); the kmemleak functions between the two
    are the range."""
    spans = []
    for sym in ('__alloc_object', '__create_object'):
        try:
            spans.append(symbol_range(sym))
        except AssertionError:
            pass
    assert spans, "none of kmemleak's __alloc_object(), __create_object() in /proc/kallsyms"
    start, end = min(a for a, _ in spans), max(b for _, b in spans)
    assert end - start < 1 << 16, (hex(start), hex(end))
    return start, end


_libc = ctypes.CDLL(None, use_errno=True)
_SYSCALLS = {'x86_64': (313, 176), 'aarch64': (273, 106)}


_module_fds = {}


def module_fd(name):
    """A memfd holding the module's .ko: loads read it from memory, not
    again and again over the guest's 9p share."""
    if name not in _module_fds:
        fd = os.memfd_create(name)
        with open(module_path(name), 'rb') as f:
            os.write(fd, f.read())
        _module_fds[name] = fd
    return _module_fds[name]


def load(name):
    """insmod, if the module is not loaded."""
    if not loaded(name):
        err = finit_module(module_fd(name))
        assert err == 0, 'insmod %s: %s' % (name, errno.errorcode.get(err, err))


def finit_module(fd):
    """finit_module(2) in this thread (so that fail-nth applies): 0 or the errno."""
    nr = _SYSCALLS[platform.machine()][0]
    ret = _libc.syscall(ctypes.c_long(nr), ctypes.c_int(fd), ctypes.c_char_p(b''),
                        ctypes.c_int(0))
    return ctypes.get_errno() if ret else 0


def delete_module(name):
    """rmmod: 0 or the errno."""
    nr = _SYSCALLS[platform.machine()][1]
    ret = _libc.syscall(ctypes.c_long(nr), ctypes.c_char_p(name.encode()),
                        ctypes.c_uint(os.O_NONBLOCK))
    return ctypes.get_errno() if ret else 0


def splats(lines):
    return [t for _, t in lines if any(p.search(t) for p in scan_console.SPLATS)]


class Sweep:
    """N = 1, 2, ... until an attempt injects no failure."""

    def __init__(self, name, kmsg, record):
        self.name, self.kmsg, self.record = name, kmsg, record
        self.injected = 0
        self.outcomes = {}          # what came of the injected failures: count
        self.log = []               # the kernel's messages meanwhile
        self.mark = 0               # where this attempt's begin
        self.splats = []

    def run(self, attempt):
        """attempt(n, note) makes call n fail, checks what came of it and
        returns True if a failure was injected (note(what) records the
        outcome). Fails if attempt MAX_N still injected one."""
        t0 = time.monotonic()
        self.kmsg.read()
        for n in range(1, MAX_N + 1):
            self.n = n
            self.read_log()
            self.mark = len(self.log)
            done = not attempt(n, self.note)
            self.read_log()
            assert not self.splats, '%s, N=%d: the kernel complained:\n%s' % (
                self.name, n, '\n'.join(self.splats))
            if done:
                break
            self.injected += 1
        else:
            pytest.fail('%s: still injecting failures at N=%d' % (self.name, MAX_N))
        took = time.monotonic() - t0
        summary = 'N=%d reached, %d failures injected, %.1f s; %s' % (
            n, self.injected, took,
            ', '.join('%s: %d' % kv for kv in sorted(self.outcomes.items())))
        print('%s: %s' % (self.name, summary))
        self.record('fault sweep %s' % self.name, summary)
        assert self.injected > 0, '%s: no failure was injected' % self.name
        return n

    def note(self, what):
        self.outcomes[what] = self.outcomes.get(what, 0) + 1

    def read_log(self):
        new = self.kmsg.read()
        self.log += new
        self.splats += splats(new)

    def logged(self, text):
        """Whether the kernel logged a line containing text during this attempt."""
        self.read_log()
        return any(text in line for _, line in self.log[self.mark:])

    def logged_since(self, text, since):
        """How many lines containing text the kernel logged at or after
        `since` (seconds of its clock) during this sweep."""
        self.read_log()
        return sum(1 for t, line in self.log if t >= since and text in line)


# ---- fixtures -------------------------------------------------------------

def kmemleak_scan():
    """Two scans (an object is reported once it stayed unreferenced over
    two); the reports, as text blocks."""
    for _ in range(2):
        _write(KMEMLEAK, 'scan')
    text = _read(KMEMLEAK)
    blocks = []
    for line in text.splitlines():
        if line.startswith('unreferenced object') or not blocks:
            blocks.append(line)
        else:
            blocks[-1] += '\n' + line
    return blocks


def ours(block):
    return scan_console.OURS.search(block) is not None


@pytest.fixture(scope='module', autouse=True)
def fault_setup():
    """failslab set up (and put back at the end); kmemleak's earlier reports
    put aside. At the end, with every sweep done and the brick gone: the
    modules unload and load again, and kmemleak finds nothing of ours."""
    assert os.path.isdir(FAILSLAB), 'no failslab in the test kernel (CONFIG_FAILSLAB, ' \
        'CONFIG_FAULT_INJECTION_DEBUG_FS: tests/kernel/test.config)'
    assert os.access(KMEMLEAK, os.W_OK), 'no kmemleak in the test kernel'
    fs = Failslab()
    _write('/proc/thread-self/make-it-fail', 1)     # for calibrate()
    try:
        yield fs
    finally:
        fs.restore()
        _write('/proc/thread-self/make-it-fail', 0)
    order = (EV3, NXT_CORE, NXT, NXT_SERIAL)
    for name in reversed(order):
        if loaded(name):
            assert delete_module(name) == 0, '%s does not unload' % name
    for name in order:
        assert finit_module(module_fd(name)) == 0, '%s does not load again' % name
    # kmemleak reports objects 5 s old and older. A scan takes 10 to 15 s
    # under TCG: no scan (and clear) before the sweeps, so a leak of our
    # modules made by an earlier test in the same boot fails this one too
    # (as it fails the suite's own scan at the end).
    time.sleep(5.5)
    t0 = time.monotonic()
    found = kmemleak_scan()
    leaks = [b for b in found if ours(b)]
    print('kmemleak: %d report(s), %d naming our modules (two scans, %.1f s)' % (
        len(found), len(leaks), time.monotonic() - t0))
    assert not leaks, 'kmemleak: %d leak(s) of our modules:\n%s' % (
        len(leaks), '\n\n'.join(leaks))


@pytest.fixture
def kmsg():
    k = Kmsg()
    yield k
    k.close()


@pytest.fixture
def fail_nth():
    f = FailNth()
    yield f
    f.disarm()
    f.close()


# ---- EV3 ------------------------------------------------------------------

def ev3_unloaded():
    """lego_ev3_uart unloaded (no tty may have it attached)."""
    if loaded(EV3):
        assert delete_module(EV3) == 0, 'lego_ev3_uart does not unload'


def load_sweep(sweep, fail_nth, name, class_dir):
    """insmod `name` with the Nth allocation of its init failing: insmod
    fails with ENOMEM and leaves nothing (no `class_dir`; the next insmod
    works), or only the module's debugfs directory is missing (the driver
    goes on without it). The module is loaded at the end."""
    fd = module_fd(name)

    def attempt(n, note):
        fail_nth.arm(n)
        err = finit_module(fd)
        injected = fail_nth.disarm()
        if not injected:
            assert err == 0, 'insmod failed with nothing injected: %s' % errno.errorcode[err]
            assert os.path.isdir(DEBUGFS + '/' + name)
            return False
        if err:
            assert err == errno.ENOMEM, 'N=%d: insmod: %s' % (n, errno.errorcode.get(err, err))
            assert not loaded(name) and not os.path.isdir(class_dir)
            note('insmod failed with ENOMEM')
        else:
            # debugfs_create_dir() may fail: the driver goes on without.
            if os.path.isdir(DEBUGFS + '/' + name):
                note('loaded, the failure absorbed by the kernel')
            else:
                note('loaded without debugfs')
            assert delete_module(name) == 0
        assert finit_module(fd) == 0, 'N=%d: insmod fails after the failure' % n
        assert os.path.isdir(class_dir)
        assert os.path.isdir(DEBUGFS + '/' + name)
        assert delete_module(name) == 0, 'N=%d: rmmod after the failure' % n
        return True
    sweep.run(attempt)
    assert loaded(name)


def test_ev3_module_load(fault_setup, fail_nth, kmsg, record_property):
    """lego_ev3_uart's load (load_sweep())."""
    fs = fault_setup
    ev3_unloaded()
    fs.require(*symbol_range('do_one_initcall'))
    load_sweep(Sweep('lego_ev3_uart load', kmsg, record_property), fail_nth, EV3,
               '/sys/class/lego-sensor')


def tiocgetd(fd):
    return struct.unpack('i', fcntl.ioctl(fd, termios.TIOCGETD, struct.pack('i', 0)))[0]


def tiocsetd(fd, ldisc):
    fcntl.ioctl(fd, termios.TIOCSETD, struct.pack('i', ldisc))


def attach_sweep(sweep, fail_nth, fd, ldisc, counters, attached=None):
    """TIOCSETD `ldisc` on `fd` with the Nth allocation failing: ENOMEM and
    the tty back on N_TTY, or attached without its debugfs `counters`; then
    attached again and detached as usual. `attached()`, if given, says
    whether what the discipline makes is there (checked both ways)."""
    def made():
        return attached is None or attached()

    def gone():
        return attached is None or not attached()

    def attempt(n, note):
        fail_nth.arm(n)
        try:
            tiocsetd(fd, ldisc)
            err = 0
        except OSError as e:
            err = e.errno
        injected = fail_nth.disarm()
        if err:
            assert injected, 'TIOCSETD failed with nothing injected: %s' % errno.errorcode[err]
            assert err == errno.ENOMEM, 'N=%d: TIOCSETD: %s' % (n, errno.errorcode[err])
            assert tiocgetd(fd) == N_TTY
            assert gone(), 'N=%d: the failed attach left its device' % n
            note('TIOCSETD failed with ENOMEM')
        else:
            assert tiocgetd(fd) == ldisc and made()
            if injected:
                note('attached, the failure absorbed by the kernel'
                     if os.path.exists(counters) else 'attached without debugfs counters')
            else:
                assert os.path.exists(counters)
            tiocsetd(fd, N_TTY)
        if not injected:
            return False
        tiocsetd(fd, ldisc)
        assert os.path.exists(counters), 'N=%d: no counters after the failure' % n
        tiocsetd(fd, N_TTY)
        assert not os.path.exists(counters) and gone()
        return True
    sweep.run(attempt)


def test_ev3_attach(fault_setup, fail_nth, kmsg, record_property):
    """TIOCSETD N_LEGOEV3 on a null-modem tty (attach_sweep())."""
    fs = fault_setup
    load(EV3)
    ev3.load_nullmodem()
    fs.require(*module_text(EV3))
    fd = os.open('/dev/ttyNM0', os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        attach_sweep(Sweep('EV3 attach', kmsg, record_property), fail_nth, fd, N_LEGOEV3,
                     DEBUGFS + '/lego_ev3_uart/ttyNM0/counters')
    finally:
        os.close(fd)


def test_nxt_serial_attach(fault_setup, fail_nth, kmsg, record_property):
    """TIOCSETD N_LEGONXT, a brick on a pty (attach_sweep()): a failed attach
    leaves no node."""
    fs = fault_setup
    for m in (NXT_CORE, NXT_SERIAL):
        load(m)
    fs.require(*module_text(NXT_SERIAL))
    master, slave = os.openpty()
    before = len(glob.glob('/sys/class/lego-nxt/nxt*'))
    try:
        attach_sweep(Sweep('NXT serial attach', kmsg, record_property), fail_nth, slave,
                     N_LEGONXT,
                     DEBUGFS + '/lego_nxt/pts%s/counters' % os.ttyname(slave).rsplit('/', 1)[1],
                     lambda: len(glob.glob('/sys/class/lego-nxt/nxt*')) == before + 1)
    finally:
        os.close(slave)
        os.close(master)


# A Powered Up device as small as they come: one mode of one value with an
# IIO type (cm: IIO_DISTANCE), which syncs fast (its handshake at 115200
# baud, a few milliseconds) and stays at 115200.
TINY = ev3_sensor.SensorDef(62, 'lego-spike-ultrasonic', 1, [
    ev3_sensor.Mode('DISTL', (0, 250), (0, 250), 'cm', 1, ev3_sensor.S16, 5, 0,
                    pct=(0, 100), mapping=(0x10, 0), flags=bytes(6)),
], speed=115200, lump=True, version=(0x10000000, 0x10000000), fast_sync=True)
HOST, FAR = 'ttyNM0', 'ttyNM1'


def iio_of(address):
    """The IIO devices labelled `address` (the sensor's)."""
    out = []
    for d in glob.glob(ev3.IIO + '/iio:device*'):
        try:
            if ev3.read_attr(d, 'label') == address:
                out.append(d)
        except OSError:
            pass
    return out


def sensors_of(address):
    out = []
    for d in glob.glob(ev3.CLASS + '/sensor*'):
        try:
            if ev3.read_attr(d, 'address') == address:
                out.append(d)
        except OSError:
            pass
    return out


class Registration:
    """TINY plugged into ttyNM1, listening for the fast sync probe, and the
    discipline attached to ttyNM0: its probe, TINY's handshake at 115200 and
    the registration follow at once (no wait for the probe of the attach
    and the 100 ms before the next, as when a sensor is plugged into an
    attached line). What came of it: the driver's ev3_uart_sensor trace
    event."""

    def __init__(self, trace):
        self.trace = trace
        self.fd = self.emu = None

    def run(self, timeout=15.0):
        """'registered' (the sensor published, with or without its IIO
        device) or 'failed', once ev3_uart_ack() is done with it, and when (the
        trace's clock, the kernel log's)."""
        tracing.write(self.trace.root + '/trace', '')
        listening = threading.Event()
        self.emu = ev3_sensor.EmulatedSensor('/dev/' + FAR, TINY, boot_delay=0.5,
                                             gate=listening.set)
        self.emu.start()
        assert listening.wait(10), 'the emulator did not start'
        self.fd = os.open('/dev/' + HOST, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tiocsetd(self.fd, N_LEGOEV3)

        def outcome():
            ev = [(t, f) for t, n, f in self.trace.timed()
                  if n == 'ev3_uart_sensor' and f.get('tty') == HOST]
            return (ev[-1][1]['event'], ev[-1][0]) if ev else None
        wait_for(outcome, timeout, 0.01)
        got = outcome()
        assert got and got[0] in ('registered', 'failed'), 'no registration in %.0f s: %s' % (
            timeout, self.emu.events)
        return got

    def detach(self):
        """Unplugged, detached, and nothing left of the sensor."""
        if self.emu:
            self.emu.stop()
            self.emu = None
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        assert wait_for(lambda: not sensors_of(HOST) and not iio_of(HOST), 5.0), \
            'the sensor outlived the detach: %s %s' % (sensors_of(HOST), iio_of(HOST))


def test_ev3_sensor_registration(fault_setup, kmsg, record_property):
    """A sensor's registration with the Nth allocation under
    ev3_uart_sensor_create() failing. It runs in the port's work, ev3_uart_ack(),
    a kernel worker, which fail-nth does not reach: failslab (Counter), its
    stack filter set to ev3_uart_sensor_create(), which every allocation of
    the registration has on its stack (the sensor, its class device, then
    its IIO device), and nothing else. The sensor does not appear and
    the driver logs why, or it appears without its IIO device (logged too);
    detached, nothing of it is left.

    Each attempt is the same registration from the start, the failure one
    call later: an attempt whose registration fails before its Nth call,
    with nothing injected, fails the test, so what a failure left behind
    that breaks the registration is caught by the next attempt, and the
    last attempt is the registration without failure."""
    fs = fault_setup
    load(EV3)
    ev3.load_nullmodem()
    text = module_symbol_range(EV3, 'ev3_uart_sensor_create')
    trace = tracing.Trace('lego_ev3_uart')
    # Only the event that says what came of a registration: one line to read.
    tracing.write(trace.root + '/events/lego_ev3_uart/enable', '0')
    tracing.write(trace.root + '/events/lego_ev3_uart/ev3_uart_sensor/enable', '1')
    reg = Registration(trace)
    counter = Counter(fs)
    sweep = Sweep('EV3 sensor registration', kmsg, record_property)

    def attempt(n, note):
        counter.arm(n, text)
        try:
            got, when = reg.run()
        finally:
            injected = counter.disarm(n)
        sensors, iio = sensors_of(HOST), iio_of(HOST)
        if not injected:
            assert got == 'registered' and len(sensors) == 1 and len(iio) == 1, \
                'N=%d, nothing injected, yet: %s, %s, %s' % (n, got, sensors, iio)
            reg.detach()
            return False
        if got == 'failed':
            assert not sensors and not iio, (n, sensors, iio)
            # -ENOMEM with CONFIG_SYMBOLIC_ERRNAME, which the test kernel
            # lacks. ev3_uart_ack() logs it before it traces the failure, and the
            # line is rate-limited (10 in 5 s): a line missing must be one
            # of those. The rate limit's 5 s are jiffies, which lag the
            # trace's clock while the guest's ticks are late (a line was
            # suppressed 5.32 s after the first of the 10 by the trace's
            # clock, with the host loaded): 10 lines in the last 6 s.
            line = HOST + ': cannot register sensor: '
            if wait_for(lambda: sweep.logged(line + '-12') or sweep.logged(line + '-ENOMEM'),
                        0.1, 0.02):
                note('not registered (ENOMEM)')
            else:
                assert sweep.logged_since(line, when - 6.0) >= 10, \
                    'N=%d: no log line for the failed registration' % n
                note('not registered, its log line rate-limited')
        else:
            assert len(sensors) == 1, (n, sensors)
            if iio:
                note('registered, the failure absorbed by the kernel')
            else:
                # Logged before the registration is traced.
                assert wait_for(lambda: sweep.logged('no IIO device: -12'), 0.1, 0.02), \
                    'N=%d: no IIO device, and no log line' % n
                note('registered without IIO (ENOMEM)')
        reg.detach()
        return True
    try:
        sweep.run(attempt)
    finally:
        fs.set(probability=0)
        reg.detach()
        trace.stop()
    # The discipline and its sensors went, the module goes.
    assert delete_module(EV3) == 0
    load(EV3)


# ---- NXT ------------------------------------------------------------------

def test_nxt_core_module_load(fault_setup, fail_nth, kmsg, record_property):
    """lego_nxt's load, the NXT core: its char device region, the class
    lego-nxt, debugfs (load_sweep()); its transports go first and come back
    after."""
    fs = fault_setup
    for m in (NXT_SERIAL, NXT, NXT_CORE):
        if loaded(m):
            assert delete_module(m) == 0, 'rmmod ' + m
    fs.require(*symbol_range('do_one_initcall'))
    try:
        load_sweep(Sweep('lego_nxt load', kmsg, record_property), fail_nth, NXT_CORE,
                   '/sys/class/lego-nxt')
    finally:
        for m in (NXT_CORE, NXT, NXT_SERIAL):
            load(m)


def test_nxt_module_load(fault_setup, fail_nth, kmsg, record_property):
    """insmod lego_nxt_usb with the Nth allocation of its init failing
    (usb_register()): insmod fails with ENOMEM, and the next insmod works."""
    fs = fault_setup
    if loaded(NXT):
        assert delete_module(NXT) == 0
    fs.require(*symbol_range('do_one_initcall'))
    sweep = Sweep('lego_nxt_usb load', kmsg, record_property)
    fd = module_fd(NXT)

    def attempt(n, note):
        fail_nth.arm(n)
        err = finit_module(fd)
        injected = fail_nth.disarm()
        if not injected:
            assert err == 0, 'insmod failed with nothing injected: %s' % errno.errorcode[err]
            return False
        if err == errno.EINVAL and sweep.logged('failed to create module links for ' + NXT):
            # The driver core's: module_add_driver() (drivers/base/module.c)
            # makes /sys/module/lego_nxt_usb/drivers with
            # kobject_create_and_add(), which says NULL whatever failed,
            # and returns -EINVAL for it. usb_register() passes it on, and
            # our init returns usb_register()'s error. The module and the
            # driver are gone all the same, and the next insmod works (below).
            assert not loaded(NXT) and not os.path.exists(nxt.DRIVER)
            note('insmod failed with EINVAL (module_add_driver())')
        elif err:
            assert err == errno.ENOMEM, 'N=%d: insmod: %s' % (n, errno.errorcode.get(err, err))
            assert not loaded(NXT) and not os.path.exists(nxt.DRIVER)
            note('insmod failed with ENOMEM')
        else:
            note('loaded, the failure absorbed by the kernel')
            assert delete_module(NXT) == 0
        assert finit_module(fd) == 0, 'N=%d: insmod fails after the failure' % n
        assert os.path.isdir(nxt.DRIVER)
        assert delete_module(NXT) == 0, 'N=%d: rmmod after the failure' % n
        return True
    sweep.run(attempt)
    assert loaded(NXT)


@pytest.fixture(scope='module')
def nxt_brick(fault_setup):
    """An emulated brick, plugged in for the NXT sweeps."""
    load(NXT)
    b = nxt.Brick('dummy_udc.0', SERIAL)
    b.plug()
    yield b
    b.unplug()
    assert b.wait_gone(), 'the node outlived the brick'


def bound(intf_name):
    return os.path.exists(os.path.join(nxt.DRIVER, intf_name))


def transaction(node):
    """open(), GetVersions, close(): the errno of the open, the errno of the
    transaction and its reply."""
    try:
        f = os.open(node, os.O_RDWR)
    except OSError as e:
        return e.errno, None, None
    try:
        err, reply = nxt.transact(f, b'\x01\x88')
    finally:
        os.close(f)
    return 0, err, reply


def test_nxt_probe(fault_setup, nxt_brick, fail_nth, kmsg, record_property):
    """The probe of a brick (bound by a write to the driver's "bind", in
    this thread) with the Nth allocation under our text failing: the write
    fails with ENOMEM, the interface stays unbound, with no node, and the
    driver core logs the probe's error; bound again, the brick works."""
    fs = fault_setup
    intf = os.path.basename(nxt_brick.interface())
    fs.require(*module_text(NXT))
    sweep = Sweep('NXT probe', kmsg, record_property)
    with open(nxt.DRIVER + '/unbind', 'w') as f:
        f.write(intf)
    assert not bound(intf)
    bind = os.open(nxt.DRIVER + '/bind', os.O_WRONLY)
    unbind = os.open(nxt.DRIVER + '/unbind', os.O_WRONLY)
    try:
        def attempt(n, note):
            fail_nth.arm(n)
            try:
                os.pwrite(bind, intf.encode(), 0)
                err = 0
            except OSError as e:
                err = e.errno
            injected = fail_nth.disarm()
            if not injected:
                assert err == 0 and bound(intf), 'bind failed with nothing injected: %s' % err
                assert nxt.node_of(SERIAL, 5.0)
                os.pwrite(unbind, intf.encode(), 0)
                return False
            if err:
                assert err == errno.ENOMEM, 'N=%d: bind: %s' % (n, errno.errorcode.get(err, err))
                assert not bound(intf) and not glob.glob('/dev/nxt[0-9]*'), n
                assert sweep.logged('probe with driver lego_nxt_usb failed with error -12'), n
                note('probe failed with ENOMEM')
            else:
                # Only the debugfs directory may be missing.
                assert bound(intf) and nxt.node_of(SERIAL, 5.0), n
                note('bound, the failure absorbed')
                os.pwrite(unbind, intf.encode(), 0)
            os.pwrite(bind, intf.encode(), 0)
            node = nxt.node_of(SERIAL, 5.0)
            assert node, 'N=%d: no node after the failure' % n
            assert transaction(node) == (0, 0, VERSIONS_REPLY), n
            os.pwrite(unbind, intf.encode(), 0)
            assert wait_for(lambda: not glob.glob('/dev/nxt[0-9]*'), 5.0)
            return True
        sweep.run(attempt)
    finally:
        if not bound(intf):
            os.pwrite(bind, intf.encode(), 0)
        os.close(bind)
        os.close(unbind)
    nxt_brick.node = nxt.node_of(SERIAL, 5.0)
    assert nxt_brick.node


def rebind(intf):
    """Unbind the brick's interface and bind it again: a new nxt_usb whose
    reader has not started (the first open() starts it). Its node."""
    with open(nxt.DRIVER + '/unbind', 'w') as f:
        f.write(intf)
    with open(nxt.DRIVER + '/bind', 'w') as f:
        f.write(intf)
    node = nxt.node_of(SERIAL, 5.0)
    assert node, 'no node after binding %s again' % intf
    return node


def test_nxt_open_and_transaction(fault_setup, nxt_brick, fail_nth, kmsg,
                                  record_property):
    """open() of /dev/nxtN and one transaction (GetVersions) with the Nth
    allocation under our text failing, on a brick just bound (so that the
    open starts the reader, the IN transfer): the open or the transaction
    fails with ENOMEM, and the same again without injection gets the
    reply."""
    fs = fault_setup
    intf = os.path.basename(nxt_brick.interface())
    fs.require(*module_text(NXT))
    sweep = Sweep('NXT open + transaction', kmsg, record_property)

    def attempt(n, note):
        node = rebind(intf)
        fail_nth.arm(n)
        got = transaction(node)
        injected = fail_nth.disarm()
        if not injected:
            assert got == (0, 0, VERSIONS_REPLY), got
            return False
        err_open, err, _ = got
        if err_open:
            assert err_open == errno.ENOMEM, (n, errno.errorcode.get(err_open, err_open))
            note('open failed with ENOMEM')
        elif err:
            assert err == errno.ENOMEM, (n, errno.errorcode.get(err, err))
            note('transaction failed with ENOMEM')
        else:
            assert got == (0, 0, VERSIONS_REPLY), got
            note('worked, the failure absorbed')
        assert transaction(node) == (0, 0, VERSIONS_REPLY), \
            'N=%d: no transaction after the failure' % n
        return True
    sweep.run(attempt)
    nxt_brick.node = nxt.node_of(SERIAL, 5.0)
