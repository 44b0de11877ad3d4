"""Two virtual Bluetooth controllers in the test VM and the emulated NXT
brick as an RFCOMM server on one of them: what test_nxt_bluetooth.py and
`make demo` use to reach a brick over the kernel's own Bluetooth stack.

btvirt (bluez-test-tools) makes the controllers on the kernel's /dev/vhci
(CONFIG_BT_HCIVHCI); hciconfig (bluez) brings them up, the brick's one
page-scannable so that the other can connect to it.
"""
import os
import re
import socket
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'emulator'))
import nxt_brick  # noqa: E402
import nxt_serial_brick as sb  # noqa: E402

CHANNEL = 1     # the brick's serial port profile


def _wait(cond, timeout):
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def address(hci):
    out = subprocess.run(['hciconfig', hci], capture_output=True, text=True).stdout
    m = re.search(r'BD Address: ([0-9A-F:]{17})', out)
    return m.group(1) if m else None


class Radio:
    """btvirt's two controllers, up: `brick` is hci0's address (the brick's
    side), `host` hci1's. stop() removes them."""

    def __init__(self):
        self.proc = subprocess.Popen(['btvirt', '-l2'], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        try:
            if not _wait(lambda: all(os.path.isdir('/sys/class/bluetooth/' + h)
                                     for h in ('hci0', 'hci1')), 15):
                raise RuntimeError('btvirt made no controllers')
            for args in (['hci0', 'up'], ['hci0', 'piscan'], ['hci1', 'up']):
                subprocess.run(['hciconfig'] + args, check=True)
            self.brick, self.host = address('hci0'), address('hci1')
            if not (self.brick and self.host):
                raise RuntimeError('no controller addresses: %s %s' % (self.brick, self.host))
        except BaseException:
            self.stop()
            raise

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


class BrickServer:
    """The emulated brick on RFCOMM channel 1 of `addr`: `brick` is its
    SerialBrick once a host has connected (`accepted`); brick_args go to
    SerialBrick (latency, gap)."""

    def __init__(self, addr, fw=None, hostile=None, **brick_args):
        self.fw = fw or nxt_brick.Firmware(name='BT-NXT')
        self.hostile = hostile
        self.brick_args = brick_args
        self.brick = None
        self.accepted = threading.Event()
        self.sock = socket.socket(socket.AF_BLUETOOTH, socket.SOCK_STREAM,
                                  socket.BTPROTO_RFCOMM)
        self.sock.bind((addr, CHANNEL))
        self.sock.listen(1)
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        try:
            conn, _ = self.sock.accept()
        except OSError:
            return
        self.brick = sb.SerialBrick(os.dup(conn.fileno()), self.fw,
                                    hostile=self.hostile, **self.brick_args).start()
        conn.close()
        self.accepted.set()

    def close(self):
        if self.brick:
            self.brick.stop()
        self.sock.close()
