"""The NXT brick on Bluetooth, through the kernel's own Bluetooth stack: two
virtual controllers (the kernel's vhci, driven by btvirt of
bluez-test-tools), the emulated brick (tests/emulator/nxt_serial_brick.py)
an RFCOMM server on channel 1 of one, and `nxtctl connect` on the other,
which gives the brick its /dev/nxtN through lego_nxt_serial.

What is checked: nxtctl info, upload and download of a 3001-byte file, raw
telegrams from several processes, nxt-python through the backend, a link
broken in the middle of a transaction (ENODEV for the caller, the node and
the RFCOMM tty gone), and nxtctl disconnect (the link ends too).
"""
import errno
import os
import random
import re
import subprocess
import sys
import threading
import time

import pytest

import btlink
import nxtdev as nxt
from conftest import loaded, module_path, wait_for

TOOLS_PYTHON = os.path.join(nxt.TOP, 'tools', 'python')
RUNDIR = nxt.NXTCTL_RUNDIR


ctl = nxt.nxtctl
ok = nxt.nxtctl_ok


@pytest.fixture(scope='module')
def radio():
    """Two virtual controllers, up."""
    if not loaded('lego_nxt_serial'):
        subprocess.run(['insmod', module_path('lego_nxt_serial')], check=True)
    r = btlink.Radio()
    yield r
    r.stop()


def connect(radio, hostile=None):
    srv = btlink.BrickServer(radio.brick, hostile=hostile)
    t = time.monotonic()
    p = ctl('connect', radio.brick, timeout=60)
    assert p.returncode == 0 and p.stderr == '', (p.returncode, p.stdout, p.stderr, srv.close())
    node = p.stdout.strip()
    assert node.startswith('/dev/nxt') and os.path.exists(node), node
    assert srv.accepted.wait(5)
    return srv, node, time.monotonic() - t


def tty_of(node):
    with open(os.path.join(RUNDIR, os.path.basename(node))) as f:
        return f.read().split()[1]


def test_connect_and_use_the_brick(radio, tmp_path):
    srv, node, took = connect(radio)
    try:
        rfcomm = tty_of(node)
        assert re.match(r'^/dev/rfcomm[0-9]+$', rfcomm), rfcomm
        info = dict(line.split(': ', 1) for line in ok(ctl('-d', node, 'info')).splitlines())
        assert info['name'] == 'BT-NXT', info
        # Upload and download of a 3001-byte file.
        data = bytes(random.Random(3001).randrange(256) for _ in range(3001))
        src = tmp_path / 'src.bin'
        src.write_bytes(data)
        ok(ctl('-d', node, 'upload', src, 'bt.dat'))
        assert bytes(srv.fw.files['bt.dat'].data) == data
        dst = tmp_path / 'dst.bin'
        ok(ctl('-d', node, 'download', 'bt.dat', dst))
        assert dst.read_bytes() == data
        # Raw telegrams from several processes, each its own replies.
        assert nxt.mixed_clients(node, 3, 10) == [(i, 0) for i in range(3)]
        assert srv.brick.dropped == []
        # nxt-python through the backend, on the Bluetooth node.
        r = subprocess.run([sys.executable, '-c', (
            'import sys; sys.path.insert(0, %r)\n'
            'import lego_nxt_linux, nxt.locator\n'
            'b = nxt.locator.find(config=None, backends=[lego_nxt_linux.get_backend()],'
            ' filename=%r)\n'
            'print(b.get_device_info()[0]); print(b.get_battery_level()); b.close()\n')
            % (TOOLS_PYTHON, node)], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        name, mv = r.stdout.split()
        assert name == 'BT-NXT' and int(mv) == srv.fw.battery_mv, r.stdout
        # disconnect: the node goes, and so do the RFCOMM tty and the link.
        assert ok(ctl('-d', node, 'disconnect')).strip() == rfcomm
        assert not os.path.exists(node)
        assert wait_for(lambda: not os.path.exists(rfcomm), 5), rfcomm + ' outlived the link'
        assert wait_for(lambda: srv.brick.gone.is_set(), 5), 'the link is still up'
    finally:
        srv.close()


def test_link_broken_mid_transaction(radio):
    srv, node, _ = connect(radio, hostile='noreply')
    fd = os.open(node, os.O_RDWR)
    try:
        rfcomm = tty_of(node)
        nxt.set_timeout(fd, 20000)
        result = {}

        def call():
            result['err'], _ = nxt.transact(fd, b'\x00\x0b')

        th = threading.Thread(target=call)
        th.start()
        assert wait_for(lambda: any(e[0] == 'cmd' for e in srv.brick.log), 5)
        srv.brick.hangup()
        th.join(15)
        assert not th.is_alive(), 'the caller is still blocked after the link broke'
        assert result['err'] == errno.ENODEV, result
        assert wait_for(lambda: not os.path.exists(node), 5), node
        assert wait_for(lambda: not os.path.exists(rfcomm), 5), rfcomm
        err, _ = nxt.transact(fd, b'\x00\x0b')
        assert err == errno.ENODEV
        assert wait_for(lambda: not os.path.exists(os.path.join(RUNDIR, os.path.basename(node))),
                        5), 'the daemon outlived the link'
    finally:
        os.close(fd)
        srv.close()
