"""Helpers for the EV3 guest tests: a sensor on a null-modem line."""
import fcntl
import glob
import os
import select
import struct
import subprocess
import sys
import termios
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', 'emulator'))
import ev3_sensor  # noqa: E402

N_LEGOEV3 = 29
CLASS = '/sys/class/lego-sensor'
IIO = '/sys/bus/iio/devices'


def load_nullmodem():
    if not os.path.isdir('/sys/module/lego_nullmodem'):
        ko = os.path.join(os.environ['LEGO_BUILD'], 'tests/kmod/lego_nullmodem.ko')
        subprocess.run(['insmod', ko], check=True)


def read_attr(path, name):
    with open(os.path.join(path, name)) as f:
        return f.read().strip()


def write_attr(path, name, value):
    with open(os.path.join(path, name), 'w') as f:
        f.write(value)


def plug(line, kind, **kw):
    """Plug an emulated sensor (ev3_sensor's kind) into line, and wait for
    its lego-sensor device: (emulator, sensorN directory)."""
    emu = line.plug(kind, **kw)
    path = find_sensor(line.address, timeout=15)
    assert path, 'no lego-sensor device on %s for %s (emulator events: %s)' % (
        line.address, kind, emu.events)
    return emu, path


def find_sensor(address, timeout=10.0, gone_from=None):
    """The sensorN directory whose address is `address`, waiting for it."""
    sd = open_sensor(address, timeout, gone_from)
    if sd is None:
        return None
    sd.close()
    return sd.path


class SensorDir:
    """One sensor's sysfs directory, held open.

    A sensorN name is given to the next sensor as soon as its holder goes, so
    reads by path can mix two sensors when one is unplugged and another
    plugged meanwhile. Reads through the held directory see only this
    sensor, and fail with ENOENT once it has gone.
    """

    def __init__(self, path):
        self.path = path
        self.fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)

    def read(self, name, binary=False):
        fd = os.open(name, os.O_RDONLY, dir_fd=self.fd)
        with open(fd, 'rb' if binary else 'r') as f:
            return f.read() if binary else f.read().strip()

    def write(self, name, value):
        fd = os.open(name, os.O_WRONLY, dir_fd=self.fd)
        with open(fd, 'w') as f:
            f.write(value)

    def has(self, name):
        """True while the attribute `name` exists in this sensor's directory."""
        try:
            os.stat(name, dir_fd=self.fd)
            return True
        except FileNotFoundError:
            return False

    def gone(self):
        """True once the directory is removed (its attributes with it)."""
        return not self.has('address')

    def wait_gone(self, timeout):
        """Wait until the directory is removed."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.gone():
                return True
            time.sleep(0.02)
        return False

    def close(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _attrs_complete(sd, deadline):
    """Wait until the sensor's attributes are all there. The directory
    appears before device_add() creates the class's attribute group, one
    file at a time, binary files last: a reader that finds the directory
    early can see "address" and not yet "fw_version" (seen on the KCSAN
    kernel). "direct" is the group's last file."""
    while not sd.has('direct'):
        if time.monotonic() >= deadline or sd.gone():
            return False                # or gone already
        time.sleep(0.01)
    return True


def open_sensor(address, timeout=10.0, gone_from=None):
    """The held directory (SensorDir) of the sensor at `address`, other
    than the directory `gone_from`, waiting for it; None if none turns up."""
    deadline = time.monotonic() + timeout
    while True:
        for d in glob.glob(CLASS + '/sensor*'):
            if d == gone_from:
                continue
            try:
                sd = SensorDir(d)
            except OSError:
                continue
            try:
                if sd.read('address') == address and _attrs_complete(sd, deadline):
                    return sd
            except OSError:
                pass
            sd.close()
        if time.monotonic() >= deadline:
            return None
        time.sleep(0.05)


def wait_gone(path, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not os.path.exists(path):
            return True
        time.sleep(0.02)
    return False


def wait_attr_int(path, attr, want, timeout=3.0):
    """Poll an integer attribute until it reads `want`; return the last read."""
    deadline = time.monotonic() + timeout
    got = None
    while time.monotonic() < deadline:
        try:
            got = int(read_attr(path, attr))
        except OSError:
            got = None
        if got == want:
            return got
        time.sleep(0.02)
    return got


def wait_handshakes(emu, n, timeout=10.0):
    """The host registers the sensor as soon as it has sent its ACK; the
    emulator counts the handshake once its thread has read that ACK."""
    deadline = time.monotonic() + timeout
    while emu.handshakes < n and time.monotonic() < deadline:
        time.sleep(0.02)
    return emu.handshakes


def wait_value(path, index, want, timeout=3.0):
    return wait_attr_int(path, 'value%d' % index, want, timeout)


def iio_device(name, timeout=5.0):
    """The IIO device directory named `name`, waiting for it (None: none)."""
    deadline = time.monotonic() + timeout
    while True:
        for d in glob.glob(IIO + '/iio:device*'):
            try:
                if read_attr(d, 'name') == name:
                    return d
            except OSError:
                pass
        if time.monotonic() >= deadline:
            return None
        time.sleep(0.05)


def registered(address):
    """How many sensors the discipline on tty `address` (ttyNM0, pts3) has
    published since it was attached (its debugfs counter), None without
    debugfs or before the attach."""
    try:
        with open('/sys/kernel/debug/lego_ev3_uart/%s/counters' % address) as f:
            return int(dict(line.split() for line in f)['registered'])
    except (OSError, KeyError, ValueError):
        return None


def wait_registered(address, n=1, timeout=30.0):
    """Wait until the discipline on `address` has published `n` sensors.
    The class device appears first; the driver publishes the sensor (its
    values reach sysfs, IIO pushes begin, the trace says "registered") once
    the IIO device is registered too, and iio_device_register() takes about
    10 ms a channel on the 7.3 debug test kernel under TCG (measured: 0.6 to
    0.8 s for 64 channels, 1.2 to 2.0 s for 128, 2.2 to 3.1 s for 256, with
    other VMs on the host; 5 to 6 s reported under more load). True once
    published, False on timeout, None without debugfs."""
    deadline = time.monotonic() + timeout
    while True:
        got = registered(address)
        if got is None or got >= n:
            return None if got is None else True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)


def drain(fd, seconds):
    """Read what a non-blocking IIO buffer fd holds, for at most `seconds`."""
    data = b''
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.05)
        if not r:
            break
        try:
            chunk = os.read(fd, 1 << 16)
        except BlockingIOError:
            break
        if not chunk:
            break
        data += chunk
    return data


class Line:
    """ttyNM<2n> with the discipline attached, ttyNM<2n+1> played by an emulator."""

    # The line itself garbles bytes sent at the wrong speed.
    watch_speed = False

    def __init__(self, pair=0):
        load_nullmodem()
        self.host = '/dev/ttyNM%d' % (2 * pair)
        self.far = '/dev/ttyNM%d' % (2 * pair + 1)
        self.address = os.path.basename(self.host)
        self.fd = None
        self.emu = None
        self.detached_ns = []       # when detach() was called (wire.check())

    def attach(self):
        self.fd = os.open(self.host, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        fcntl.ioctl(self.fd, termios.TIOCSETD, struct.pack('i', N_LEGOEV3))
        self.wait_probe()

    def wait_probe(self, timeout=2.0):
        """Wait until the fast sync probe the discipline makes when it is
        attached is over and the tty back at 2400 baud (about 35 ms), as
        tests that read or lock the tty's speed expect."""
        path = '/sys/kernel/debug/lego_ev3_uart/%s/counters' % os.path.basename(self.host)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                with open(path) as f:
                    c = dict(line.split() for line in f)
            except OSError:
                return                  # no debugfs: nothing to wait for
            if int(c.get('tx_speed', 1)) + int(c.get('tx_errors', 0)) >= 1 and \
                    c.get('state') != '4' and termios.tcgetattr(self.fd)[4] == termios.B2400:
                return
            time.sleep(0.01)

    def detach(self):
        if self.fd is not None:
            self.detached_ns.append(time.monotonic_ns())
            os.close(self.fd)
            self.fd = None

    def plug(self, kind, **kw):
        if self.watch_speed:
            kw.setdefault('host_tty', self.host)
        self.emu = ev3_sensor.EmulatedSensor(self.far, kind, **kw)
        self.emu.start()
        return self.emu

    def close(self):
        if self.emu:
            self.emu.stop()
        self.detach()


def serial_pair():
    """The two 16550A ports tests/vm-run wires to each other, e.g.
    ['ttyS1', 'ttyS2'], or [] if the VM was started without them."""
    return os.environ.get('LEGO_SERIAL_PAIR', '').split()


class SerialLine(Line):
    """Two 8250 UARTs joined by a socket in QEMU: the discipline on the first,
    an emulator on the second. A socket carries no baud rate, so the emulator
    garbles what it sends while the host end's speed differs from its own."""

    watch_speed = True

    def __init__(self, host, far):
        self.host = '/dev/' + host
        self.far = '/dev/' + far
        self.address = host
        self.fd = None
        self.emu = None
        self.detached_ns = []

    def speed(self):
        """The host end's speed in baud (tcgetattr with the discipline attached)."""
        return ev3_sensor.SPEED_OF[termios.tcgetattr(self.fd)[5]]


# The null modem's transmit-side knob and read-outs (tests/kmod/lego_nullmodem.c).
NM_PARAMS = '/sys/module/lego_nullmodem/parameters'
NM_DEBUG = '/sys/kernel/debug/lego_nullmodem'


def stall(port, on):
    """Hold (on=True) or release ttyNM<port>'s transmitter (tx_stall): while
    held it takes nothing from its writer and sends nothing; the release
    sends what it holds and wakes the writer (tty_wakeup())."""
    path = os.path.join(NM_PARAMS, 'tx_stall')
    with open(path) as f:
        mask = int(f.read())
    mask = mask | (1 << port) if on else mask & ~(1 << port)
    with open(path, 'w') as f:
        f.write(str(mask))


def nm_state(port):
    """ttyNM<port>'s state: {'stall', 'held', 'write_wakeup'} (ints; write_wakeup
    is the tty's TTY_DO_WRITE_WAKEUP, -1 while the tty is not open)."""
    with open('%s/ttyNM%d/state' % (NM_DEBUG, port)) as f:
        return {k: int(v) for k, v in (line.split() for line in f)}


def clear_wire(port):
    with open('%s/ttyNM%d/wire' % (NM_DEBUG, port), 'w') as f:
        f.write('0')


def wire(port, since_ns=0, kind='o'):
    """The bytes ttyNM<port> put on the wire (kind 'o') or took from its
    writer ('w') since the log was emptied and at or after since_ns
    (time.monotonic_ns(), the kernel's ktime_get_ns()): [(ns, baud, byte)]."""
    out = []
    with open('%s/ttyNM%d/wire' % (NM_DEBUG, port)) as f:
        for line in f:
            ns, k, baud, byte = line.split()
            if k == kind and int(ns) >= since_ns:
                out.append((int(ns), int(baud), int(byte, 16)))
    return out


def counters(address):
    """The discipline's debugfs counters on tty `address` ({} before the attach)."""
    try:
        with open('/sys/kernel/debug/lego_ev3_uart/%s/counters' % address) as f:
            return {k: int(v) for k, v in (line.split() for line in f)}
    except OSError:
        return {}
