#!/usr/bin/env python3
"""Reproducer (found by nxt_fuzz.py): write() fails with the reply's error.

nxt-usb.rst: "write() sends one telegram ... and returns once the brick has
taken it. If the telegram asks for a reply, the next read() on the same open
file returns it". But nxt_xfer_start() returns the transaction's status once
the OUT transfer is done, and if the reply (or the IN endpoint's stall) has
already been judged by then, write() fails with its EPROTO or EPIPE, although
the brick took and answered the telegram; the read() that follows gives
ENODATA. Which call reports the error depends on how fast the writer runs
after the OUT completion, so a caller cannot tell whether its telegram went
(a retry repeats a Write or MessageWrite that the brick executed).

Runs in the test VM:
  tests/vm-run -- python3 tests/soak/nxt_write_reply_error.py [short|stall] [COUNT]
Against a hostile brick (nxt_hostile.py, NOT a real brick) that answers every
command with a short reply ('short': EPROTO) or by stalling IN ('stall':
EPIPE), with two busy processes delaying the writer. Prints the errnos of
write() and read() and exits 1 if any write() failed although the brick had
received the telegram.
"""
import errno
import multiprocessing
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'guest'))
sys.path.insert(0, os.path.join(HERE, '..', 'emulator'))
import nxtdev as nxt  # noqa: E402
import nxt_hostile as nh  # noqa: E402

SERIAL = '0016530F0E02'


def ename(err):
    return errno.errorcode.get(err, str(err)) if err else 'ok'


def burn():
    while True:
        pass


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else 'short'
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 300
    nxt.load_driver()
    burners = [multiprocessing.Process(target=burn, daemon=True) for _ in range(2)]
    for b in burners:
        b.start()
    brick = nh.HostileBrick(profile={mode: 1}, seed=1, udc='dummy_udc.0', serial=SERIAL)
    brick.start()
    try:
        assert brick.wait_configured(20), 'brick not configured'
        fd = os.open(nxt.node_of(SERIAL, 20), os.O_RDWR)
        assert nxt.set_timeout(fd, 300) == 0
        os.nice(10)
        writes, reads, bad = {}, {}, 0
        for _ in range(count):
            before = brick.commands
            try:
                os.write(fd, b'\x00\x0b')           # GetBatteryLevel
                err = 0
            except OSError as e:
                err = e.errno
            if err in (errno.EPROTO, errno.EPIPE) and brick.commands > before:
                bad += 1                            # taken by the brick, yet failed
            writes[ename(err)] = writes.get(ename(err), 0) + 1
            try:
                os.read(fd, 64)
                err = 0
            except OSError as e:
                err = e.errno
            reads[ename(err)] = reads.get(ename(err), 0) + 1
        os.close(fd)
    finally:
        for b in burners:
            b.kill()
        brick.unplug()
    print('%s: write() %s; read() %s; %d write()s failed with the reply\'s error although '
          'the brick had the telegram' % (mode, writes, reads, bad), flush=True)
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
