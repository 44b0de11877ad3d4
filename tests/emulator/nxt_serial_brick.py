"""An emulated LEGO MINDSTORMS NXT brick on a Bluetooth serial link.

The brick's Bluetooth side, as shared/research/nxt.md describes it, over
any byte stream: a pty's master (the host attaches lego_nxt_serial to the
slave with `nxtctl attach`), or an RFCOMM socket (the brick as a server on
channel 1 of a virtual Bluetooth controller). The firmware behind it is
nxt_brick.Firmware, the same as on USB.

- Framing: each telegram and each reply is preceded by a 2-byte
  little-endian length that does not count itself (LEGO's direct command
  document). The brick reads the length, then that many bytes; a frame
  longer than 64 bytes is read and dropped (assumed: the firmware's
  Bluetooth buffer holds one 64-byte telegram).
- Timing: a reply leaves `latency` seconds (default 30 ms) after its
  command came: replies take 30 ms and more on Bluetooth (users measure
  100-150 ms a round trip through a host's stack). LEGO's developer kit
  asks hosts for about 30 ms between a reply and the next command; what
  the brick does with a command that comes sooner is not documented. The
  emulator drops it (`gap` seconds, default 30 ms; 0 turns this off), so
  that a host that does not keep the gap is seen to lose commands.
- Files opened over Bluetooth stay open when the link goes (only USB
  handles are closed on an unplug).

`hostile` makes a misbehaving link: `lying` (a length prefix that lies
before each reply: 0, over 64, or a frame of garbage), `noreply` (no reply
at all), `hangup` (the link goes after a command is read, before its
reply), `fuzz` (random bytes, random frames and lying prefixes around the
reply, which it sometimes leaves out or cuts short; `seed` picks them).
Tests use SerialBrick(fd) with start(), stop(), hangup(), set and
clear `deaf` (the brick reads nothing meanwhile, as a stuck link), and read
`log` (the times each command came and each reply left).

Usage: python3 tests/emulator/nxt_serial_brick.py --pty
prints the pty's slave path, then serves until SIGTERM or SIGINT.
"""
import argparse
import errno
import os
import random
import select
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import nxt_brick  # noqa: E402
from stop_signals import StopSignals  # noqa: E402

TELEGRAM_MAX = 64
LATENCY = 0.030
GAP = 0.030
HOSTILE = ('lying', 'noreply', 'hangup', 'fuzz')


class SerialBrick:
    """A brick serving Firmware telegrams on the byte stream `fd` (which it
    closes on stop() or hangup())."""

    def __init__(self, fd, firmware=None, latency=LATENCY, gap=GAP, hostile=None,
                 now=time.monotonic, seed=0):
        if hostile not in (None,) + HOSTILE:
            raise ValueError('hostile: one of %s' % (HOSTILE,))
        self.fd = fd
        self.fw = firmware or nxt_brick.Firmware()
        self.latency = latency
        self.gap = gap
        self.hostile = hostile
        self.now = now
        self.log = []               # ('cmd', t, telegram) and ('reply', t, reply)
        self.dropped = []           # telegrams dropped for coming too soon
        self.oversized = 0          # frames over 64 bytes, dropped
        self.last_reply = None
        self.stopping = threading.Event()
        self.gone = threading.Event()
        self.deaf = threading.Event()   # set: reads nothing (the host's tty fills)
        self.lock = threading.Lock()
        self.thread = None
        self._lie = 0
        self.rng = random.Random(seed)

    def start(self):
        self.thread = threading.Thread(target=self._loop, name='nxt-serial-brick', daemon=True)
        self.thread.start()
        return self

    def stop(self):
        self.stopping.set()
        if self.thread:
            self.thread.join(5)
        self._close()

    def hangup(self):
        """The link goes: the host's tty hangs up (pty) or the socket closes."""
        self.stopping.set()
        self._close()
        if self.thread:
            self.thread.join(5)

    def _close(self):
        with self.lock:
            if self.fd is not None:
                try:
                    os.close(self.fd)
                except OSError:
                    pass
                self.fd = None
                self.gone.set()

    def _read(self, n):
        """n bytes, or None once stopped or the link is gone."""
        buf = b''
        while len(buf) < n:
            if self.stopping.is_set():
                return None
            fd = self.fd
            if fd is None:
                return None
            if self.deaf.is_set():
                time.sleep(0.02)
                continue
            try:
                r, _, _ = select.select([fd], [], [], 0.1)
                if not r:
                    continue
                chunk = os.read(fd, n - len(buf))
            except OSError as e:
                if e.errno == errno.EIO:
                    # A pty master whose slave nobody holds open (not yet
                    # attached, or detached): wait for the host.
                    time.sleep(0.05)
                    continue
                return None
            if not chunk:
                return None
            buf += chunk
        return buf

    def _write(self, data):
        with self.lock:
            if self.fd is None:
                return
            try:
                os.write(self.fd, data)
            except OSError:
                pass

    def _frame(self, reply):
        return struct.pack('<H', len(reply)) + reply

    def _lies(self):
        """What a lying link puts before a reply, in turn."""
        self._lie += 1
        return [b'\x00\x00', b'\x41\x00\x02', b'\x05\x01\x02', b'\xff\x13\x37\x00'][self._lie % 4]

    def _fuzz(self, reply):
        """The reply among random bytes and frames, or cut, or left out."""
        r = self.rng
        out = b''
        for _ in range(r.randrange(3)):
            kind = r.randrange(4)
            if kind == 0:
                out += bytes(r.randrange(256) for _ in range(r.randrange(1, 12)))
            elif kind == 1:     # a frame of the right shape, of garbage
                body = b'\x02' + bytes(r.randrange(256) for _ in range(r.randrange(2, 64)))
                out += self._frame(body)
            elif kind == 2:     # a length that lies
                out += struct.pack('<H', r.choice([0, 1, 2, 65, 300, 0xffff]))
            else:               # a reply's frame cut short
                out += self._frame(reply)[:r.randrange(1, len(reply) + 2)]
        choice = r.randrange(10)
        if choice == 0:
            return out          # no reply
        if choice == 1:
            return out + self._frame(reply)[:-1]
        return out + self._frame(reply)

    def _loop(self):
        while not self.stopping.is_set():
            head = self._read(2)
            if head is None:
                break
            (n,) = struct.unpack('<H', head)
            body = self._read(n) if n else b''
            if body is None:
                break
            t = self.now()
            if n == 0:
                continue
            if n > TELEGRAM_MAX:
                self.oversized += 1
                continue
            if self.gap and self.last_reply is not None and t - self.last_reply < self.gap:
                self.dropped.append((t, body))
                continue
            self.log.append(('cmd', t, body))
            if self.hostile == 'hangup':
                self.hangup()
                break
            reply = self.fw.handle(body)
            if reply is None or self.hostile == 'noreply':
                continue
            delay = self.latency + self.fw.busy
            if delay > 0:
                time.sleep(delay)
            # The gap runs from when the reply leaves: taken before the
            # write, since the host may have it before this thread runs on.
            self.last_reply = self.now()
            if self.hostile == 'lying':
                self._write(self._lies())
            if self.hostile == 'fuzz':
                self._write(self._fuzz(reply))
            else:
                self._write(self._frame(reply))
            self.log.append(('reply', self.last_reply, reply))
        self.gone.set()


def open_pty():
    """(master fd, slave path) of a new pty, raw on both sides."""
    import tty
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    return master, path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--pty', action='store_true', required=True,
                    help='serve on a new pty; print its slave path')
    ap.add_argument('--name', default='NXT')
    ap.add_argument('--latency-ms', type=float, default=LATENCY * 1000)
    ap.add_argument('--gap-ms', type=float, default=GAP * 1000)
    ap.add_argument('--hostile', choices=HOSTILE)
    args = ap.parse_args()
    stop = StopSignals()
    master, path = open_pty()
    brick = SerialBrick(master, nxt_brick.Firmware(name=args.name),
                        latency=args.latency_ms / 1000, gap=args.gap_ms / 1000,
                        hostile=args.hostile).start()
    print(path, flush=True)
    while not stop.wait(0.2) and not brick.gone.is_set():
        pass
    brick.stop()


if __name__ == '__main__':
    main()
