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
import socket
import subprocess
import sys
import threading
import time

import pytest

import nxtdev as nxt
from conftest import loaded, module_path, wait_for

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))
import nxt_brick  # noqa: E402
import nxt_serial_brick as sb  # noqa: E402

TOOLS_PYTHON = os.path.join(nxt.TOP, 'tools', 'python')
NXTCTL = os.path.join(os.environ.get('LEGO_BUILD', ''), 'tools', 'nxtctl')
RUNDIR = '/tmp/nxtctl-run'
CHANNEL = 1


def ctl(*args, text=True, timeout=120):
    env = dict(os.environ, NXTCTL_RUNDIR=RUNDIR)
    return subprocess.run([NXTCTL] + [str(a) for a in args], capture_output=True,
                          text=text, timeout=timeout, env=env)


def ok(p):
    assert p.returncode == 0, (p.args, p.returncode, p.stdout, p.stderr)
    return p.stdout


def address(hci):
    out = subprocess.run(['hciconfig', hci], capture_output=True, text=True).stdout
    m = re.search(r'BD Address: ([0-9A-F:]{17})', out)
    return m.group(1) if m else None


@pytest.fixture(scope='module')
def radio():
    """Two virtual controllers, up: (the brick's address, the host's)."""
    if not loaded('lego_nxt_serial'):
        subprocess.run(['insmod', module_path('lego_nxt_serial')], check=True)
    p = subprocess.Popen(['btvirt', '-l2'], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: all(os.path.isdir('/sys/class/bluetooth/' + h)
                                    for h in ('hci0', 'hci1')), 15), 'btvirt made no controllers'
        for args in (['hci0', 'up'], ['hci0', 'piscan'], ['hci1', 'up']):
            subprocess.run(['hciconfig'] + args, check=True)
        addrs = address('hci0'), address('hci1')
        assert all(addrs), addrs
        yield addrs
    finally:
        p.terminate()
        p.wait(10)


class Server:
    """The emulated brick as an RFCOMM server on the brick's controller."""

    def __init__(self, addr, hostile=None):
        self.fw = nxt_brick.Firmware(name='BT-NXT')
        self.hostile = hostile
        self.brick = None
        self.sock = socket.socket(socket.AF_BLUETOOTH, socket.SOCK_STREAM,
                                  socket.BTPROTO_RFCOMM)
        self.sock.bind((addr, CHANNEL))
        self.sock.listen(1)
        self.accepted = threading.Event()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        try:
            conn, _ = self.sock.accept()
        except OSError:
            return
        self.brick = sb.SerialBrick(os.dup(conn.fileno()), self.fw,
                                    hostile=self.hostile).start()
        conn.close()
        self.accepted.set()

    def close(self):
        if self.brick:
            self.brick.stop()
        self.sock.close()


def connect(radio, hostile=None):
    srv = Server(radio[0], hostile)
    t = time.monotonic()
    p = ctl('connect', radio[0], timeout=60)
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
        pids = []
        for k in range(3):
            pid = os.fork()
            if pid == 0:
                code = 101
                try:
                    rng = random.Random(k)
                    fd = os.open(node, os.O_RDWR)
                    bad = 0
                    for _ in range(10):
                        port = rng.randrange(4)
                        tg = rng.choice([b'\x00\x0b', b'\x00\x07' + bytes([port])])
                        err, reply = nxt.transact(fd, tg)
                        if err or reply[1] != tg[1] or (tg[1] == 7 and reply[3] != port):
                            bad += 1
                    code = bad
                finally:
                    os._exit(code)
            pids.append(pid)
        codes = [os.waitstatus_to_exitcode(os.waitpid(p, 0)[1]) for p in pids]
        assert codes == [0, 0, 0], codes
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
