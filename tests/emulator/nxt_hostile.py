"""A hostile NXT brick: NOT a real brick.

HostileBrick is nxt_brick.RawGadgetBrick (the same USB identity, the same
firmware interpreter, so that files, mailboxes and motors keep a real
brick's state) with a seeded saboteur between the firmware and the IN
endpoint. For each command it receives it draws an action from a profile
(a dict action -> weight) and answers accordingly. No LEGO firmware does
any of this: it exists to make the driver face every kind of bad reply, in
a reproducible order (the random generator is seeded; the order in which
commands arrive from several processes is the scheduler's).

Actions on a command that asks for a reply:

  ok         the firmware's reply
  short      the reply cut to 1 .. len-1 bytes
  long       the reply padded with random bytes, up to 100 (more than one
             packet: a 64-byte packet and the rest in the next one)
  opcode     the reply with another opcode byte
  type       the reply with a type byte other than 0x02
  garbage    1 to 64 random bytes
  zlp        a zero-length packet
  foreign    a well-formed reply (right length) to another opcode
  status     the reply with a random status byte, payload left as it is
  payload    status 0, the right length, random payload (counts out of
             range: LSRead length, MessageRead size, a name with no NUL)
  dup        the reply, twice
  extra      the reply, then a foreign reply or garbage
  before     a foreign reply or garbage, then the reply
  split      the reply in two packets
  late       the reply after 0 to late_max seconds (no command is read
             meanwhile, as a busy firmware)
  missing    no reply
  stall      halt the IN endpoint instead of replying
  stall_out  the reply, then halt the OUT endpoint (the next command stalls)
  vanish     unplug after the command, before replying (mid-transfer)

A command that asks for no reply gets nothing ('ok'), or now and then an
unsolicited reply, garbage, a stall or a vanish.

Every packet put on the IN endpoint is recorded in `sent` (64-byte chunks
of longer writes), so that a test can check that whatever a client got was
sent by the brick and is not, say, stale kernel memory; `pairs` holds each
(command, reply) the firmware answered unspoilt.

Usage: python3 tests/emulator/nxt_hostile.py [--udc dummy_udc.0]
    [--profile NAME] [--seed N] [--verbose]   (runs until SIGTERM/SIGINT)
"""
import argparse
import collections
import random
import sys
import threading
import time

import nxt_brick as nb
from stop_signals import StopSignals

DIRECT_OPS = list(range(0x00, 0x12)) + [0x13] + list(range(0x19, 0x22))
SYSTEM_OPS = [0x80, 0x81, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8b, 0x8c,
              0x8d, 0x90, 0x91, 0x92, 0x94, 0x95, 0x97, 0x98, 0x9a, 0x9b, 0xa0, 0xa1,
              0xa2, 0xa4]

# Whole reply lengths (LEGO's documents; the USB caps for Read, ReadIOMap and
# PollCommand are left out: a foreign reply uses the fixed part).
DIRECT_REPLY_LEN = {0x00: 3, 0x01: 3, 0x02: 3, 0x03: 3, 0x04: 3, 0x05: 3, 0x06: 25,
                    0x07: 16, 0x08: 3, 0x09: 3, 0x0a: 3, 0x0b: 5, 0x0c: 3, 0x0d: 7,
                    0x0e: 4, 0x0f: 3, 0x10: 20, 0x11: 23, 0x13: 64, 0x19: 64, 0x1a: 3,
                    0x1b: 4, 0x1c: 21, 0x1d: 4, 0x1e: 21, 0x1f: 3, 0x20: 4, 0x21: 3}
SYSTEM_REPLY_LEN = {0x80: 8, 0x81: 4, 0x82: 6, 0x83: 6, 0x84: 4, 0x85: 23, 0x86: 28,
                    0x87: 28, 0x88: 7, 0x89: 4, 0x8b: 4, 0x8c: 8, 0x8d: 4, 0x90: 34,
                    0x91: 34, 0x92: 4, 0x94: 9, 0x95: 9, 0x97: 7, 0x98: 3, 0x9a: 10,
                    0x9b: 33, 0xa0: 3, 0xa1: 5, 0xa2: 5, 0xa4: 3}
REPLY_LEN = {**DIRECT_REPLY_LEN, **SYSTEM_REPLY_LEN}

# Every status byte the documents define.
STATUSES = [0x00, 0x20, 0x40] + list(range(0x81, 0x9c)) + [0xbd, 0xbe, 0xbf, 0xc0, 0xdd,
                                                            0xde, 0xdf, 0xe0, 0xec, 0xed,
                                                            0xee, 0xef, 0xf0, 0xfb, 0xff]

ACTIONS = ('ok', 'short', 'long', 'opcode', 'type', 'garbage', 'zlp', 'foreign', 'status',
           'payload', 'dup', 'extra', 'before', 'split', 'late', 'missing', 'stall',
           'stall_out', 'vanish')
NOREPLY_ACTIONS = ('ok', 'unsolicited', 'garbage', 'stall', 'vanish')

_HOSTILE = {a: 5 for a in ACTIONS}
_HOSTILE.update(ok=20, vanish=1, late=3)
PROFILES = {
    # The firmware as it is (still not quite a brick: see nxt_brick.py).
    'honest': {'ok': 1},
    # Mostly right, now and then anything.
    'flaky': dict({a: 1 for a in ACTIONS}, ok=60, vanish=0.2),
    # Anything, often.
    'hostile': _HOSTILE,
    # Answers late, or not at all.
    'silent': {'ok': 30, 'late': 30, 'missing': 30, 'stall': 5, 'stall_out': 5},
    # Says too much: duplicates, junk around the replies.
    'babbler': {'ok': 20, 'dup': 20, 'extra': 20, 'before': 20, 'split': 10, 'long': 5,
                'foreign': 5},
    # Well-formed replies with bad contents.
    'liar': {'ok': 20, 'status': 30, 'payload': 30, 'foreign': 10, 'opcode': 10},
}


class HostileBrick(nb.RawGadgetBrick):
    """NOT A REAL BRICK: a RawGadgetBrick that sabotages its replies (see
    the module docstring). `profile` is a PROFILES name or a dict of
    action weights; `seed` seeds the saboteur (and the firmware)."""

    def __init__(self, profile='hostile', seed=1, late_max=1.0, noreply_hostility=0.05,
                 **kw):
        kw.setdefault('firmware', nb.Firmware(seed=seed, name=kw.get('name', 'NXT'),
                                              bt_address=kw.get('serial', '001653A0B1C2')))
        super().__init__(seed=seed, **kw)
        weights = PROFILES[profile] if isinstance(profile, str) else profile
        unknown = set(weights) - set(ACTIONS)
        if unknown:
            raise ValueError('unknown actions %s' % sorted(unknown))
        self.profile_name = profile if isinstance(profile, str) else 'custom'
        self._actions = [a for a in weights if weights[a] > 0]
        self._weights = [weights[a] for a in self._actions]
        self.hrng = random.Random(seed ^ 0x5EED)
        self.late_max = late_max
        self.noreply_hostility = noreply_hostility
        self.sent = set()
        self.pairs = set()      # (command, reply) of every unspoilt reply
        self.actions = collections.Counter()
        self.vanished = threading.Event()
        self._sent_lock = threading.Lock()

    # ---- choosing ----

    def choose(self, packet, reply):
        r = self.hrng
        if reply is None:
            if self.profile_name == 'honest' or r.random() >= self.noreply_hostility:
                return 'ok'
            return r.choice(NOREPLY_ACTIONS[1:])
        return r.choices(self._actions, self._weights)[0]

    def _junk(self):
        r = self.hrng
        if r.random() < 0.5:
            return self._foreign(None)
        return bytes(r.randrange(256) for _ in range(r.randint(1, 64)))

    def _foreign(self, op):
        """A well-formed reply to an opcode other than `op`."""
        r = self.hrng
        other = r.choice([o for o in REPLY_LEN if o != op])
        n = REPLY_LEN[other]
        return bytes([nb.REPLY, other, r.choice(STATUSES)]) + bytes(
            r.randrange(256) for _ in range(n - 3))

    def _payload(self, reply):
        """Status 0, random payload; the counts the driver checks out of range."""
        r = self.hrng
        body = bytearray(r.randrange(256) for _ in range(len(reply) - 3))
        op = reply[1]
        if body:
            if op == 0x10 and r.random() < 0.7:          # LSRead: length
                body[0] = r.randint(17, 255)
            elif op == 0x13 and len(body) > 1 and r.random() < 0.7:   # MessageRead: size
                body[1] = r.randint(60, 255)
            elif op == 0x0e and r.random() < 0.7:        # LSGetStatus: bytes ready
                body[0] = r.randint(17, 255)
            elif op == 0x11 and r.random() < 0.7:        # program name: no NUL
                body[:] = bytes(r.randint(1, 255) for _ in body)
        return bytes(reply[:2]) + b'\0' + bytes(body)

    # ---- sending ----

    def _record(self, data):
        with self._sent_lock:
            if not data:
                self.sent.add(b'')
            for i in range(0, len(data), 64):
                self.sent.add(bytes(data[i:i + 64]))

    def _emit(self, data, wait=True):
        """Queue one IN write (a longer one goes out as several packets) and,
        like the firmware, wait up to reply_timeout for the host to take it."""
        self._record(data)
        item = nb._Reply(bytes(data))
        with self._cond:
            if len(self._banks) >= nb.IN_BANKS:
                self.replies_lost += 1
                self.log('packet lost, both IN banks full: %s' % bytes(data).hex())
                return
            self._banks.append(item)
            self._cond.notify_all()
        if wait:
            deadline = time.monotonic() + self.reply_timeout
            while not self._stopping.is_set():
                left = deadline - time.monotonic()
                if left <= 0 or item.collected.wait(min(left, 0.05)):
                    break

    def _halt(self, ep, what):
        try:
            nb._ioctl(self.fd, nb.USB_RAW_IOCTL_EP_SET_HALT, ep)
            self.log('halted the %s endpoint' % what)
        except (OSError, TypeError) as e:
            self.log('set halt (%s) failed: %s' % (what, e))

    def act(self, action, packet, reply):
        r = self.hrng
        if action == 'ok':
            if reply is not None:
                self._emit(reply)
        elif action == 'unsolicited':
            op = packet[1] if len(packet) > 1 else 0
            n = REPLY_LEN.get(op, 3)
            self._emit(bytes([nb.REPLY, op, 0]) + bytes(r.randrange(256) for _ in range(n - 3)))
        elif action == 'short':
            self._emit(reply[:r.randint(1, max(1, len(reply) - 1))])
        elif action == 'long':
            n = r.randint(len(reply) + 1, 100)
            self._emit(reply + bytes(r.randrange(256) for _ in range(n - len(reply))))
        elif action == 'opcode':
            self._emit(reply[:1] + bytes([(reply[1] + r.randint(1, 255)) & 0xFF]) + reply[2:])
        elif action == 'type':
            t = r.choice([b for b in range(256) if b != nb.REPLY])
            self._emit(bytes([t]) + reply[1:])
        elif action == 'garbage':
            self._emit(bytes(r.randrange(256) for _ in range(r.randint(1, 64))))
        elif action == 'zlp':
            self._emit(b'')
        elif action == 'foreign':
            self._emit(self._foreign(reply[1]))
        elif action == 'status':
            st = r.choice(STATUSES[1:]) if r.random() < 0.8 else r.randrange(1, 256)
            self._emit(reply[:2] + bytes([st]) + reply[3:])
        elif action == 'payload':
            self._emit(self._payload(reply))
        elif action == 'dup':
            self._emit(reply)
            self._emit(reply)
        elif action == 'extra':
            self._emit(reply)
            self._emit(self._junk())
        elif action == 'before':
            self._emit(self._junk(), wait=False)
            self._emit(reply)
        elif action == 'split':
            k = r.randint(1, len(reply) - 1)
            self._emit(reply[:k], wait=False)
            self._emit(reply[k:])
        elif action == 'late':
            self._stopping.wait(r.uniform(0, self.late_max))
            self._emit(reply)
        elif action == 'missing':
            pass
        elif action == 'stall':
            self._halt(self._ep_in, 'IN')
        elif action == 'stall_out':
            if reply is not None:
                self._emit(reply)
            self._halt(self._ep_out, 'OUT')
        elif action == 'vanish':
            self.vanished.set()
            self._unplug_soon('vanishing in mid-transfer')
        else:
            raise ValueError(action)

    # ---- the command loop ----

    def _command_loop(self):
        while not self._stopping.is_set():
            packet = self._next_command()
            if packet is None:
                continue
            if self.tick:
                self._wait_for_pass()
            reply = self.fw.handle(packet)
            action = self.choose(packet, reply)
            self.actions[action] += 1
            if action in ('ok', 'late', 'dup') and reply is not None:
                with self._sent_lock:
                    self.pairs.add((bytes(packet), bytes(reply)))
            self.log('command %s: %s' % (packet.hex(), action))
            if self.fw.busy:
                self._stopping.wait(self.fw.busy)
            try:
                self.act(action, packet, reply)
            except OSError as e:
                if not self._stopping.is_set():
                    self.log('%s failed: %s' % (action, e))
            if self.tick:
                self._pass_done()
            if action == 'vanish':
                return
            if self.fw.rebooting:
                self.vanished.set()
                self._unplug_soon('rebooting into SAM-BA (not emulated)')
                return


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--udc', default='dummy_udc.0')
    ap.add_argument('--driver', default='dummy_udc')
    ap.add_argument('--serial', default='001653A0B1C2')
    ap.add_argument('--profile', default='hostile', choices=sorted(PROFILES))
    ap.add_argument('--seed', type=lambda s: int(s, 0), default=1)
    ap.add_argument('--verbose', action='store_true')
    args = ap.parse_args()
    stop = StopSignals()
    brick = HostileBrick(profile=args.profile, seed=args.seed, udc=args.udc,
                         driver=args.driver, serial=args.serial, verbose=args.verbose)
    brick.start()
    announced = False
    while not stop.wait(0.1):
        if not announced and brick.configured.is_set():
            print('nxt_hostile: configured on %s (NOT a real brick: profile %s, seed %d)'
                  % (args.udc, args.profile, args.seed), flush=True)
            announced = True
    brick.stop()
    print('nxt_hostile: actions %s' % dict(brick.actions))


if __name__ == '__main__':
    sys.exit(main())
