#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""The recorded inputs of tests/bench/proto, from the emulators' models.

Usage: tests/bench/proto/make-streams.py OUTDIR [--quick]

- OUTDIR/ev3.stream: what a UART receives from five sensors plugged in one
  after the other (colour, ultrasonic, gyro, infrared, FatcatLab humidity):
  each handshake byte for byte as tests/emulator/ev3_sensor.py sends it,
  then DATA messages of mode 0 (200 per mode the sensor has; 20 with
  --quick). OUTDIR/ev3.unplug: the offsets in the stream where the sensor
  was unplugged (one a line): the line is silent then until the host's
  keep-alive gives the sensor up.
- The three stream shapes of issue 19, each OUTDIR/NAME.stream with an empty
  OUTDIR/NAME.unplug (the sensor stays plugged in) and OUTDIR/NAME.json
  (what it holds: sensor, handshake length, mode, messages, bad checksums):
  gyro-ang: the gyro's handshake, then 100000 GYRO-ANG DATA messages
  (mode 0, 4 bytes each; 10000 with --quick);
  color-rgb-raw: the colour sensor's handshake, then 50000 RGB-RAW DATA
  messages (mode 4, header 0xdc, 10 bytes each; 5000 with --quick), nine
  in ten with the wrong checksum the real firmware sends; the host SELECTs
  mode 4 after the handshake;
  gyro-old-handshake: the handshake of the old (5-mode) gyro firmware, 244
  bytes, and nothing else.
- Issue 20's Powered Up shape, the same way: boost-rgb-i: the BOOST colour
  and distance sensor's recorded handshake (716 bytes), then 50000 RGB I
  DATA messages (mode 6, 3 x s16 in 8 bytes) each after an EXT_MODE
  message, 13 bytes a pair (5000 with --quick); the host SELECTs mode 6.
- OUTDIR/nxt.records: a program's polling loop against
  tests/emulator/nxt_brick.py's firmware model, with its replies: 4 x
  GetInputValues, 3 x GetOutputState, SetOutputState, LSWrite,
  LSGetStatus, LSRead (ultrasonic), MessageRead per cycle; GetBatteryLevel
  and KeepAlive every 10 cycles; GetVersions and GetDeviceInfo (sysfs)
  every 50. 500 cycles (50 with --quick). Record format: see bench_nxt.c.

Deterministic: the same files every time.
"""
import importlib.util
import json
import os
import random
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', '..'))
spec = importlib.util.spec_from_file_location('make_seeds',
                                              os.path.join(TOP, 'tests', 'fuzz', 'make-seeds.py'))
seeds = importlib.util.module_from_spec(spec)
spec.loader.exec_module(seeds)
sensors = seeds.ev3

# The records' kind byte, which bench_nxt.c reads and ignores (it once named
# the typed ioctl of the record; kept so that the record format stays).
SET_OUTPUT_STATE, SET_INPUT_MODE, GET_OUTPUT_STATE, GET_INPUT_VALUES = 5, 6, 7, 8
BATTERY, KEEP_ALIVE, LS_GET_STATUS, LS_WRITE, LS_READ, MESSAGE_READ = 12, 14, 15, 16, 17, 19
RAW = 0


def nxt_records(cycles):
    fw, clock = seeds.nxt_firmware()
    out = bytearray()

    def cmd(kind, tg):
        clock.t += 0.01
        r = fw.handle(tg)
        assert r is not None and len(r) <= 64, tg.hex()
        out.extend(bytes([kind, len(tg)]) + tg + bytes([len(r)]) + r)

    cmd(SET_INPUT_MODE, b'\x00\x05\x03\x0b\x00')        # port 4: low-speed 9 V
    for port in range(3):                               # motors on, regulated
        cmd(SET_OUTPUT_STATE, bytes([0x00, 0x04, port, 60, 0x07, 0x01, 0, 0x20]) + bytes(4))
    for i in range(cycles):
        for port in range(4):
            cmd(GET_INPUT_VALUES, bytes([0x00, 0x07, port]))
        for port in range(3):
            cmd(GET_OUTPUT_STATE, bytes([0x00, 0x06, port]))
        cmd(SET_OUTPUT_STATE, bytes([0x00, 0x04, i % 3, 40 + i % 40, 0x07, 0x01, 0, 0x20]) + bytes(4))
        cmd(LS_WRITE, b'\x00\x0f\x03\x02\x01\x02\x42')   # ultrasonic: read distance
        cmd(LS_GET_STATUS, b'\x00\x0e\x03')
        cmd(LS_READ, b'\x00\x10\x03')
        if i % 7 == 0:
            fw.program_send(10, b'msg %d' % i)
        cmd(MESSAGE_READ, b'\x00\x13\x0a\x00\x01')
        if i % 10 == 0:
            cmd(BATTERY, b'\x00\x0b')
            cmd(KEEP_ALIVE, b'\x00\x0d')
        if i % 50 == 0:
            cmd(RAW, b'\x01\x88')
            cmd(RAW, b'\x01\x9b')
    return bytes(out)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    quick = '--quick' in sys.argv[2:]
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    ev3, unplugged = seeds.ev3_stream(per_mode=20 if quick else 200)
    nxt = nxt_records(50 if quick else 500)
    with open(os.path.join(out, 'ev3.stream'), 'wb') as f:
        f.write(ev3)
    with open(os.path.join(out, 'ev3.unplug'), 'w') as f:
        f.write(''.join('%d\n' % o for o in unplugged))
    with open(os.path.join(out, 'nxt.records'), 'wb') as f:
        f.write(nxt)
    n = 10 if quick else 1
    rng = random.Random(19)
    shapes = {}
    for name, sdef, firmware, mode, count in (
            ('gyro-ang', sensors.GYRO, 'new', 0, 100000 // n),
            ('color-rgb-raw', sensors.COLOR, None, 4, 50000 // n),
            ('gyro-old-handshake', sensors.GYRO_OLD, 'old', None, 0),
            ('boost-rgb-i', sensors.BOOST_CDS, None, 6, 50000 // n)):
        hs = sensors.handshake(sdef)
        data = seeds.frames(sdef, mode, count, rng) if count else b''
        size = len(data) // count if count else 0
        # What the stream holds, for the figures' notes (proto/run.sh).
        info = {'sensor': sdef.driver, 'firmware': firmware, 'handshake_bytes': len(hs),
                'mode': mode, 'mode_name': sdef.modes[mode].name if count else None,
                'messages': count, 'message_bytes': size,
                'bad_checksums': 0 if sdef.lump else
                sum(1 for i in range(0, len(data), size or 1)
                    if sensors.checksum(data[i:i + size - 1]) != data[i + size - 1])}
        shapes[name] = hs + data
        with open(os.path.join(out, name + '.stream'), 'wb') as f:
            f.write(hs + data)
        open(os.path.join(out, name + '.unplug'), 'w').close()
        with open(os.path.join(out, name + '.json'), 'w') as f:
            json.dump(info, f, indent=1)
            f.write('\n')
    print('ev3.stream: %d bytes; nxt.records: %d bytes; %s' %
          (len(ev3), len(nxt), ', '.join('%s.stream: %d bytes' % (k, len(v))
                                          for k, v in shapes.items())))


if __name__ == '__main__':
    main()
