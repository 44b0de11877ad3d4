#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""Seed corpora for the fuzz targets, from the emulators' own models.

Usage: tests/fuzz/make-seeds.py [OUTDIR]   (default: tests/fuzz/corpus)

Writes OUTDIR/ev3/* and OUTDIR/nxt/* in the input formats of fuzz_ev3.c and
fuzz_nxt.c:

- ev3: for every sensor tests/emulator/ev3_sensor.py emulates (Powered Up
  devices included), its handshake byte for byte as the emulator sends it,
  followed by DATA messages of every mode (with EXT_MODE for Powered Up) (with the quiet host, seed 0, and with a pseudo-random host); the
  emulator's hostile byte sequences followed by a good handshake.
- nxt: telegrams (as NXT_IOC_TRANSACT and write() take them) and the
  replies tests/emulator/nxt_brick.py's firmware model gives them, with no
  brick information known before them, and those that fill or clear the
  sysfs attributes' information again with all of it known; and those
  replies as a Bluetooth stream (framed, with garbage between).

The output is deterministic; tests/bench/proto uses the same streams.
"""
import os
import random
import struct
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'emulator'))

import ev3_sensor as ev3  # noqa: E402
import nxt_brick as nxt  # noqa: E402

QUIET = bytes(4)        # host seed 0: one batch, answers at once
BUSY = struct.pack('<I', 0x2545f491)


def values(rng, mode):
    lo, hi = mode.raw
    if mode.t == ev3.FLOAT:
        return [rng.uniform(lo, hi) for _ in range(mode.n)]
    bits = {ev3.S8: 8, ev3.S16: 16, ev3.S32: 32}[mode.t]
    lo = max(int(lo), -(1 << (bits - 1)))
    hi = min(int(hi), (1 << (bits - 1)) - 1)
    return [rng.randint(lo, hi) for _ in range(mode.n)]


def frames(sdef, mode, count, rng):
    m = sdef.modes[mode]
    out = b''
    for _ in range(count):
        bad = sdef.type == 29 and mode == 4 and rng.random() < 0.9
        out += ev3.data_frame(sdef, mode, ev3.pack_values(m, values(rng, m)), bad_checksum=bad)
    return out


def ev3_session(sdef, per_mode, rng):
    """A sensor's handshake, then `per_mode` DATA messages of each mode."""
    out = ev3.handshake(sdef)
    for mode in range(len(sdef.modes)):
        out += frames(sdef, mode, per_mode, rng)
    return out


def ev3_seeds():
    rng = random.Random(1)
    seeds = {}
    for name, sdef in sorted(ev3.SENSORS.items()):
        if sdef.lump:
            continue
        seeds['%s-quiet' % name] = QUIET + ev3_session(sdef, 4, rng)
        seeds['%s-busy' % name] = BUSY + ev3_session(sdef, 4, rng)
    # Powered Up devices from a generator of their own: the EV3 seeds stay.
    lrng = random.Random(3)
    for name, sdef in sorted(ev3.SENSORS.items()):
        if sdef.lump:
            seeds['%s-quiet' % name] = QUIET + ev3_session(sdef, 4, lrng)
            seeds['%s-busy' % name] = BUSY + ev3_session(sdef, 4, lrng)
    junk = [ev3.cmd_msg(ev3.CMD_TYPE, [29])[:2] + b'\x00',
            ev3.cmd_msg(ev3.CMD_TYPE, [29]) + bytes([0xb0, 0x00]) + bytes(70),
            ev3.cmd_msg(ev3.CMD_TYPE, [29]) + ev3.cmd_msg(ev3.CMD_MODES, [200, 200]),
            ev3.cmd_msg(ev3.CMD_TYPE, [29]) + ev3.cmd_msg(ev3.CMD_SPEED, struct.pack('<I', 10**9)),
            ev3.cmd_msg(ev3.CMD_TYPE, [29]) + ev3.info_msg(0, ev3.INFO_NAME, b'X' * 16),
            bytes([0xc0, 0x01, 0x02, 0xff] * 8)]
    seeds['hostile-then-color'] = QUIET + b''.join(junk) + ev3_session(ev3.COLOR, 2, rng)
    return seeds


def ev3_stream(per_mode=200, seed=2):
    """The recorded stream of tests/bench/proto: several sensors one after
    the other, each a handshake then mostly DATA messages. Returns the bytes
    and the offsets where a sensor was unplugged (the line went silent
    until the host gave it up)."""
    rng = random.Random(seed)
    out = b''
    unplugged = []
    for name in ('color', 'us', 'gyro', 'ir', 'fcl-humidity'):
        sdef = ev3.SENSORS[name]
        out += ev3.handshake(sdef)
        # The data phase starts in mode 0; the quiet host does not SELECT.
        out += frames(sdef, 0, per_mode * len(sdef.modes), rng)
        unplugged.append(len(out))
    return out, unplugged


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def nxt_firmware():
    clock = Clock()
    fw = nxt.Firmware(now=clock)
    return fw, clock


def nxt_raw_pairs():
    """(telegram, reply) for telegrams the driver or a program sends raw."""
    fw, clock = nxt_firmware()
    tgs = [b'\x01\x88', b'\x01\x9b', b'\x00\x0b', b'\x00\x0d', b'\x00\x11',
           b'\x00\x06\x00', b'\x00\x06\x02', b'\x00\x07\x00', b'\x00\x07\x03',
           b'\x00\x0e\x03', b'\x00\x10\x03', b'\x00\x20\x02', b'\x00\x20\x00',
           b'\x00\x30', b'\x01\x8a\x00\x00',
           b'\x01\x80' + b'Demo.rxe'.ljust(20, b'\0'),
           b'\x01\x82\x00\x10\x00', b'\x01\x82\x00\x40\x00',
           b'\x01\x84\x00',
           b'\x01\x86' + b'*.*'.ljust(20, b'\0'),
           b'\x01\x94\x01\x00\x01\x00\x00\x00\x20\x00',
           b'\x01\xa2\x00\x00\x10',
           b'\x00\x13\x0a\x00\x01',
           # A program runs and has posted a message: a successful
           # MessageRead (its local inbox echoed).
           b'\x00\x00Demo.rxe\0', b'\x00\x0d\x00',
           lambda: fw.program_send(10, b'hello'),
           b'\x00\x13\x0a\x04\x01\x00',
           b'\x01\x98Fuzz\0', b'\x01\xa0']
    pairs = []
    for tg in tgs:
        if callable(tg):
            tg()
            continue
        clock.t += 0.1
        r = fw.handle(tg)
        if r is not None:
            pairs.append((tg, r))
    return pairs


# The telegrams whose replies fill the information the sysfs attributes
# show (GetVersions, GetDeviceInfo, GetBatteryLevel) or that make it
# unknown (SetBrickName, DeleteUserFlash): again with all of it known.
KNOWN_ALL = 0x07
BT_STREAM = 0x80
NOTED = {(0x01, 0x88), (0x01, 0x9b), (0x00, 0x0b), (0x01, 0x98), (0x01, 0xa0)}


def nxt_seeds():
    """fuzz_nxt.c's input: the flags byte (what the brick's information
    holds before the telegram), the telegram's length - 2, the telegram,
    the reply."""
    seeds = {}
    for tg, r in nxt_raw_pairs():
        seeds['raw-%02x%02x-%d' % (tg[0], tg[1], len(tg))] = \
            bytes([0x00, len(tg) - 2]) + tg + r
        if (tg[0], tg[1]) in NOTED:
            seeds['known-%02x%02x-%d' % (tg[0], tg[1], len(tg))] = \
                bytes([KNOWN_ALL, len(tg) - 2]) + tg + r
            # Bluetooth (flags bit 7): the reply framed with its 2-byte
            # length, then line noise and a lying prefix, then again.
            framed = struct.pack('<H', len(r)) + r
            seeds['bt-%02x%02x-%d' % (tg[0], tg[1], len(tg))] = \
                bytes([BT_STREAM | KNOWN_ALL, len(tg) - 2]) + tg + framed + \
                b'\xff\x00\x41\x00\x02' + framed
    return seeds


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(TOP, 'tests', 'fuzz', 'corpus')
    for sub, seeds in (('ev3', ev3_seeds()), ('nxt', nxt_seeds())):
        d = os.path.join(out, sub)
        os.makedirs(d, exist_ok=True)
        for name, data in seeds.items():
            with open(os.path.join(d, name), 'wb') as f:
                f.write(data)
        print('%s: %d seeds, %d bytes' % (d, len(seeds), sum(map(len, seeds.values()))))


if __name__ == '__main__':
    main()
