"""A sensor's IIO device served on the network by libiio's own daemon, iiod
(Debian's package, 0.24), and read over TCP with libiio's stock tools, as a
laptop reads a robot's sensors (ev3-uart.rst, "Over the network"): the
device and its channels (iio_info), a channel's raw value and scale and a
mode written over the network (iio_attr), a buffered capture with
timestamps (iio_readdev), each checked against what the emulated sensor
was told to send. And tools/udev/90-lego-ev3-iiod.rules under the real
systemd-udevd: it restarts iiod as a sensor comes and goes."""
import contextlib
import fcntl
import os
import re
import shutil
import socket
import struct
import subprocess
import time

import pytest

from conftest import pid_alive, udevd_with_rules
from ev3 import find_sensor, iio_device, read_attr, wait_attr_int

PORT = 30431                    # iiod's port (IIOD_PORT), which ip: URIs use
URI = 'ip:127.0.0.1'
DEVICE = 'lego-ev3-us'
# Under TCG a libiio tool takes a second or two to start, iiod too.
TOOL_TIMEOUT = 60
START_TIMEOUT = 60

SIOCGIFFLAGS = 0x8913
SIOCSIFFLAGS = 0x8914
IFF_UP = 0x1


def _lo_flags(sock, flags=None):
    """The loopback interface's flags, or set them (struct ifreq: the name,
    then a short)."""
    if flags is None:
        req = fcntl.ioctl(sock, SIOCGIFFLAGS, struct.pack('16sH14x', b'lo', 0))
        return struct.unpack('16sH14x', req)[1]
    fcntl.ioctl(sock, SIOCSIFFLAGS, struct.pack('16sH14x', b'lo', flags))
    return flags


@contextlib.contextmanager
def loopback():
    """The loopback interface up (the VM's init leaves it down), and as it
    was afterwards. Bringing it up gives it 127.0.0.1 (and ::1)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        old = _lo_flags(s)
        if not old & IFF_UP:
            _lo_flags(s, old | IFF_UP)
        try:
            yield
        finally:
            if not old & IFF_UP:
                _lo_flags(s, old)


def _log(path):
    try:
        with open(path, errors='replace') as f:
            return f.read()[-3000:]
    except OSError:
        return ''


def _listening(port):
    try:
        with socket.create_connection(('127.0.0.1', port), timeout=2):
            return True
    except OSError:
        return False


def _stop(proc):
    """End iiod: SIGTERM, which it handles by stopping its threads and
    waiting for them; but the thread that looks for an avahi-daemon (none
    runs in the VM) tries for about a minute, sleeping 1 to 10 s between
    tries, and nothing wakes it (iiod/dns-sd.c): SIGKILL after 5 s. Returns
    how it ended (for the log)."""
    if proc.poll() is not None:
        return 'had exited (%d)' % proc.returncode
    proc.terminate()
    try:
        proc.wait(5)
        return 'SIGTERM'
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(20)
        return 'SIGKILL 5 s after SIGTERM'


@contextlib.contextmanager
def iiod(tmp_path):
    """iiod serving this machine's IIO devices on 127.0.0.1:PORT, yielded
    once it accepts connections; stopped afterwards whatever happened.

    iiod 0.24 stays in the foreground (no option makes it a daemon; the
    init script backgrounds it) and needs no writable directory; it listens
    on every address (no option to choose one) and announces itself with
    avahi when an avahi-daemon runs (none does here: it tries for a minute,
    then gives up). Options it has for USB (-F) and serial (-s) are not
    given, so it serves on TCP only. It lists the IIO devices once, when it
    starts (iiod/iiod.c: one context for its lifetime): the sensor must be
    there before."""
    exe = shutil.which('iiod') or ('/usr/sbin/iiod' if os.access('/usr/sbin/iiod', os.X_OK)
                                   else None)
    if not exe:
        pytest.fail('iiod is not installed (Debian package iiod: tests/install-deps.sh)')
    assert not _listening(PORT), 'something already listens on port %d' % PORT
    log = str(tmp_path / 'iiod.log')
    with open(log, 'w') as out:
        proc = subprocess.Popen([exe], stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + START_TIMEOUT
        while not _listening(PORT):
            if proc.poll() is not None:
                pytest.fail('iiod exited with %d before it listened on port %d:\n%s'
                            % (proc.returncode, PORT, _log(log)))
            if time.monotonic() > deadline:
                pytest.fail('iiod (pid %d) did not listen on port %d within %d s:\n%s'
                            % (proc.pid, PORT, START_TIMEOUT, _log(log)))
            time.sleep(0.2)
        yield proc
    finally:
        how = _stop(proc)
        print('iiod stopped: %s; its log:\n%s' % (how, _log(log)))
    assert not pid_alive(proc.pid), 'iiod (pid %d) still runs' % proc.pid
    assert not _listening(PORT), 'port %d still open after iiod stopped' % PORT


def listeners(port):
    """The addresses that listen on TCP `port` ({'0.0.0.0', '::'} for
    every address), from /proc/net/tcp and tcp6."""
    out = set()
    for name, wild in (('tcp', '00000000'), ('tcp6', '0' * 32)):
        try:
            with open('/proc/net/' + name) as f:
                rows = [line.split() for line in f][1:]
        except FileNotFoundError:
            continue
        for row in rows:
            addr, p = row[1].split(':')
            if int(p, 16) == port and row[3] == '0A':           # TCP_LISTEN
                out.add(('0.0.0.0' if name == 'tcp' else '::') if addr == wild
                        else '%s:%s' % (name, addr))
    return out


def tool(*args, binary=False):
    """Run a libiio tool on URI; its stdout (bytes if binary)."""
    cmd = [args[0], '-u', URI] + list(args[1:])
    r = subprocess.run(cmd, capture_output=True, text=not binary, timeout=TOOL_TIMEOUT)
    err = r.stderr if not binary else r.stderr.decode(errors='replace')
    assert r.returncode == 0, '%s: exit %d\n%s' % (' '.join(cmd), r.returncode, err[-2000:])
    return r.stdout


def net_attr(*args):
    """iio_attr over the network, given the device, channel and attribute:
    the attribute's value (after a write, what it reads back). It reports a
    failed read or write as "ERROR: ..." on stdout."""
    out = tool('iio_attr', *args).strip()
    assert 'ERROR' not in out, 'iio_attr %s: %s' % (' '.join(args), out)
    return out


def wait_net_raw(channel, want, timeout=20.0):
    """Read a channel's raw value over the network until it is `want`; the
    last value read."""
    deadline = time.monotonic() + timeout
    while True:
        got = int(net_attr('-c', DEVICE, channel, 'raw'))
        if got == want or time.monotonic() > deadline:
            return got
        time.sleep(0.2)


def device_section(info, name):
    """iio_info's lines of the device named `name`: from its line
    ("\\tiio:deviceN: name ...") to the next device's."""
    lines = info.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r'\t(iio:device\d+): (\S+)', line)
        if m and m.group(2) == name:
            end = next((j for j in range(i + 1, len(lines))
                        if re.match(r'\t\S', lines[j])), len(lines))
            return m.group(1), lines[i:end]
    return None, []


def scan_formats(section):
    """{channel id: (index, format)} of the scan elements iio_info lists,
    from lines "\\t\\t\\tdistance0: US-DIST-CM value0 (input, index: 0,
    format: le:S32/32>>0)"."""
    out = {}
    for line in section:
        m = re.match(r'\t\t\t(\w+): .*\((?:input|output), index: (\d+), format: (\S+)\)$', line)
        if m:
            out[m.group(1)] = (int(m.group(2)), m.group(3))
    return out


def channel_attrs(section, channel):
    """{attribute: value} of a channel in iio_info's lines of its device
    ("\t\t\t\tattr  2: raw value: 263"; a failed read: "raw ERROR: ...")."""
    attrs, inside = {}, False
    for line in section:
        m = re.match(r'\t\t\t(\w+): ', line)
        if m:
            inside = m.group(1) == channel
        elif line.startswith('\t\t\t\t') and inside:
            m = re.match(r'\t\t\t\tattr +\d+: (\S+) (?:value: )?(.*)$', line)
            if m:
                attrs[m.group(1)] = m.group(2)
        elif not line.startswith('\t\t\t'):
            inside = False
    return attrs


def parse_format(fmt):
    """A scan element's type ("le:s16/32>>0", iio_info's form with a
    capital S or U when fully defined) as (endianness '<' or '>', signed,
    bits, storage bits, shift)."""
    m = re.fullmatch(r'([bl])e:([sSuU])(\d+)/(\d+)>>(\d+)', fmt)
    assert m, 'unexpected scan element type %r' % fmt
    return ('>' if m.group(1) == 'b' else '<', m.group(2) in 'sS', int(m.group(3)),
            int(m.group(4)), int(m.group(5)))


def layout(formats):
    """The byte offset of each channel in a sample and the sample's size,
    for the channels in scan index order: each at a multiple of its own
    storage size, the sample a multiple of the largest (the kernel's and
    libiio's rule)."""
    offsets, off, align = {}, 0, 1
    for name, fmt in formats:
        size = parse_format(fmt)[3] // 8
        off = (off + size - 1) // size * size
        offsets[name] = off
        off += size
        align = max(align, size)
    return offsets, (off + align - 1) // align * align


def decode(data, formats):
    """[{channel: value}] of each whole sample in data."""
    offsets, size = layout(formats)
    samples = []
    for base in range(0, len(data) - size + 1, size):
        s = {}
        for name, fmt in formats:
            endian, signed, bits, storage, shift = parse_format(fmt)
            raw = int.from_bytes(data[base + offsets[name]:base + offsets[name] + storage // 8],
                                 'big' if endian == '>' else 'little')
            v = (raw >> shift) & ((1 << bits) - 1)
            if signed and v >> (bits - 1):
                v -= 1 << bits
            s[name] = v
        samples.append(s)
    return samples


def capture(channels, formats, n):
    """n samples of `channels` (with the timestamp) through iio_readdev
    over the network, decoded; and the monotonic clock before and after."""
    before = time.monotonic_ns()
    data = tool('iio_readdev', '-b', '16', '-s', str(n), DEVICE, *channels, binary=True)
    after = time.monotonic_ns()
    fmts = sorted(((c, formats[c][1]) for c in channels), key=lambda cf: formats[cf[0]][0])
    _, size = layout(fmts)
    assert len(data) == n * size, 'iio_readdev gave %d bytes, not %d samples of %d' % (
        len(data), n, size)
    return decode(data, fmts), data, before, after


@pytest.fixture
def served(line, tmp_path):
    """The emulated ultrasonic sensor on the line, at 26.3 cm, and iiod
    serving its IIO device on the loopback interface."""
    emu = line.plug('us')
    emu.set_values(0, [263])
    assert find_sensor(line.address, timeout=15), 'no sensor (emulator: %s)' % emu.events
    dev = iio_device(DEVICE)
    assert dev, 'no IIO device %s' % DEVICE
    assert wait_attr_int(dev, 'in_distance0_raw', 263) == 263
    with loopback(), iiod(tmp_path) as proc:
        yield emu, dev, proc


def test_iio_info_lists_the_sensor(served):
    emu, dev, proc = served
    info = tool('iio_info')
    assert 'IIO context created with network backend' in info, info[:2000]
    devid, section = device_section(info, DEVICE)
    assert devid == os.path.basename(dev), 'iio_info over the network:\n%s' % info[-3000:]
    text = '\n'.join(section)
    assert '(buffer capable)' in section[0]
    # The label is the sensor's address, as in sysfs.
    assert '(label: %s)' % read_attr(dev, 'label') in section[0]
    formats = scan_formats(section)
    # Every channel in sysfs is listed, with its scan element type.
    sysfs = sorted(f[len('in_'):-len('_en')] for f in os.listdir(os.path.join(dev, 'scan_elements'))
                   if f.endswith('_en'))
    assert sorted(formats) == sysfs, text
    assert 'distance0' in formats and 'timestamp' in formats
    for ch in sysfs:
        kernel = read_attr(dev, 'scan_elements/in_%s_type' % ch)
        assert formats[ch][1].lower() == kernel.lower(), (ch, formats[ch], kernel)
        assert formats[ch][0] == int(read_attr(dev, 'scan_elements/in_%s_index' % ch))
    # The channels' attributes: label (the mode and value), raw, scale.
    d0 = channel_attrs(section, 'distance0')
    assert d0['label'] == 'US-DIST-CM value0', d0
    assert d0['raw'] == '263' and d0['scale'] == read_attr(dev, 'in_distance0_scale'), d0
    # Another mode's channel is busy (EBUSY), over the network as in sysfs.
    d1 = channel_attrs(section, 'distance1')
    assert d1['label'] == 'US-DIST-IN value0' and 'busy' in d1['raw'].lower(), d1
    assert re.search(r'attr +\d+: mode value: US-DIST-CM\n', text + '\n'), text
    # On every address (ev3-uart.rst): IPv6's, which takes IPv4 too, when
    # the kernel has IPv6.
    assert listeners(PORT) == ({'::'} if os.path.exists('/proc/net/tcp6') else {'0.0.0.0'}), \
        listeners(PORT)
    assert proc.poll() is None, 'iiod ended'


def test_iio_attr_reads_and_writes_over_the_network(served):
    emu, dev, proc = served
    assert int(net_attr('-c', DEVICE, 'distance0', 'raw')) == 263
    # Two sensors of a kind share a name: the label (the address) tells them apart.
    assert int(net_attr('-c', read_attr(dev, 'label'), 'distance0', 'raw')) == 263
    scale = net_attr('-c', DEVICE, 'distance0', 'scale')
    assert scale == read_attr(dev, 'in_distance0_scale')
    assert float(scale) == pytest.approx(0.001)     # 263 * 0.001 m: 26.3 cm
    # A new value reaches the network: the value read is the sensor's.
    emu.set_values(0, [1742])
    assert wait_net_raw('distance0', 1742) == 1742
    # Anyone who reaches iiod may change the mode (ev3-uart.rst: a firewall).
    assert net_attr('-d', DEVICE, 'mode', 'US-DIST-IN') == 'US-DIST-IN'
    assert read_attr(dev, 'mode') == 'US-DIST-IN'
    emu.set_values(1, [104])
    assert wait_net_raw('distance1', 104) == 104
    assert float(net_attr('-c', DEVICE, 'distance1', 'scale')) == pytest.approx(0.00254)
    r = subprocess.run(['iio_attr', '-u', URI, '-c', DEVICE, 'distance0', 'raw'],
                       capture_output=True, text=True, timeout=TOOL_TIMEOUT)
    # The mode's other channels are busy, over the network as in sysfs.
    assert 'busy' in (r.stdout + r.stderr).lower(), r
    net_attr('-d', DEVICE, 'mode', 'US-DIST-CM')
    assert wait_attr_int(dev, 'in_distance0_raw', 1742) == 1742
    assert proc.poll() is None, 'iiod ended'


def test_iio_readdev_captures_values_and_timestamps(served):
    emu, dev, proc = served
    _, section = device_section(tool('iio_info'), DEVICE)
    formats = scan_formats(section)
    # Monotonic timestamps, set over the network, to compare with this clock.
    assert net_attr('-d', DEVICE, 'current_timestamp_clock', 'monotonic') == 'monotonic'
    assert read_attr(dev, 'current_timestamp_clock') == 'monotonic'
    for value, n in ((263, 48), (-2, 32), (2550, 32)):
        emu.set_values(0, [value])
        assert wait_attr_int(dev, 'in_distance0_raw', value) == value
        samples, data, before, after = capture(['distance0', 'timestamp'], formats, n)
        values = [s['distance0'] for s in samples]
        assert values == [value] * n, 'sent %d, captured %s' % (value, values)
        # As ev3-uart.rst decodes them: the value sign extended to 32 bits.
        assert [(s['distance0'], s['timestamp']) for s in samples] == \
            list(struct.iter_unpack('<i4xq', data))
        stamps = [s['timestamp'] for s in samples]
        bad = [i for i in range(1, n) if stamps[i] <= stamps[i - 1]]
        assert not bad, 'timestamps not increasing at %s: %s' % (bad, stamps)
        # Taken while iio_readdev ran; the sensor sends every 22 ms.
        assert before <= stamps[0] and stamps[-1] <= after, (before, stamps, after)
        gaps = sorted(stamps[i] - stamps[i - 1] for i in range(1, n))
        assert 5e6 <= gaps[len(gaps) // 2] <= 200e6, 'median gap %d ns' % gaps[len(gaps) // 2]
    assert read_attr(dev, 'buffer/enable') == '0'
    assert proc.poll() is None, 'iiod ended'


def test_iiod_serves_only_the_devices_it_found_when_it_started(line, tmp_path):
    """Why 90-lego-ev3-iiod.rules restarts iiod: a sensor that connects
    while iiod runs is not served until iiod is started again (libiio 0.24;
    a later iiod that finds new devices by itself makes this fail, and the
    rule can go)."""
    with loopback():
        with iiod(tmp_path):
            emu = line.plug('us')
            emu.set_values(0, [263])
            assert find_sensor(line.address, timeout=15), 'no sensor (emulator: %s)' % emu.events
            dev = iio_device(DEVICE)
            assert dev and wait_attr_int(dev, 'in_distance0_raw', 263) == 263
            devid, _ = device_section(tool('iio_info'), DEVICE)
            assert devid is None, 'iiod found the new sensor (%s) by itself' % devid
        with iiod(tmp_path):
            devid, _ = device_section(tool('iio_info'), DEVICE)
            assert devid == os.path.basename(dev)


FAKE_SYSTEMCTL = """#!/bin/sh
echo "$*" >> %s
exit 0
"""


def test_udev_rule_restarts_iiod_as_a_sensor_comes_and_goes(line, tmp_path):
    """90-lego-ev3-iiod.rules in systemd-udevd: the add and the remove of
    the sensor's IIO device (and of nothing else the sensor brings) run its
    command, which restarts iiod.service when it is enabled. The VM runs no
    systemd: /bin/systemctl is replaced in a copy of the rule by a script
    that logs its arguments and says yes."""
    top = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
    calls = tmp_path / 'calls'
    fake = tmp_path / 'systemctl'
    fake.write_text(FAKE_SYSTEMCTL % calls)
    os.chmod(fake, 0o755)
    with open(os.path.join(top, 'tools/udev/90-lego-ev3-iiod.rules')) as f:
        text = f.read()
    assert text.count('/bin/systemctl ') == 2
    rules = tmp_path / '90-lego-ev3-iiod.rules'
    rules.write_text(text.replace('/bin/systemctl ', '%s ' % fake))

    def logged():
        try:
            return calls.read_text().splitlines()
        except FileNotFoundError:
            return []

    restart = ['-q is-enabled iiod.service', '--no-block restart iiod.service']
    with udevd_with_rules(str(tmp_path / 'udev'), [str(rules)]):
        emu = line.plug('us')
        assert find_sensor(line.address, timeout=15), 'no sensor (emulator: %s)' % emu.events
        dev = iio_device(DEVICE)
        assert dev
        deadline = time.monotonic() + 30
        while len(logged()) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert logged() == restart, 'on the IIO device\'s add: %s' % logged()
        line.detach()
        deadline = time.monotonic() + 30
        while len(logged()) < 4 and time.monotonic() < deadline:
            time.sleep(0.1)
        # (A moment more: nothing else the sensor's removal brings runs it.)
        time.sleep(1)
        assert logged() == restart * 2, 'on the IIO device\'s remove: %s' % logged()
