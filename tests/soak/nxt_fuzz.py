#!/usr/bin/env python3
"""Whole-driver fuzzer of lego_nxt_usb: runs inside the test VM.

Random sequences of open/write/read/poll/ioctl/close (NXT_IOC_TRANSACT
with random telegrams, the typed ioctl numbers of earlier releases and
other unknown ioctl numbers, timeouts, O_NONBLOCK switches, signals, sysfs
reads) run in
several processes at once against an emulated brick that is often hostile
(tests/emulator/nxt_hostile.py: wrong lengths, types and opcodes,
duplicated, late and missing replies, stalls, vanishing in mid-transfer),
while the orchestrator resets the brick (USBDEVFS_RESET) and unplugs it.

Structure: the run is a series of *epochs*; an epoch plugs in one brick
with one behaviour profile, hands sequences to the worker processes, now
and then resets the brick, maybe unplugs it in the middle, and ends with
the brick unplugged. Everything derives from the run seed: epoch k's seed
is derive(run seed, k), the epoch's plan (profile, resets, unplug) and
the brick's choices come from the epoch seed, and sequence i of the epoch
is derive(epoch seed, i). Which process runs which sequence, and how their
system calls interleave, is the scheduler's.

Checks (any failure names the epoch and sequence seeds and the command
that replays them):
  - every errno is one Documentation/lego/nxt-usb.rst documents for that
    call, and the deterministic ones are exact (EINVAL for bad arguments,
    EMSGSIZE, ENOTTY, ENODATA with nothing asked, EINTR only with a signal);
  - NXT_IOC_TRANSACT: a failed transaction leaves the structure untouched
    (the brick's status byte is data: a reply that says the brick refused
    is a success); a telegram with no reply gets reply_length 0;
  - every other ioctl number, the retired typed ones (0x10 to 0x33 of the
    magic, with arguments of any size, never smaller than the number's
    size field) included, fails with ENOTTY and leaves its buffer as it was;
  - replies: type 0x02, the file's own command's opcode, the length the
    firmware gives that command, bytes past reply_length zero, and every
    reply a client got is a packet the brick sent (no stale kernel data);
  - poll: POLLIN means a read returns at once (no EAGAIN, no ENODATA);
    a read() buffer too small keeps the reply for the next read;
  - no system call takes longer than --op-bound seconds (a hang: the
    process's kernel stacks are printed and it is killed);
  - on unplug the node and the interface go away, every later call on an
    open file fails with ENODEV and poll() says POLLHUP; the next epoch's
    brick comes back;
  - no kernel splat in /dev/kmsg during the epoch (the patterns of
    tests/scan-console.py).

Usage (in the VM, e.g. tests/vm-run -- python3 tests/soak/nxt_fuzz.py ...):
  nxt_fuzz.py [--seed N] [--sequences N] [--per-epoch N] [--workers N]
  nxt_fuzz.py --epoch-seed N          replay one epoch
  nxt_fuzz.py --show SEQUENCE_SEED    print a sequence's operations
"""
import argparse
import collections
import ctypes
import errno
import fcntl
import hashlib
import importlib.util
import json
import multiprocessing
import multiprocessing.connection
import os
import random
import select
import signal
import struct
import sys
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
TOP = os.path.abspath(os.path.join(HERE, '..', '..'))
sys.path.insert(0, os.path.join(HERE, '..', 'guest'))
sys.path.insert(0, os.path.join(HERE, '..', 'emulator'))
import kmsg  # noqa: E402
import nxtdev as nxt  # noqa: E402
import nxt_hostile as nh  # noqa: E402
from kstacks import kernel_stacks  # noqa: E402

CTX = multiprocessing.get_context('fork')
MAX_FAILURES = 40

E = errno
# What a transaction may end in (nxt-usb.rst, "Errors"): EINTR only with a
# signal, EAGAIN only with O_NONBLOCK; both are checked separately.
TRANSACTION = {E.ETIMEDOUT, E.EPROTO, E.EPIPE, E.EIO, E.ENODEV, E.EINTR, E.EAGAIN}

def ename(err):
    return errno.errorcode.get(err, str(err)) if err else 'ok'


def derive(seed, *parts):
    """A 32-bit seed from a seed and a path (stable across Python versions)."""
    h = hashlib.sha256(repr((seed,) + parts).encode()).digest()
    return int.from_bytes(h[:4], 'little')


# ---- reply lengths (the firmware's, as LEGO's documents give them) ----------

def reply_length(tg):
    """Whole length of the reply the firmware gives telegram `tg`, or None
    when unknown (an opcode it does not know, a count the telegram lacks)."""
    if len(tg) < 2 or tg[0] not in (0x00, 0x01):
        return None
    op = tg[1]
    if tg[0] == 0x00:
        if op == 0x20:
            return 7 if len(tg) > 2 and tg[2] == 2 else 4
        return nh.DIRECT_REPLY_LEN.get(op)
    n = nh.SYSTEM_REPLY_LEN.get(op)
    if n is None:
        return None
    caps = {0x82: (3, 2, 58), 0x94: (8, 2, 55), 0xa2: (3, 1, 59)}
    if op in caps:
        at, size, cap = caps[op]
        if len(tg) < at + size:
            return None
        count = tg[at] if size == 1 else struct.unpack_from('<H', tg, at)[0]
        return n + min(count, cap)
    return n


def check_reply(tg, reply):
    """What is wrong with `reply` as the answer to `tg` (None if nothing)."""
    if len(reply) < 3 or len(reply) > 64:
        return 'reply of %d bytes' % len(reply)
    if reply[0] != 0x02:
        return 'reply type 0x%02x' % reply[0]
    if reply[1] != tg[1]:
        return 'reply to opcode 0x%02x for a telegram with opcode 0x%02x' % (reply[1], tg[1])
    want = reply_length(tg)
    if want and len(reply) != want and (reply[2] == 0 or len(reply) > want):
        return 'reply of %d bytes (status 0x%02x), the firmware sends %d' % (
            len(reply), reply[2], want)
    return None


# ---- generators ---------------------------------------------------------------

NAMES = [b'Demo.rxe', b'Woops.rso', b'fz.txt', b'fz.rxe', b'fz.rdt', b'*.*', b'*.rxe',
         b'Demo.*', b'', b'x' * 19, b'x' * 20, b'no such.rso', b'a\x01b', b'\xff\xfe']


def gen_name(rng, n=20):
    if rng.random() < 0.85:
        name = rng.choice(NAMES)
    else:
        name = bytes(rng.randrange(256) for _ in range(rng.randint(0, n)))
    return name[:n].ljust(n, b'\0')


def u8(rng, good):
    return rng.randrange(good) if rng.random() < 0.8 else rng.randrange(256)


def gen_direct(rng, op):
    r = rng
    if op in (0x00,):
        body = gen_name(r)
    elif op == 0x02:
        body = bytes([u8(r, 2)]) + gen_name(r)
    elif op == 0x03:
        body = struct.pack('<HH', r.choice([100, 200, 440, 14000, 20000, r.randrange(65536)]),
                           r.choice([0, 1, 10, 100, r.randrange(65536)]))
    elif op == 0x04:
        body = struct.pack('<BbBBbBI', r.choice([0, 1, 2, 0xff, r.randrange(256)]),
                           r.randint(-128, 127), u8(r, 8), u8(r, 3), r.randint(-128, 127),
                           r.choice([0, 0x10, 0x20, 0x40, r.randrange(256)]),
                           r.choice([0, 1, 360, r.randrange(1 << 32)]))
    elif op == 0x05:
        body = bytes([u8(r, 4), u8(r, 12), r.randrange(256)])
    elif op in (0x06, 0x0a, 0x21):
        body = bytes([u8(r, 3)]) + (bytes([u8(r, 2)]) if op == 0x0a else b'')
    elif op in (0x07, 0x08, 0x0e, 0x10):
        body = bytes([u8(r, 4)])
    elif op == 0x09:
        size = r.randint(0, 60)
        msg = bytes(r.randrange(1, 128) for _ in range(max(0, size - 1))) + b'\0'
        body = bytes([u8(r, 10), size if r.random() < 0.9 else r.randrange(256)]) + msg[:size]
    elif op == 0x0f:
        tx = r.randint(0, 17)
        head = bytes([u8(r, 4), tx, r.randint(0, 17)])
        data = [0x02, r.choice([0x00, 0x08, 0x10, 0x41, 0x42])] + [
            r.randrange(256) for _ in range(16)]
        body = head + bytes(data[:tx])
    elif op == 0x13:
        body = bytes([u8(r, 20), u8(r, 10), u8(r, 2)])
    elif op in (0x19, 0x1c, 0x1e, 0x20):
        body = bytes([u8(r, 4)])
    elif op == 0x1a:
        body = struct.pack('<I', r.randrange(1 << 32))
    elif op == 0x1f:
        prop = u8(r, 4)
        body = bytes([prop]) + (struct.pack('<I', r.randrange(1 << 32)) if prop == 2
                                else bytes([r.randrange(256)]))
    else:
        body = b''
    return body


def gen_system(rng, op):
    r = rng
    handle = lambda: u8(r, 17)  # noqa: E731
    if op in (0x80, 0x85, 0x86, 0x8c, 0x90):
        body = gen_name(r)
    elif op in (0x81, 0x89, 0x8b):
        name = gen_name(r)
        size = r.choice([0, 1, 64, 300, 5000, r.randrange(1 << 32)])
        body = name + struct.pack('<I', size)
    elif op == 0x82:
        body = struct.pack('<BH', handle(), r.choice([0, 1, 58, 59, 64, r.randrange(65536)]))
    elif op == 0x83:
        body = bytes([handle()]) + bytes(r.randrange(256) for _ in range(r.randint(0, 61)))
    elif op in (0x84, 0x87, 0x8d, 0x91, 0x92):
        body = bytes([handle()])
    elif op in (0x94, 0x95):
        mid = r.choice([m[1] for m in nh.nb.MODULES] + [r.randrange(1 << 32)])
        n = r.choice([0, 1, 8, 55, 56, r.randrange(65536)])
        body = struct.pack('<IHH', mid, r.choice([0, 4, 100, 300, r.randrange(65536)]), n)
        if op == 0x95:
            body += bytes(r.randrange(256) for _ in range(r.randint(0, 54)))
    elif op == 0x97:
        body = b"Let's dance: SAMBA\0" if r.random() < 0.02 else gen_name(r, 19)
    elif op == 0x98:
        body = gen_name(r, 16)
    elif op == 0xa1:
        body = bytes([u8(r, 2)])
    elif op == 0xa2:
        body = bytes([u8(r, 2), r.choice([0, 1, 59, 60, r.randrange(256)])])
    else:
        body = b''
    return body


def gen_telegram(rng):
    r = rng
    k = r.random()
    if k < 0.45:
        op = r.choice(nh.DIRECT_OPS)
        tg = bytes([0x00 if r.random() < 0.85 else 0x80, op]) + gen_direct(r, op)
    elif k < 0.78:
        op = r.choice([o for o in nh.SYSTEM_OPS if o != 0xa0 or r.random() < 0.05])
        tg = bytes([0x01 if r.random() < 0.85 else 0x81, op]) + gen_system(r, op)
    elif k < 0.86:
        tg = bytes([r.choice([0x00, 0x01, 0x80, 0x81]), r.randrange(256)]) + bytes(
            r.randrange(256) for _ in range(r.randint(0, 20)))
    elif k < 0.93:
        tg = bytes(r.randrange(256) for _ in range(r.randint(2, 64)))
    else:
        tg = bytes(r.randrange(256) for _ in range(r.choice([0, 1, 65, 66, 80])))
    if 2 <= len(tg) <= 64 and r.random() < 0.1:
        # A command cut short, or followed by junk.
        tg = tg[:r.randint(2, len(tg))] if r.random() < 0.5 else \
            (tg + bytes(r.randrange(256) for _ in range(r.randint(1, 10))))[:64]
    return tg


def telegram_errno(tg):
    """The errno the driver must give before sending anything, or None."""
    if len(tg) > 64:
        return E.EMSGSIZE
    if len(tg) < 2 or tg[0] not in (0x00, 0x01, 0x80, 0x81):
        return E.EINVAL
    if not nxt.request_complete(tg):
        return E.EINVAL     # shorter than what its command reads
    return None


# The three ioctls of the header; every other number fails with ENOTTY.
KNOWN_IOCTLS = {nxt.ioctl_number(n) for n in ('TRANSACT', 'SET_TIMEOUT', 'GET_TIMEOUT')}
_IOC_SIZEMASK = 0x3FFF

RETIRED_TYPED = nxt.RETIRED_TYPED
RETIRED_NR = range(0x10, 0x34)      # the numbers the typed ioctls had room for


def ioc_size(num):
    return (num >> 16) & _IOC_SIZEMASK


def gen_unknown_ioctl(rng):
    while True:
        d = rng.randrange(4)
        nr = rng.randrange(0x40) if rng.random() < 0.8 else rng.randrange(256)
        size = rng.choice([0, 4, 8, 20, 24, 28, 64, 136, rng.randrange(1 << 14)])
        magic = 0xE4 if rng.random() < 0.85 else rng.choice([0xE3, 0xE5, 0x4E])
        num = d << 30 | size << 16 | magic << 8 | nr
        if num not in KNOWN_IOCTLS:
            return num


def gen_retired(rng):
    """An ioctl number of the magic that the driver does not know, most of
    them the retired typed ones, and its argument: random bytes, never
    fewer than the number's size field says (often a few more)."""
    r = rng
    k = r.random()
    if k < 0.6:
        op = r.choice(sorted(RETIRED_TYPED))
        num = nxt.retired_number(op)
    else:
        while True:
            if k < 0.85:
                nr = r.choice(RETIRED_NR)
            else:
                nr = r.randrange(3)         # a known ioctl's, another size or direction
            size = r.choice([0, 1, 4, 8, 16, 20, 24, 64, 136, r.randrange(257),
                             r.randrange(_IOC_SIZEMASK + 1)])
            num = nxt._ioc(r.randrange(4), nr, size)
            if num not in KNOWN_IOCTLS:
                break
    size = ioc_size(num)
    extra = r.choice([0, 0, 1, 4, r.randrange(65)])
    arg = bytes(r.randrange(256) for _ in range(size + extra))
    return num, arg


TIMEOUTS_OK = [1, 5, 20, 100, 300, 1000, 2000]
TIMEOUTS_BAD = [0, 60001, 0xFFFFFFFF]
SYSFS = ['battery_mv', 'firmware_version', 'protocol_version', 'brick_name', 'bt_address',
         'free_flash']


def gen_sequence(seed):
    """The operations of sequence `seed`: a list of tuples (see run_op)."""
    r = random.Random(seed)
    ops = [('open', 0, r.random() < 0.2)]
    slots = 3
    for _ in range(r.randint(1, 14)):
        k = r.random()
        s = 0 if r.random() < 0.6 else r.randrange(slots)
        if k < 0.07:
            ops.append(('open', s, r.random() < 0.3))
        elif k < 0.11:
            ops.append(('close', s))
        elif k < 0.27:
            ops.append(('write', s, gen_telegram(r)))
        elif k < 0.38:
            ops.append(('read', s, r.choice([0, 1, 2, 3, 4, 16, 63, 64, 64, 64, 200])))
        elif k < 0.44:
            ops.append(('poll', s, r.choice([0, 0, 10, 50]), r.random() < 0.7))
        elif k < 0.72:
            tg = gen_telegram(r)
            length = len(tg) if r.random() < 0.9 else r.choice([0, 1, 65, 1 << 31, r.randrange(80)])
            ops.append(('transact', s, tg[:64], length))
        elif k < 0.80:
            num, arg = gen_retired(r)
            ops.append(('retired', s, num, arg))
        elif k < 0.83:
            ops.append(('ioctl', s, gen_unknown_ioctl(r)))
        elif k < 0.88:
            ms = r.choice(TIMEOUTS_OK) if r.random() < 0.8 else r.choice(TIMEOUTS_BAD)
            ops.append(('set_timeout', s, ms))
        elif k < 0.89:
            ops.append(('get_timeout', s))
        elif k < 0.92:
            ops.append(('nonblock', s, r.random() < 0.5))
        elif k < 0.95:
            ops.append(('alarm', r.choice([1, 5, 20, 100, 300]), r.random() < 0.3))
        elif k < 0.98:
            ops.append(('sysfs', r.choice(SYSFS)))
        else:
            ops.append(('sleep', r.choice([1, 10, 50])))
    return ops


def describe(op):
    kind = op[0]
    if kind == 'write':
        return 'write fd%d %s' % (op[1], op[2].hex() or '(empty)')
    if kind == 'transact':
        return 'NXT_IOC_TRANSACT fd%d length=%d %s' % (op[1], op[3], op[2].hex() or '(empty)')
    if kind == 'retired':
        return 'ioctl fd%d 0x%08x (unknown) %d bytes %s' % (op[1], op[2], len(op[3]),
                                                          op[3][:64].hex())
    if kind == 'ioctl':
        return 'ioctl fd%d 0x%08x' % (op[1], op[2])
    return ' '.join(str(x) for x in op)


TICK = 0.001
TICK_SHARE = 0.3


def epoch_plan(seed, sequences):
    r = random.Random(seed)
    profile = r.choices(['honest', 'flaky', 'hostile', 'silent', 'babbler', 'liar'],
                        [30, 20, 20, 10, 10, 10])[0]
    plan = dict(seed=seed, profile=profile, sequences=sequences,
                late_max=r.choice([0.05, 0.3, 1.0]),
                noreply_hostility=0 if profile == 'honest' else r.choice([0.02, 0.2]))
    # An unplug in the middle of the epoch (after k sequences ended, plus a
    # delay), or at the end; USB resets now and then.
    plan['unplug_after'] = r.randrange(sequences) if r.random() < 0.5 else None
    plan['unplug_delay'] = r.uniform(0, 0.3)
    plan['resets'] = sorted(r.randrange(sequences) for _ in range(r.choice([0, 0, 0, 1, 2])))
    if profile == 'honest' and r.random() < 0.6:
        # Left alone until the end: the strictest checks apply.
        plan['unplug_after'], plan['resets'] = None, []
    # The firmware's 1 ms scheduler (nxt_brick.py `tick`) in a share of the
    # epochs, drawn apart so that the rest of a seed's plan stays as it was.
    plan['tick'] = TICK if random.Random(seed ^ 0x7469636b).random() < TICK_SHARE else None
    return plan


# ---- the worker side ------------------------------------------------------------

_libc = ctypes.CDLL(None, use_errno=True)


def ioctl_buf(fd, num, data):
    buf = ctypes.create_string_buffer(bytes(data), max(len(data), 1))
    ret = _libc.ioctl(fd, ctypes.c_ulong(num), buf)
    err = ctypes.get_errno() if ret < 0 else 0
    return err, buf.raw[:len(data)]


SLOT_OPS = {'close', 'write', 'read', 'poll', 'transact', 'retired', 'ioctl', 'set_timeout',
            'get_timeout', 'nonblock'}


class Slot:
    def __init__(self, fd, nonblock):
        self.fd = fd
        self.nonblock = nonblock
        self.pending = False     # True, False or None (unknown)
        self.tg = None           # the last telegram written that wants a reply


class Sequence:
    """Runs one sequence in a worker process and checks each call."""

    def __init__(self, seed, node, sysfs, honest, status, bound, strict=False):
        self.seed, self.node, self.sysfs, self.honest = seed, node, sysfs, honest
        self.strict = strict
        self.pairs = []
        self.strict_failures = []   # failures unless the brick rebooted itself
        self.eproto = []            # failures unless a timeout or signal came first
        self.status = status
        self.bound = bound
        self.slots = {}
        self.failures = []
        self.replies = []
        self.errnos = collections.Counter()
        self.calls = 0
        self.armed = False
        self.slowest = 0.0

    def fail(self, i, op, msg):
        self.failures.append('sequence %#x op %d (%s): %s' % (
            self.seed, i, describe(op)[:200], msg))

    def note(self, what, err):
        self.errnos['%s:%s' % (what, ename(err))] += 1

    def allowed(self, i, op, what, err, extra, nonblock=False):
        """Transaction errnos and `extra` are allowed; EAGAIN only with
        O_NONBLOCK, EINTR only with a signal armed."""
        self.note(what, err)
        if err == 0:
            return
        ok = err in TRANSACTION or err in extra
        if err == E.EAGAIN and E.EAGAIN not in extra and not nonblock:
            ok = False
        if err == E.EINTR and E.EINTR not in extra and not self.armed:
            ok = False
        if self.honest and err == E.EPIPE:
            ok = False
        if ok and self.strict and err == E.EPROTO:
            self.eproto.append('sequence %#x op %d (%s): EPROTO from an honest brick' % (
                self.seed, i, describe(op)[:200]))
        if ok and self.strict and err in (E.EIO, E.EPIPE, E.ENODEV):
            self.strict_failures.append('sequence %#x op %d (%s): %s from an honest brick '
                                        'that was neither reset nor unplugged' % (
                                            self.seed, i, describe(op)[:200], ename(err)))
        if not ok:
            self.fail(i, op, '%s failed with %s, not a documented errno for it'
                      % (what, ename(err)))

    def run(self, ops):
        for i, op in enumerate(ops):
            self.status.value = ('%#x:%d %s' % (self.seed, i, describe(op)[:150])).encode()
            t0 = time.monotonic()
            try:
                self.run_op(i, op)
            except Exception:
                self.fail(i, op, 'exception: %s' % traceback.format_exc(limit=3))
            dt = time.monotonic() - t0
            self.slowest = max(self.slowest, dt)
            if dt > self.bound:
                self.fail(i, op, 'took %.1f s (bound %.0f s)' % (dt, self.bound))
            if op[0] != 'alarm' and self.armed:
                signal.setitimer(signal.ITIMER_REAL, 0)
                self.armed = False
        # A signal armed by the last operation must not hit the next sequence.
        signal.setitimer(signal.ITIMER_REAL, 0)
        self.armed = False
        for s in list(self.slots.values()):
            os.close(s.fd)
        self.slots.clear()
        self.status.value = b''

    def run_op(self, i, op):
        fn = getattr(self, 'op_' + op[0])
        if op[0] in SLOT_OPS:
            slot = self.slots.get(op[1])
            if slot is None:
                return
            self.calls += 1
            fn(i, op, slot)
        else:
            self.calls += 1
            fn(i, op)

    # -- the operations --

    def op_open(self, i, op):
        _, s, nonblock = op
        if s in self.slots:
            os.close(self.slots.pop(s).fd)
        try:
            fd = os.open(self.node, os.O_RDWR | (os.O_NONBLOCK if nonblock else 0))
        except OSError as e:
            self.note('open', e.errno)
            if e.errno not in (E.ENODEV, E.ENOENT) and not (e.errno == E.EINTR and self.armed):
                self.fail(i, op, 'open failed with %s' % ename(e.errno))
            return
        self.note('open', 0)
        self.slots[s] = Slot(fd, nonblock)

    def op_close(self, i, op, slot):
        del self.slots[op[1]]
        os.close(slot.fd)

    def op_nonblock(self, i, op, slot):
        flags = fcntl.fcntl(slot.fd, fcntl.F_GETFL)
        flags = flags | os.O_NONBLOCK if op[2] else flags & ~os.O_NONBLOCK
        fcntl.fcntl(slot.fd, fcntl.F_SETFL, flags)
        slot.nonblock = op[2]

    def op_alarm(self, i, op):
        _, ms, restart = op
        if self.strict:         # no signals where replies are paired exactly
            return
        signal.siginterrupt(signal.SIGALRM, not restart)
        signal.setitimer(signal.ITIMER_REAL, ms / 1000.0)
        self.armed = True

    def op_sleep(self, i, op):
        time.sleep(op[1] / 1000.0)

    def op_write(self, i, op, slot):
        tg = op[2]
        want = telegram_errno(tg)
        try:
            n = os.write(slot.fd, tg)
            err = 0
        except OSError as e:
            err, n = e.errno, None
        if want is not None:
            self.note('write', err)
            if err != want:
                self.fail(i, op, 'write gave %s, must be %s' % (ename(err), ename(want)))
            return
        self.allowed(i, op, 'write', err, (), slot.nonblock)
        if err == 0:
            if n != len(tg):
                self.fail(i, op, 'write returned %r of %d bytes' % (n, len(tg)))
            slot.pending = tg[0] in (0x00, 0x01)
            slot.tg = tg if slot.pending else None
        elif err == E.EAGAIN:
            slot.pending = None
        else:
            slot.pending = False if err != E.EINTR else None

    def _got_reply(self, i, op, tg, reply, what):
        self.replies.append(reply)
        if tg is None:
            return
        self.pairs.append((bytes(tg), bytes(reply)))
        bad = check_reply(tg, reply)
        if bad:
            self.fail(i, op, '%s: %s (%s)' % (what, bad, reply.hex()))

    def op_read(self, i, op, slot):
        size = op[2]
        try:
            reply, err = os.read(slot.fd, size), 0
        except OSError as e:
            reply, err = None, e.errno
        self.allowed(i, op, 'read', err, (E.ENODATA, E.EMSGSIZE), slot.nonblock)
        if err == E.ENODATA and slot.pending:
            self.fail(i, op, 'read gave ENODATA with a reply awaited')
        if slot.pending is False and err not in (E.ENODATA, E.ENODEV):
            self.fail(i, op, 'read gave %s with nothing asked (must be ENODATA)' % ename(err))
            slot.pending = False
            return
        if err == E.EAGAIN:
            return
        if err == E.EMSGSIZE:
            # The reply is kept for a read with room for it.
            try:
                reply, err2 = os.read(slot.fd, 64), 0
            except OSError as e:
                reply, err2 = None, e.errno
            if err2 or len(reply) <= size:
                self.fail(i, op, 'read(%d) gave EMSGSIZE, then read(64) gave %s' % (
                    size, ename(err2) if err2 else '%d bytes' % len(reply)))
            err = err2
        if err == 0:
            self._got_reply(i, op, slot.tg, reply, 'read')
        slot.pending = False

    def op_poll(self, i, op, slot):
        _, _, timeout, then_read = op
        p = select.poll()
        p.register(slot.fd, select.POLLIN | select.POLLOUT)
        got = dict(p.poll(timeout)).get(slot.fd, 0)
        known = (select.POLLIN | select.POLLRDNORM | select.POLLOUT | select.POLLWRNORM |
                 select.POLLERR | select.POLLHUP)
        if got & ~known:
            self.fail(i, op, 'poll events 0x%x' % got)
        if got & select.POLLHUP:
            self.note('poll', E.ENODEV)
        if got & select.POLLIN and not got & select.POLLHUP:
            if slot.pending is False:
                self.fail(i, op, 'POLLIN with nothing asked')
            if then_read:
                try:
                    reply, err = os.read(slot.fd, 64), 0
                except OSError as e:
                    reply, err = None, e.errno
                self.note('read-after-POLLIN', err)
                if err in (E.EAGAIN, E.ENODATA):
                    self.fail(i, op, 'POLLIN, then read gave %s' % ename(err))
                elif err == 0:
                    self._got_reply(i, op, slot.tg, reply, 'read after POLLIN')
                elif err not in TRANSACTION:
                    self.fail(i, op, 'POLLIN, then read gave %s' % ename(err))
                slot.pending = False

    def op_transact(self, i, op, slot):
        _, _, tg, length = op
        junk = bytes((i * 37 + k) & 0xFF for k in range(64))
        inp = struct.pack('<64s64sII', tg, junk, length & 0xFFFFFFFF, 0xDEADBEEF)
        err, out = ioctl_buf(slot.fd, nxt.ioctl_number('TRANSACT'), inp)
        if length > 64:
            want = E.EMSGSIZE
        else:
            want = telegram_errno(tg[:length] if length <= len(tg) else
                                  tg + bytes(length - len(tg)))
        if want is not None:
            self.note('transact', err)
            if err != want:
                self.fail(i, op, 'TRANSACT gave %s, must be %s' % (ename(err), ename(want)))
            return
        self.allowed(i, op, 'transact', err, (), slot.nonblock)
        # EAGAIN or EINTR may come before the file's last reply was settled.
        slot.pending = None if err in (E.EAGAIN, E.EINTR) else False
        if err:
            if out != inp:
                self.fail(i, op, 'TRANSACT failed with %s but changed the structure' % ename(err))
            return
        _, reply, _, rlen = struct.unpack('<64s64sII', out)
        full = (tg + bytes(64))[:length]
        if full[0] in (0x80, 0x81):
            if rlen != 0 or reply != bytes(64):
                self.fail(i, op, 'a telegram with no reply got reply_length %d, reply %s'
                          % (rlen, reply.hex()))
            return
        if rlen > 64:
            self.fail(i, op, 'reply_length %d' % rlen)
            return
        if any(reply[rlen:]):
            self.fail(i, op, 'bytes past reply_length %d not zero: %s' % (rlen, reply.hex()))
        self._got_reply(i, op, full, reply[:rlen], 'TRANSACT')

    def op_retired(self, i, op, slot):
        _, _, num, arg = op
        if len(arg) < ioc_size(num):
            raise AssertionError('a buffer smaller than the size field of 0x%08x' % num)
        err, out = ioctl_buf(slot.fd, num, arg)
        self.note('retired-ioctl', err)
        if err != E.ENOTTY:
            self.fail(i, op, 'an ioctl number the driver does not know gave %s, must be ENOTTY'
                      % ename(err))
        if out != arg:
            self.fail(i, op, 'ioctl 0x%08x failed but changed its buffer' % num)

    def op_ioctl(self, i, op, slot):
        err, _ = ioctl_buf(slot.fd, op[2], bytes(max(64, (op[2] >> 16) & 0x3FFF)))
        self.note('unknown-ioctl', err)
        if err != E.ENOTTY:
            self.fail(i, op, 'unknown ioctl gave %s, must be ENOTTY' % ename(err))

    def op_set_timeout(self, i, op, slot):
        ms = op[2]
        if self.strict and 1 <= ms < 1000:      # no timeouts where replies are paired
            ms = 2000
        err, _ = ioctl_buf(slot.fd, nxt.ioctl_number('SET_TIMEOUT'), struct.pack('<I', ms))
        self.note('set_timeout', err)
        want = 0 if 1 <= ms <= 60000 else E.EINVAL
        if err != want and not (err == E.EINTR and self.armed and want == 0):
            self.fail(i, op, 'SET_TIMEOUT(%d) gave %s, must be %s' % (ms, ename(err), ename(want)))
        if err == 0:
            got = nxt.get_timeout(slot.fd)
            if got != ms:
                self.fail(i, op, 'GET_TIMEOUT gives %d after SET_TIMEOUT(%d)' % (got, ms))

    def op_get_timeout(self, i, op, slot):
        err, out = ioctl_buf(slot.fd, nxt.ioctl_number('GET_TIMEOUT'), bytes(4))
        ms = struct.unpack('<I', out)[0]
        if err or not 1 <= ms <= 60000:
            self.fail(i, op, 'GET_TIMEOUT gave %s, %d ms' % (ename(err), ms))

    def op_sysfs(self, i, op):
        path = os.path.join(self.sysfs, op[1])
        value, err = None, 0
        try:
            fd = os.open(path, os.O_RDONLY)
            try:
                # Raw reads: a buffered one turns EAGAIN (status 0x20) into None.
                value = os.read(fd, 4096).decode('ascii', 'replace').strip()
            finally:
                os.close(fd)
        except OSError as e:
            value, err = None, e.errno
        self.note('sysfs', err)
        # The attributes show what replies to the users' telegrams said and
        # never ask the brick: ENODATA while no such reply has come, ENOENT
        # once the brick is gone (ENODEV from kernfs when it went between
        # the open and the read), and no transaction's errno. A strict
        # epoch has no unplug: ENODEV fails it below.
        sysfs_ok = {E.ENODATA, E.ENOENT, E.ENODEV}
        if self.strict and err == E.EPROTO:
            self.eproto.append('sequence %#x op %d (%s): EPROTO from an honest brick' % (
                self.seed, i, describe(op)))
        elif self.strict and err in (E.EIO, E.EPIPE, E.ENODEV, E.ENOENT):
            self.strict_failures.append('sequence %#x op %d (%s): %s from an honest brick '
                                        'that was neither reset nor unplugged' % (
                                            self.seed, i, describe(op), ename(err)))
        elif err and err not in sysfs_ok:
            self.fail(i, op, 'reading %s gave %s' % (op[1], ename(err)))
        if err == E.EPIPE and self.honest:
            self.fail(i, op, 'EPIPE from an honest brick')
        if value is not None and op[1] in ('battery_mv', 'free_flash') and not value.isdigit():
            self.fail(i, op, '%s = %r' % (op[1], value))


def worker_main(conn, status, bound):
    signal.signal(signal.SIGALRM, lambda signum, frame: None)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.nice(3)
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg is None:
            return
        seed, node, sysfs, honest, strict = msg
        seq = Sequence(seed, node, sysfs, honest, status, bound, strict)
        seq.run(gen_sequence(seed))
        conn.send(dict(seed=seed, failures=seq.failures, replies=seq.replies, pairs=seq.pairs,
                       strict_failures=seq.strict_failures, eproto=seq.eproto,
                       errnos=dict(seq.errnos), calls=seq.calls, slowest=seq.slowest))


class Worker:
    def __init__(self, index, bound):
        self.index = index
        self.bound = bound
        self.spawn()

    def spawn(self):
        self.status = CTX.Array('c', 256, lock=False)
        self.conn, child = CTX.Pipe()
        self.proc = CTX.Process(target=worker_main, args=(child, self.status, self.bound),
                                daemon=True)
        self.proc.start()
        child.close()
        self.busy = None        # (seed, started)
        self.last_status, self.status_since = None, time.monotonic()

    def kill(self):
        try:
            self.proc.kill()
        except Exception:
            pass
        self.proc.join(5)


# ---- the orchestrator -----------------------------------------------------------

def load_splat_patterns():
    spec = importlib.util.spec_from_file_location('scan_console',
                                                  os.path.join(TOP, 'tests', 'scan-console.py'))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.SPLATS


class Kmsg(kmsg.Kmsg):
    """The kernel log since the last call: its splats."""

    def __init__(self):
        super().__init__()
        self.patterns = load_splat_patterns()

    def splats(self):
        return [ln for ln in self.texts() if any(p.search(ln) for p in self.patterns)]



def usb_reset(serial):
    """USBDEVFS_RESET on the brick: the driver stays bound (pre/post_reset)."""
    intf = nxt.interface_of(serial)
    if not intf:
        return 'no interface'
    dev = os.path.dirname(intf)
    try:
        with open(os.path.join(dev, 'busnum')) as f:
            bus = int(f.read())
        with open(os.path.join(dev, 'devnum')) as f:
            num = int(f.read())
        fd = os.open('/dev/bus/usb/%03d/%03d' % (bus, num), os.O_RDWR)
    except (OSError, ValueError) as e:
        return str(e)
    try:
        fcntl.ioctl(fd, ord('U') << 8 | 20, 0)
        return 'reset'
    except OSError as e:
        return 'reset failed: %s' % ename(e.errno)
    finally:
        os.close(fd)


class Fuzzer:
    def __init__(self, seed, workers=3, per_epoch=24, udc='dummy_udc.0',
                 serial='0016530F0E01', op_bound=30.0, hang_s=None, log=None):
        self.seed = seed
        self.per_epoch = per_epoch
        self.udc, self.serial = udc, serial
        self.op_bound = op_bound
        # A sequence's call still running after this long is a hang.
        self.hang_s = hang_s if hang_s is not None else 2 * op_bound + 30
        self.log = log or (lambda m: print(m, flush=True))
        self.failures = []
        self.failed_epochs = []
        self.sequences = 0
        self.calls = 0
        self.epochs = 0
        self.info = collections.Counter()
        self.errnos = collections.Counter()
        self.actions = collections.Counter()
        self.slowest = 0.0
        nxt.load_driver()
        self.workers = [Worker(i, op_bound) for i in range(workers)]
        nh.nb._ensure_wake_handler()
        self.kmsg = Kmsg()
        self.tamper = None      # test hook: called with the brick after the plug
        self.t0 = time.monotonic()

    def close(self):
        for w in self.workers:
            try:
                w.conn.send(None)
            except OSError:
                pass
        for w in self.workers:
            w.proc.join(5)
            if w.proc.is_alive():
                w.kill()

    def replay_command(self, eseed=None):
        if eseed is None:
            return 'tests/vm-run -- python3 tests/soak/nxt_fuzz.py --seed %#x' % self.seed
        return ('tests/vm-run -- python3 tests/soak/nxt_fuzz.py --epoch-seed %#x --per-epoch %d '
                '--workers %d' % (eseed, self.per_epoch, len(self.workers)))

    def fail(self, eseed, msg):
        if eseed not in self.failed_epochs:
            self.failed_epochs.append(eseed)
        text = '[epoch %#x] %s' % (eseed, msg)
        if len(self.failures) < MAX_FAILURES:
            self.failures.append(text)
        self.log('nxt_fuzz: FAIL: %s\n  replay: %s' % (text, self.replay_command(eseed)))

    def run(self, sequences):
        """Epochs until `sequences` sequences have run."""
        k = 0
        while self.sequences < sequences:
            n = min(self.per_epoch, sequences - self.sequences)
            eseed = derive(self.seed, 'epoch', k)
            before = self.sequences
            self.run_epoch(eseed, n)
            plan = epoch_plan(eseed, n)
            self.log('nxt_fuzz: epoch %d (%#x, %s%s): %d sequences; %d of %d in %.0f s, '
                     '%d failure(s)' % (k, eseed, plan['profile'],
                                        ', 1 ms tick' if plan['tick'] else '',
                                        self.sequences - before, self.sequences, sequences,
                                        time.monotonic() - self.t0, len(self.failures)))
            k += 1
        return not self.failures

    def run_epoch(self, eseed, n):
        plan = epoch_plan(eseed, n)
        self.epochs += 1
        self.info['profile_' + plan['profile']] += 1
        if plan['tick']:
            self.info['tick_epochs'] += 1
        for ln in self.kmsg.splats():
            self.fail(eseed, 'kernel splat before the epoch: %s' % ln)
        brick = nh.HostileBrick(profile=plan['profile'], seed=eseed, udc=self.udc,
                                serial=self.serial, late_max=plan['late_max'],
                                noreply_hostility=plan['noreply_hostility'],
                                tick=plan['tick'])
        honest = plan['profile'] == 'honest'
        brick.start()
        node = None
        try:
            if not brick.wait_configured(20):
                self.fail(eseed, 'the brick was not configured within 20 s')
                return
            node = nxt.node_of(self.serial, 20)
            if not node:
                self.fail(eseed, 'no /dev/nxtN within 20 s of the plug (did it come back?)')
                return
            sysfs = '/sys/class/lego-nxt/%s' % os.path.basename(node)
            if self.tamper:
                self.tamper(brick)
            probe = os.open(node, os.O_RDWR)
            try:
                self._dispatch(eseed, plan, brick, node, sysfs, honest)
                if not brick.vanished.is_set() and brick.fd is not None:
                    brick.unplug()
                self._after_unplug(eseed, brick, node, probe)
            finally:
                os.close(probe)
        finally:
            brick.unplug()
            self.actions.update(brick.actions)
            for ln in self.kmsg.splats():
                self.fail(eseed, 'kernel splat: %s' % ln)

    def _dispatch(self, eseed, plan, brick, node, sysfs, honest):
        todo = collections.deque(derive(eseed, 'seq', i) for i in range(plan['sequences']))
        done = 0
        unplug_at = None
        resets = list(plan['resets'])
        reset_threads = []
        replies = []
        pairs = []
        errnos = collections.Counter()
        strict_failures = []
        eproto = []
        stop = False
        # An honest brick, not reset or unplugged until the sequences end:
        # no EIO, EPIPE or ENODEV, and (below) replies paired exactly.
        strict = honest and not plan['resets'] and plan['unplug_after'] is None
        while True:
            now = time.monotonic()
            if unplug_at is None and plan['unplug_after'] is not None and \
                    done >= plan['unplug_after']:
                unplug_at = now + plan['unplug_delay']
            if unplug_at is not None and now >= unplug_at and brick.fd is not None:
                brick.unplug()
                self.info['unplugs_mid_epoch'] += 1
                stop = True
            if brick.vanished.is_set():
                if not stop:
                    self.info['vanished'] += 1
                stop = True
            while resets and done >= resets[0] and not stop:
                resets.pop(0)
                t = threading.Thread(target=lambda: self.info.update(
                    [usb_reset(self.serial).split(':')[0]]), daemon=True)
                t.start()
                reset_threads.append(t)
            for w in self.workers:
                if w.busy is None and todo and not stop:
                    seed = todo.popleft()
                    w.conn.send((seed, node, sysfs, honest, strict))
                    w.busy = (seed, time.monotonic())
                    w.last_status, w.status_since = None, time.monotonic()
            busy = [w for w in self.workers if w.busy]
            if not busy:
                break
            ready = multiprocessing.connection.wait([w.conn for w in busy], timeout=0.05)
            for w in busy:
                if w.conn in ready:
                    try:
                        res = w.conn.recv()
                    except (EOFError, OSError):
                        self.fail(eseed, 'worker %d died in sequence %#x (exit %s)' % (
                            w.index, w.busy[0], w.proc.exitcode))
                        w.kill()
                        w.spawn()
                        continue
                    w.busy = None
                    done += 1
                    self.sequences += 1
                    self.calls += res['calls']
                    self.slowest = max(self.slowest, res['slowest'])
                    self.errnos.update(res['errnos'])
                    replies.extend((res['seed'], r) for r in res['replies'])
                    pairs.extend((res['seed'], tg, r) for tg, r in res['pairs'])
                    errnos.update(res['errnos'])
                    strict_failures.extend(res['strict_failures'])
                    eproto.extend(res['eproto'])
                    for m in res['failures']:
                        self.fail(eseed, m)
                elif self._stuck(w):
                    self._hang(eseed, w)
        for t in reset_threads:
            t.join(60)
            if t.is_alive():
                self.fail(eseed, 'USBDEVFS_RESET did not return within 60 s')
        # Whatever a client got must have come from the brick.
        with brick._sent_lock:
            sent = set(brick.sent)
        for seed, r in replies:
            if r not in sent:
                self.fail(eseed, 'sequence %#x got a reply the brick never sent: %s'
                          % (seed, r.hex()))
        self.info['replies_checked'] += len(replies)
        # Replies carry no sequence number: after a timeout or a signal a
        # late reply may answer a later command with the same opcode. With
        # neither, each reply must be the brick's answer to that very command.
        if not brick.vanished.is_set():     # BootCommand makes even a real brick go
            for m in strict_failures:
                self.fail(eseed, m)
        lost = [k for k in errnos if k.endswith((':ETIMEDOUT', ':EINTR'))]
        self.info['strict_epochs'] += strict
        if strict and not lost and not brick.vanished.is_set():
            # Without a timeout or a signal no reply comes late, so the
            # driver must take every reply of the firmware as it is.
            for m in eproto:
                self.fail(eseed, m)
            self.info['paired_epochs'] += 1
            with brick._sent_lock:
                answered = set(brick.pairs)
            for seed, tg, r in pairs:
                if (tg, r) not in answered:
                    self.fail(eseed, 'sequence %#x: %s got %s, which the brick did not send '
                              'in answer to it' % (seed, tg.hex(), r.hex()))
            self.info['replies_paired'] += len(pairs)

    def _stuck(self, w):
        """The worker's current call has run longer than hang_s."""
        what = w.status.value
        if what != w.last_status:
            w.last_status, w.status_since = what, time.monotonic()
        return time.monotonic() - w.status_since > self.hang_s

    def _hang(self, eseed, w):
        what = w.status.value.decode(errors='replace')
        self.fail(eseed, 'worker %d hung (one call > %.0f s) in %s; kernel stacks:\n%s' % (
            w.index, self.hang_s, what, kernel_stacks(w.proc.pid)))
        w.kill()
        if w.proc.is_alive():
            self.fail(eseed, 'worker %d cannot be killed (stuck in the kernel)' % w.index)
        w.spawn()

    def _after_unplug(self, eseed, brick, node, probe):
        """The node goes; calls on a file that was open fail with ENODEV."""
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            if not os.path.exists(node) and not nxt.interface_of(self.serial):
                break
            time.sleep(0.02)
        else:
            self.fail(eseed, '%s or its interface still there 15 s after the unplug' % node)
            return
        # The driver's sysfs link goes before its disconnect() runs: wait
        # (bounded) for the held file to report the hangup.
        p = select.poll()
        p.register(probe, select.POLLIN | select.POLLOUT)
        t0 = time.monotonic()
        while True:
            ev = dict(p.poll(20)).get(probe, 0)
            hup = ev & (select.POLLERR | select.POLLHUP) == select.POLLERR | select.POLLHUP
            if hup or time.monotonic() - t0 > 10:
                break
        ms = round((time.monotonic() - t0) * 1000)
        self.info['hup_after_gone_max_ms'] = max(self.info['hup_after_gone_max_ms'], ms)
        if not hup:
            self.fail(eseed, 'poll after the unplug: 0x%x 10 s after the node went, '
                      'not POLLERR|POLLHUP' % ev)
        checks = []
        try:
            os.write(probe, b'\x00\x0b')
            checks.append(('write', 0))
        except OSError as e:
            checks.append(('write', e.errno))
        try:
            os.read(probe, 64)
            checks.append(('read', 0))
        except OSError as e:
            checks.append(('read', e.errno))
        checks.append(('TRANSACT', nxt.transact(probe, b'\x01\x88')[0]))
        checks.append(('TRANSACT with no reply', nxt.transact(probe, b'\x80\x0d')[0]))
        for what, err in checks:
            if err != E.ENODEV:
                self.fail(eseed, '%s after the unplug gave %s, not ENODEV' % (what, ename(err)))
        # A number the driver does not know stays unknown.
        num = nxt.retired_number(0x0b)
        err, _ = ioctl_buf(probe, num, bytes(RETIRED_TYPED[0x0b]))
        if err != E.ENOTTY:
            self.fail(eseed, 'ioctl 0x%08x after the unplug gave %s, not ENOTTY'
                      % (num, ename(err)))

    def summary(self):
        return dict(seed=self.seed, epochs=self.epochs, sequences=self.sequences,
                    calls=self.calls, seconds=round(time.monotonic() - self.t0),
                    failures=len(self.failures),
                    slowest_call_s=round(self.slowest, 2), info=dict(self.info),
                    brick_actions=dict(self.actions),
                    errnos=dict(sorted(self.errnos.items())))


def run(sequences, seed, workers=3, per_epoch=24, log=None, **kw):
    """Run the fuzzer; returns the Fuzzer (failures, counts)."""
    fz = Fuzzer(seed, workers=workers, per_epoch=per_epoch, log=log, **kw)
    fz.log('nxt_fuzz: seed %#x: %d sequences, %d per epoch, %d processes (replay: %s)'
        % (seed, sequences, per_epoch, workers, fz.replay_command()))
    try:
        fz.run(sequences)
    finally:
        fz.close()
    return fz


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split('\n', 2)[2])
    num = lambda s: int(s, 0)  # noqa: E731
    ap.add_argument('--seed', type=num, help='run seed (default: random, printed)')
    ap.add_argument('--sequences', type=int, default=300)
    ap.add_argument('--per-epoch', type=int, default=24)
    ap.add_argument('--workers', type=int, default=3)
    ap.add_argument('--op-bound', type=float, default=30.0,
                    help='seconds a call may take before it is a hang (default 30)')
    ap.add_argument('--epoch-seed', type=num, help='replay this one epoch')
    ap.add_argument('--show', type=num, metavar='SEED', help="print a sequence's operations")
    ap.add_argument('--json', metavar='FILE')
    args = ap.parse_args()
    if args.show is not None:
        for i, op in enumerate(gen_sequence(args.show)):
            print('%3d %s' % (i, describe(op)))
        return 0
    if os.environ.get('LEGO_IN_VM') != '1':
        print('nxt_fuzz.py runs inside the test VM (tests/vm-run)', file=sys.stderr)
        return 2
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(1 << 32)
    if args.epoch_seed is not None:
        fz = Fuzzer(seed, workers=args.workers, per_epoch=args.per_epoch, op_bound=args.op_bound)
        print('nxt_fuzz: replaying epoch %#x: %s' % (args.epoch_seed,
                                                    epoch_plan(args.epoch_seed, args.per_epoch)))
        try:
            fz.run_epoch(args.epoch_seed, args.per_epoch)
        finally:
            fz.close()
    else:
        fz = run(args.sequences, seed, workers=args.workers, per_epoch=args.per_epoch,
                 op_bound=args.op_bound)
    s = fz.summary()
    print(json.dumps(s, indent=1))
    for m in fz.failures:
        print('FAIL: ' + m)
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(dict(s, messages=fz.failures), f, indent=1)
    print('nxt_fuzz: %s: %d sequences (%d calls) in %d epochs, %d failure(s); seed %#x' % (
        'PASS' if not fz.failures else 'FAIL', fz.sequences, fz.calls, fz.epochs,
        len(fz.failures), seed))
    if fz.failed_epochs:
        print('nxt_fuzz: replay a failed epoch with: %s' % fz.replay_command(fz.failed_epochs[0]))
    return 1 if fz.failures else 0


if __name__ == '__main__':
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    sys.exit(main())
