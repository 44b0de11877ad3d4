#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""Checks of the Powered Up (LUMP) device definitions of ev3_sensor.py, on
the host (no VM):

- handshake(BOOST_CDS) is byte for byte the handshake a logic analyser
  recorded from a BOOST colour and distance sensor (the bytes of Pybricks'
  lib/pbio/test/src/test_lump.c, the same as in the parser's KUnit suite);
- every Powered Up definition has at most 16 modes, names of at most 11
  characters (5 with flags), at most 32 bytes of values a mode, and its
  handshake has right checksums.

  python3 tests/emulator/test_lump_defs.py     (or: python3 -m pytest ...)
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ev3_sensor as ev3  # noqa: E402

BOOST_CDS_RECORDED = bytes.fromhex(
    '40259a5107070a07a35200c201006e5f0000001000000010a09a2043414c4942'
    '000000009a210000000000ff7f47839a22000000000000c842cd9a2300000000'
    '00ff7f478192244e2f4100698a2510004092a008010500c19920444542554700'
    '00001799210000000000c07f44bc9922000000000000c842ce99230000000000'
    '0020412491244e2f41006a892510004391a002010500c8982053504543203100'
    '005398210000000000007f437a9822000000000000c842cf9823000000000000'
    '7f437890244e2f41006b882500005290a004000300c89f004952205478000000'
    '779f010000000000ff7f47a69f02000000000000c842e89f030000000000ff7f'
    '47a497044e2f41004c8f05000471978001010500ed9e0052474220490000005f'
    '9e010000000000c07f449b9e02000000000000c842e99e030000000000c07f44'
    '99960452415700298e05100064968003010500ee9d00434f4c204f0000004d9d'
    '010000000000002041029d02000000000000c842ea9d03000000000000204100'
    '9504494458003b8d05000473958001000300e89400414d42496c9c0100000000'
    '0000c842e89c02000000000000c842eb9c03000000000000c842ea9404504354'
    '00288c05100066948001000300e99b005245464c540000002d9b010000000000'
    '00c842ef9b02000000000000c842ec9b03000000000000c842ed930450435400'
    '2f8b05100061938001000300ee9a00434f554e54000000269a01000000000000'
    'c842ee9a02000000000000c842ed9a03000000000000c842ec9204434e540030'
    '8a05080078928001020400ea910050524f587b99010000000000002041069902'
    '000000000000c842ee9903000000000000204104910444495300348905500023'
    '918001000300ec9800434f4c4f520000003a9801000000000000204107980200'
    '0000000000c842ef98030000000000002041059004494458003e8805c400b690'
    '8001000300ed88064f003e04')

SIZE = {ev3.S8: 1, ev3.S16: 2, ev3.S32: 4, ev3.FLOAT: 4}


def messages(data):
    """Split a handshake into messages (SYS bytes alone)."""
    i = 0
    while i < len(data):
        h = data[i]
        if h < 0x40:
            yield data[i:i + 1]
            i += 1
            continue
        n = (1 << ((h >> 3) & 7)) + (3 if h & 0xc0 == 0x80 else 2)
        yield data[i:i + n]
        i += n


def test_boost_cds_recorded():
    assert ev3.handshake(ev3.BOOST_CDS) == BOOST_CDS_RECORDED


def described_modes(data):
    """{mode: (name, values, type)} of a Powered Up handshake."""
    names, formats = {}, {}
    for msg in messages(data):
        if len(msg) < 3 or msg[0] & 0xc0 != 0x80:
            continue
        mode = (msg[0] & 7) + (8 if msg[1] & 0x20 else 0)
        itype = msg[1] & ~0x20
        if itype == 0:
            names[mode] = msg[2:-1].split(b'\0')[0].decode()
        elif itype == 0x80:
            formats[mode] = (msg[2], msg[3])
    return {m: (names[m],) + formats[m] for m in names}


def test_technic_l_recorded():
    """The Technic Large motor's definition says what its recorded
    handshake says: mode names, value counts and types, MODE_COMBOS."""
    s = ev3.TECHNIC_L
    assert ev3.handshake(s) == ev3.TECHNIC_L_RECORDED
    got = described_modes(ev3.TECHNIC_L_RECORDED)
    assert got == {i: (m.name, m.n, m.t) for i, m in enumerate(s.modes)}
    combos = [msg for msg in messages(ev3.TECHNIC_L_RECORDED) if msg[:2] == bytes([0x88, 0x06])]
    assert [int.from_bytes(m[2:4], 'little') for m in combos] == list(s.combos)
    assert ev3.TECHNIC_L_RECORDED[1] == 0x2e and s.type == 0x2e


def test_lump_defs():
    lump = [s for s in ev3.SENSORS.values() if s.lump]
    assert len(lump) >= 3
    for s in lump:
        assert 1 <= len(s.modes) <= 16 and 1 <= s.views <= len(s.modes)
        for m in s.modes:
            assert len(m.name) <= (5 if m.flags is not None else 11)
            assert m.n * SIZE[m.t] <= 32
        for msg in messages(ev3.handshake(s)):
            if len(msg) > 1:
                assert ev3.checksum(msg[:-1]) == msg[-1], msg.hex()


if __name__ == '__main__':
    test_boost_cds_recorded()
    test_technic_l_recorded()
    test_lump_defs()
    print('ok')
