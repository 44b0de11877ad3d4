"""lego_nxt_serial: a brick on a serial line (Bluetooth's framing) through
the same /dev/nxtN as on USB, against the emulated brick's Bluetooth side
(tests/emulator/nxt_serial_brick.py) on a pty, attached with
`nxtctl attach` as a user attaches an RFCOMM tty.

What is checked: the node and its sysfs and debugfs; nxtctl info, upload
and download of a 3001-byte file; raw telegrams from several processes at
once, each getting its own replies; the 30 ms the brick wants between a
reply and the next command (the emulated brick drops a command that comes
sooner); length prefixes that lie; a link lost in the middle of a
transaction (ENODEV for the caller, the node gone); nxtctl disconnect.
"""
import errno
import os
import random
import signal
import subprocess
import sys
import threading
import time

import pytest

import nxtdev as nxt
from conftest import loaded, module_path, pid_alive, wait_for

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))
import nxt_brick  # noqa: E402
import nxt_serial_brick as sb  # noqa: E402

RUNDIR = nxt.NXTCTL_RUNDIR
CLASS = '/sys/class/lego-nxt'
GAP = 0.030


class Attached:
    """An emulated brick on a pty, attached with nxtctl attach."""

    def __init__(self, hostile=None, name='BT-NXT'):
        if not loaded('lego_nxt_serial'):
            subprocess.run(['insmod', module_path('lego_nxt_serial')], check=True)
        self.fw = nxt_brick.Firmware(name=name)
        master, self.tty = sb.open_pty()
        self.emu = sb.SerialBrick(master, self.fw, hostile=hostile).start()
        p = ctl('attach', self.tty)
        assert p.returncode == 0 and p.stderr == '', (p.returncode, p.stdout, p.stderr)
        self.node = p.stdout.strip()
        assert self.node.startswith('/dev/nxt'), p.stdout
        self.name = os.path.basename(self.node)
        self.pidfile = os.path.join(RUNDIR, self.name)

    def ctl(self, *args, **kw):
        return ctl('-d', self.node, *args, **kw)

    def close(self):
        if os.path.exists(self.pidfile):
            self.ctl('disconnect')
        self.emu.stop()
        assert wait_for(lambda: not os.path.exists(self.node), 5), self.node + ' outlived its link'


ctl = nxt.nxtctl
ok = nxt.nxtctl_ok


@pytest.fixture
def brick():
    b = Attached()
    yield b
    b.close()


def test_attach_gives_a_node_with_sysfs_and_debugfs(brick):
    assert os.path.exists(brick.node)
    assert os.path.isdir(os.path.join(CLASS, brick.name))
    pts = 'pts' + brick.tty.rsplit('/', 1)[1]
    assert os.path.isfile('/sys/kernel/debug/lego_nxt/%s/counters' % pts)
    with open(brick.pidfile) as f:
        pid, tty = f.read().split()
    assert tty == brick.tty and os.path.exists('/proc/%s' % pid)
    info = dict(line.split(': ', 1) for line in ok(brick.ctl('info')).splitlines())
    assert info['name'] == 'BT-NXT', info
    # The sysfs attributes fill from the replies that passed, as on USB.
    with open(os.path.join(CLASS, brick.name, 'brick_name')) as f:
        assert f.read().strip() == 'BT-NXT'


def test_upload_download_3001_bytes(brick, tmp_path):
    data = bytes(random.Random(3001).randrange(256) for _ in range(3001))
    src = tmp_path / 'src.bin'
    src.write_bytes(data)
    ok(brick.ctl('upload', src, 'bt.dat'))
    assert bytes(brick.fw.files['bt.dat'].data) == data
    dst = tmp_path / 'dst.bin'
    ok(brick.ctl('download', 'bt.dat', dst))
    assert dst.read_bytes() == data
    assert brick.fw.handles == {}, brick.fw.handles
    # The brick got every command: none came within its gap.
    assert brick.emu.dropped == []


def test_the_brick_gets_its_gap_after_each_reply(brick):
    fd = os.open(brick.node, os.O_RDWR)
    try:
        for _ in range(10):
            err, reply = nxt.transact(fd, b'\x00\x0b')
            assert err == 0 and reply[:3] == b'\x02\x0b\x00', (err, reply)
    finally:
        os.close(fd)
    log = brick.emu.log
    gaps = [b[1] - a[1] for a, b in zip(log, log[1:]) if a[0] == 'reply' and b[0] == 'cmd']
    assert len(gaps) >= 9, log
    # The emulator's reply left before the driver saw it: the driver's
    # 30 ms from its own receive make more than 30 ms here.
    assert min(gaps) >= GAP, gaps
    assert brick.emu.dropped == []


def test_raw_telegrams_from_several_processes(brick):
    """Four processes, 15 transactions each, every reply checked against
    what its own client asked (nxtdev.mixed_request())."""
    results = nxt.mixed_clients(brick.node, 4, 15)
    log = brick.emu.log
    gaps = [round(b[1] - a[1], 4) for a, b in zip(log, log[1:]) if a[0] == 'reply' and b[0] == 'cmd']
    assert results == [(i, 0) for i in range(4)], (results, brick.emu.dropped, min(gaps))
    assert sum(1 for e in brick.emu.log if e[0] == 'cmd') == 60
    assert brick.emu.dropped == []


def test_length_prefixes_that_lie_are_survived():
    b = Attached(hostile='lying')
    try:
        fd = os.open(b.node, os.O_RDWR)
        try:
            for _ in range(12):
                err, reply = nxt.transact(fd, b'\x00\x0b')
                assert err == 0 and reply[:3] == b'\x02\x0b\x00', (err, reply)
        finally:
            os.close(fd)
    finally:
        b.close()


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_random_streams_around_the_replies(seed):
    """Whole-driver fuzzing of the framing: random bytes, frames and lying
    lengths around each reply, replies cut or left out. Each transaction
    ends with its reply, or ETIMEDOUT or EPROTO; a reply given to a caller
    is one for its telegram; and the brick answers normally afterwards."""
    b = Attached(hostile='fuzz')
    b.emu.rng.seed(seed)
    fd = os.open(b.node, os.O_RDWR)
    try:
        nxt.set_timeout(fd, 400)
        ends = {}
        for i in range(40):
            port = i % 4
            tg = b'\x00\x0b' if i % 2 else b'\x00\x07' + bytes([port])
            err, reply = nxt.transact(fd, tg)
            ends[err] = ends.get(err, 0) + 1
            assert err in (0, errno.ETIMEDOUT, errno.EPROTO), (i, err)
            if not err:
                assert reply[:2] == b'\x02' + tg[1:2], (tg, reply)
                assert len(reply) == (5 if tg[1] == 0x0b else 16), (tg, reply)
                if tg[1] == 0x07:
                    assert reply[3] == port, (tg, reply)
        assert ends.get(0, 0) >= 10, ends
        b.emu.hostile = None
        time.sleep(0.5)
        nxt.set_timeout(fd, 2000)
        err, reply = nxt.transact(fd, b'\x00\x0b')
        assert err == 0 and reply[:3] == b'\x02\x0b\x00', (err, reply)
    finally:
        os.close(fd)
        b.close()


def test_link_lost_mid_transaction_is_an_unplug():
    b = Attached(hostile='noreply')
    fd = os.open(b.node, os.O_RDWR)
    nxt.set_timeout(fd, 20000)
    result = {}

    def call():
        t = time.monotonic()
        result['err'], _ = nxt.transact(fd, b'\x00\x0b')
        result['s'] = time.monotonic() - t

    th = threading.Thread(target=call)
    th.start()
    try:
        assert wait_for(lambda: any(e[0] == 'cmd' for e in b.emu.log), 5)
        time.sleep(0.2)
        b.emu.hangup()
        th.join(10)
        assert not th.is_alive(), 'the caller is still blocked after the link went'
        assert result['err'] == errno.ENODEV, result
        assert result['s'] < 5, result
        assert wait_for(lambda: not os.path.exists(b.node), 5)
        assert not os.path.isdir(os.path.join(CLASS, b.name))
        err, _ = nxt.transact(fd, b'\x00\x0b')
        assert err == errno.ENODEV
        # The daemon holding the tty saw the hangup and went.
        assert wait_for(lambda: not os.path.exists(b.pidfile), 5)
    finally:
        os.close(fd)
        b.emu.stop()


def test_a_full_tty_sends_the_rest_later_or_times_out():
    """A link that takes nothing (the brick deaf): telegrams that ask for
    no reply fill the tty; the one that finds it full waits for room and
    times out (the rest of its frame dropped); one that waits longer goes
    out once the brick reads again (the tty's write_wakeup)."""
    b = Attached()
    fd = os.open(b.node, os.O_RDWR)
    try:
        nxt.set_timeout(fd, 2000)
        # MessageWrite to inbox 0, its longest message, no reply: a
        # 65-byte frame.
        tg = b'\x80\x09\x00\x3b' + b'x' * 58 + b'\x00'
        assert len(tg) == 63
        b.emu.deaf.set()
        sent, err = 0, 0
        while sent < 20000:
            err, _ = nxt.transact(fd, tg)
            if err:
                break
            sent += 1
        assert err == errno.ETIMEDOUT, (sent, err)
        assert sent > 50, sent          # the pty took some first (16 KiB or so)
        # A signal stops a send the tty has not taken (the transport's kill).
        code = ('import os, signal, sys; sys.path.insert(0, %r); import nxtdev\n'
                'signal.signal(signal.SIGUSR1, lambda *a: sys.exit(7))\n'
                'fd = os.open(%r, os.O_RDWR); nxtdev.set_timeout(fd, 30000)\n'
                'print("go", flush=True); nxtdev.transact(fd, %r)\n'
                % (os.path.dirname(os.path.abspath(__file__)), b.node, tg))
        p = subprocess.Popen([sys.executable, '-c', code], stdout=subprocess.PIPE)
        try:
            assert p.stdout.readline() == b'go\n'
            time.sleep(0.5)
            p.send_signal(signal.SIGUSR1)
            assert p.wait(10) == 7, 'the signal did not end the send'
        finally:
            p.kill()
            p.wait()
        nxt.set_timeout(fd, 30000)
        result = {}
        th = threading.Thread(target=lambda: result.update(err=nxt.transact(fd, tg)[0]))
        th.start()
        time.sleep(0.5)
        assert th.is_alive(), 'sent into a full tty'
        b.emu.deaf.clear()
        th.join(30)
        assert not th.is_alive() and result['err'] == 0, result
    finally:
        b.emu.deaf.clear()
        os.close(fd)
        b.close()


def test_disconnect_lets_go():
    b = Attached()
    try:
        with open(b.pidfile) as f:
            pid = int(f.read().split()[0])
        out = ok(b.ctl('disconnect'))
        assert out.strip() == b.tty
        assert not os.path.exists(b.node)
        assert not os.path.exists(b.pidfile)
        assert wait_for(lambda: not pid_alive(pid), 5), 'the daemon is still there'
        # Nothing left to disconnect.
        p = b.ctl('disconnect')
        assert p.returncode == 3 and 'was not attached' in p.stderr, p.stderr
    finally:
        b.emu.stop()


def test_attach_refuses_what_is_not_a_tty(tmp_path):
    f = tmp_path / 'file'
    f.write_bytes(b'')
    p = ctl('attach', f)
    assert p.returncode == 3 and p.stderr.startswith('nxtctl: '), p.stderr
