"""lego-sensors, the sensor listing tool, against emulated sensors on the
test null modem (as in test_ev3_sensors.py): its text and JSON compared with
what the emulator sent and sysfs shows, --mode, --watch, and its errors."""
import fcntl
import glob
import json
import os
import pty
import re
import select
import signal
import subprocess
import time

import pytest

from ev3 import (CLASS, IIO, Line, find_sensor, open_sensor, plug, read_attr, wait_gone,
                 wait_value, write_attr)
from ev3_sensor import S8, S16, Mode, SensorDef

TOP = os.path.join(os.path.dirname(__file__), '..', '..')
# _IOW(0xE3, 0x01, struct lego_ev3_port_label), 16 bytes.
LEGO_EV3_SET_PORT_LABEL = (1 << 30) | (16 << 16) | (0xE3 << 8) | 0x01


def tool():
    path = os.path.join(os.environ['LEGO_BUILD'], 'tools/lego-sensors')
    assert os.access(path, os.X_OK), path + ' not built (tests/build-modules.sh)'
    return path


def run(*args, timeout=30, env=None):
    return subprocess.run([tool(), *args], capture_output=True, text=True,
                          timeout=timeout, env=env)


def connect(line, kind):
    emu, path = plug(line, kind)
    if isinstance(kind, str):
        # LEGO's sensors have IIO channels: the IIO device comes just after
        # the lego-sensor device, and the tool's listing should show it.
        iio_of(path, timeout=10)
    return emu, path


@pytest.fixture
def line2(ev3_module):
    """A second line, ttyNM2 (the emulator on ttyNM3)."""
    ln = Line(1)
    ln.attach()
    yield ln
    ln.close()
    for d in glob.glob(CLASS + '/sensor*'):
        try:
            if read_attr(d, 'address').split(':')[0] == ln.address:
                assert wait_gone(d, 5), 'sensor left behind on ' + ln.address
        except OSError:
            pass


def settle(address, index, want, timeout=30):
    """Wait for value`index` of the sensor at `address` to read `want`,
    finding the sensor again if it reconnected meanwhile."""
    deadline = time.monotonic() + timeout
    got = None
    while time.monotonic() < deadline:
        path = find_sensor(address, timeout=max(0.1, deadline - time.monotonic()))
        if path:
            got = wait_value(path, index, want, timeout=1)
            if got == want:
                return got
    return got


def alive(sd):
    try:
        os.stat('address', dir_fd=sd.fd)
        return True
    except OSError:
        return False


def steady(addresses, check, tries=4):
    """check(paths), with paths the sensorN directories of `addresses` (in
    that order), run again if a sensor reconnected meanwhile.

    Python in the emulated guest, on a busy host, sometimes misses a
    sensor's keep-alive deadline and the driver reconnects the sensor
    (possibly as another sensorN). A listing taken across a reconnect shows
    the sensor missing: it says nothing of the tool. So each sensor's
    directory is held open while check() runs, and only if one of them went
    away meanwhile is check() run again; a failure with every sensor there
    throughout is a failure.
    """
    for _ in range(tries):
        sds = [open_sensor(a, timeout=20) for a in addresses]
        try:
            assert all(sds), 'sensor(s) %s did not come back' % addresses
            try:
                result = check([sd.path for sd in sds])
            except (AssertionError, KeyError, ValueError, OSError):
                if all(alive(sd) for sd in sds):
                    raise
                continue
            if all(alive(sd) for sd in sds):
                return result
        finally:
            for sd in sds:
                if sd:
                    sd.close()
    pytest.fail('the sensors %s reconnected during each of %d tries' % (addresses, tries))


def iio_of(path, timeout=0):
    """The IIO device of the sensor at `path`, found as the docs say: the
    one with the same parent (the tty) and the sensor's address as label.
    The driver registers it just after the lego-sensor device: `timeout`
    seconds to wait for it (None if it has not come by then)."""
    deadline = time.monotonic() + timeout
    while True:
        name = _iio_of(path)
        if name or time.monotonic() >= deadline:
            return name
        time.sleep(0.05)


def _iio_of(path):
    tty = os.path.realpath(os.path.join(path, 'device'))
    found = []
    address = read_attr(path, 'address')
    for d in glob.glob(IIO + '/iio:device*'):
        try:
            if os.path.dirname(os.path.realpath(d)) == tty and \
                    read_attr(d, 'label') == address:
                found.append(os.path.basename(d))
        except FileNotFoundError:
            pass                # another sensor's, gone meanwhile
    assert len(found) <= 1, found
    return found[0] if found else None


def blocks(text):
    """The text listing as {sensorN: {field: value}}."""
    out = {}
    for block in text.strip().split('\n\n'):
        lines = block.split('\n')
        fields = {}
        for ln in lines[1:]:
            k, v = ln.split(':', 1)
            fields[k] = v.strip()
        out[lines[0]] = fields
    return out


def scaled(raw, dec):
    """raw / 10^dec as the decimal text the tool must print."""
    if not dec:
        return str(raw)
    s = '%d.%0*d' % (abs(raw) // 10 ** dec, dec, abs(raw) % 10 ** dec)
    return '-' + s if raw < 0 else s


def sysfs_view(path):
    """What sysfs says of a sensor, in the JSON document's terms."""
    n = int(read_attr(path, 'num_values'))
    dec = int(read_attr(path, 'decimals'))
    raw = [int(read_attr(path, 'value%d' % k)) for k in range(n)]
    return {
        'name': os.path.basename(path),
        'address': read_attr(path, 'address'),
        'driver': read_attr(path, 'driver_name'),
        'mode': read_attr(path, 'mode'),
        'modes': read_attr(path, 'modes').split(' '),
        'num_values': n,
        'decimals': dec,
        'units': read_attr(path, 'units'),
        'raw_values': raw,
        'bin_data_format': read_attr(path, 'bin_data_format'),
        'iio_device': iio_of(path),
    }


def check_json_sensor(doc, path):
    want = sysfs_view(path)
    for k, v in want.items():
        assert doc[k] == v, (k, doc[k], v)
    # The scaled values are JSON numbers with the mode's decimals.
    assert [float(x) for x in doc['values']] == \
        [float(scaled(r, want['decimals'])) for r in want['raw_values']]


# --- listing ---------------------------------------------------------------

def test_text_listing(line):
    emu, path = connect(line, 'us')
    emu.set_values(0, [263])
    assert settle('ttyNM0', 0, 263) == 263

    def check(paths):
        path, = paths
        r = run()
        assert r.returncode == 0, r.stderr
        b = blocks(r.stdout)
        name = os.path.basename(path)
        assert list(b) == [name], r.stdout
        f = b[name]
        assert f['Address'] == 'ttyNM0'
        assert f['Driver'] == 'lego-ev3-us'
        assert f['Mode'] == 'US-DIST-CM'
        assert f['Modes'] == read_attr(path, 'modes')
        iio = iio_of(path, timeout=10)
        assert iio and f['IIO'] == iio
        assert read_attr(os.path.join(IIO, iio), 'name') == 'lego-ev3-us'
        assert f['value0'] == '26.3 cm'             # 263 with 1 decimal
    steady(['ttyNM0'], check)


def test_negative_value_and_selection(line, line2):
    """Two sensors; a negative value with a decimal; SENSOR by name,
    address, tty and label; -s."""
    emu, path = connect(line, 'fcl-humidity')
    emu2, path2 = connect(line2, 'color')
    emu.set_values(0, [-53])                    # -5.3 C
    assert settle('ttyNM0', 0, -53) == -53
    emu2.set_values(0, [42])
    assert settle('ttyNM2', 0, 42) == 42

    def check(paths):
        n1, n2 = [os.path.basename(p) for p in paths]
        b = blocks(run().stdout)
        assert sorted(b, key=lambda s: int(s[6:])) == list(b) and set(b) == {n1, n2}
        assert b[n1]['value0'] == '-5.3 C'
        assert b[n1]['Driver'] == 'fcl-humidity'
        assert b[n2]['value0'] == '42 pct'
        assert b[n2]['Address'] == 'ttyNM2'
        for sel in ([n2], ['ttyNM2'], ['-s', n2], ['--sensor=ttyNM2']):
            r = run(*sel)
            assert r.returncode == 0, r.stderr
            assert list(blocks(r.stdout)) == [n2], (sel, r.stdout)
        r = run(n1, '-s', 'ttyNM2')
        assert set(blocks(r.stdout)) == {n1, n2}
    steady(['ttyNM0', 'ttyNM2'], check)


def test_port_label_selects(ev3_module):
    """A sensor whose address has a port label (ttyNM0:in3) is found by the
    label, the whole address and the tty."""
    ln = Line(0)
    ln.attach()
    path = None
    try:
        # The label, set as lego-ev3-attach --label sets it, before the
        # handshake.
        fcntl.ioctl(ln.fd, LEGO_EV3_SET_PORT_LABEL, b'in3'.ljust(16, b'\0'))
        emu = ln.plug('gyro')
        path = find_sensor('ttyNM0:in3', timeout=15)
        assert path, emu.events

        def check(paths):
            for sel in ('in3', 'ttyNM0:in3', 'ttyNM0'):
                r = run('--json', sel)
                assert r.returncode == 0, (sel, r.stderr)
                doc = json.loads(r.stdout)
                assert [s['address'] for s in doc['sensors']] == ['ttyNM0:in3']
            b = blocks(run('in3').stdout)
            assert b[os.path.basename(paths[0])]['Address'] == 'ttyNM0:in3'
        steady(['ttyNM0:in3'], check)
    finally:
        ln.close()
    assert path is None or wait_gone(path, 5)


def test_json_matches_sysfs_and_emulator(line, line2):
    emu, path = connect(line, 'color')
    emu2, path2 = connect(line2, 'fcl-humidity')
    # RGB-RAW: four values (the fourth with the LED off), no decimals.
    emu.set_values(4, [300, 400, 500, 12])
    write_attr(path, 'mode', 'RGB-RAW')        # kept across reconnects
    assert [settle('ttyNM0', k, v) for k, v in enumerate([300, 400, 500, 12])] == \
        [300, 400, 500, 12]
    emu2.set_values(0, [1234])                  # 123.4 C
    assert settle('ttyNM2', 0, 1234) == 1234

    def check(paths):
        path, path2 = paths
        r = run('--json')
        assert r.returncode == 0, r.stderr
        doc = json.loads(r.stdout)
        assert list(doc) == ['sensors']
        by_addr = {s['address']: s for s in doc['sensors']}
        assert set(by_addr) == {'ttyNM0', 'ttyNM2'}

        s = by_addr['ttyNM0']
        check_json_sensor(s, path)
        assert s['raw_values'] == [300, 400, 500, 12]     # what the emulator sent
        assert s['values'] == [300, 400, 500, 12]
        assert s['mode'] == 'RGB-RAW' and s['units'] == '' and s['bin_data_format'] == 's16'
        assert s['iio_device'] is not None

        s = by_addr['ttyNM2']
        check_json_sensor(s, path2)
        assert s['raw_values'] == [1234] and s['values'] == [123.4]
        assert s['units'] == 'C' and s['decimals'] == 1
        # The number is printed exactly as its decimal text.
        assert '"values": [123.4]' in r.stdout
    steady(['ttyNM0', 'ttyNM2'], check)


def test_json_escapes_strings(line):
    """Mode names and units are printable ASCII, quotes and backslashes
    included: the document must still parse and give them back."""
    sdef = SensorDef(92, 'ev3-uart-92', 2, [
        Mode('Q"T\\E', (0, 100), (0, 100), 'a"\\', 1, S8, 3, 0),
        Mode('PLAIN', (0, 100), (0, 100), None, 1, S16, 3, 0)], speed=57600)
    emu = line.plug(sdef)
    path = find_sensor(line.address, timeout=15)
    assert path, emu.events
    emu.set_values(0, [7])
    assert settle('ttyNM0', 0, 7) == 7

    def check(paths):
        path, = paths
        r = run('--json')
        assert r.returncode == 0, r.stderr
        doc = json.loads(r.stdout)
        (s,) = doc['sensors']
        assert s['modes'] == ['Q"T\\E', 'PLAIN']
        assert s['mode'] == 'Q"T\\E' and s['units'] == 'a"\\'
        assert s['raw_values'] == [7]
        # No value has an IIO type: no IIO device.
        assert s['iio_device'] is None and iio_of(path) is None
        check_json_sensor(s, path)
        b = blocks(run().stdout)
        assert b[s['name']]['IIO'] == 'none'
        assert b[s['name']]['value0'] == '7 a"\\'
    steady(['ttyNM0'], check)


# --- --mode ----------------------------------------------------------------

def test_mode_switch(line):
    emu, path = connect(line, 'us')
    emu.set_values(1, [104])                    # 10.4 inch

    def switch(paths):
        path, = paths
        # The only sensor: no SENSOR needed.
        r = run('--mode=US-DIST-IN')
        assert r.returncode == 0, r.stderr
        assert read_attr(path, 'mode') == 'US-DIST-IN'
        f = blocks(r.stdout)[os.path.basename(path)]
        assert f['Mode'] == 'US-DIST-IN'
        assert settle('ttyNM0', 0, 104) == 104
        assert blocks(run().stdout)[os.path.basename(path)]['value0'] == '10.4 inch'
    steady(['ttyNM0'], switch)

    def back(paths):
        path, = paths
        # By address, short option, and JSON after the switch.
        r = run('-m', 'US-DIST-CM', '--json', 'ttyNM0')
        assert r.returncode == 0, r.stderr
        assert read_attr(path, 'mode') == 'US-DIST-CM'
        assert json.loads(r.stdout)['sensors'][0]['mode'] == 'US-DIST-CM'
    steady(['ttyNM0'], back)

    def bad(paths):
        path, = paths
        # A mode the sensor does not have: EINVAL, nothing changed.
        r = run('--mode=NO-SUCH', os.path.basename(path))
        assert r.returncode == 1, (r.returncode, r.stderr)
        assert 'no mode "NO-SUCH"' in r.stderr and 'US-DIST-IN' in r.stderr
        assert r.stdout == ''
        assert read_attr(path, 'mode') == 'US-DIST-CM'
    steady(['ttyNM0'], bad)


def test_mode_needs_a_sensor_when_several(line, line2):
    connect(line, 'us')
    connect(line2, 'color')

    def check(paths):
        r = run('--mode=COL-AMBIENT')
        assert r.returncode == 2, (r.returncode, r.stderr)
        assert 'name the one to switch' in r.stderr
        r = run('--mode=COL-AMBIENT', 'ttyNM0', 'ttyNM2')
        assert r.returncode == 2, (r.returncode, r.stderr)
        r = run('--mode=COL-AMBIENT', 'ttyNM2')
        assert r.returncode == 0, r.stderr
        assert read_attr(paths[1], 'mode') == 'COL-AMBIENT'
    steady(['ttyNM0', 'ttyNM2'], check)


def test_mode_busy_with_iio_buffer(line):
    """An enabled IIO buffer holds the mode: EBUSY, said with strerror."""
    connect(line, 'us')

    def check(paths):
        path, = paths
        name = iio_of(path, timeout=10)
        assert name, 'no IIO device for ' + path
        dev = os.path.join(IIO, name)
        write_attr(dev, 'scan_elements/in_distance0_en', '1')
        write_attr(dev, 'buffer/enable', '1')
        try:
            r = run('--mode=US-DIST-IN')
            assert r.returncode == 1, (r.returncode, r.stderr)
            assert os.strerror(16) in r.stderr         # EBUSY
            assert 'IIO buffer' in r.stderr
            assert read_attr(path, 'mode') == 'US-DIST-CM'
        finally:
            try:
                write_attr(dev, 'buffer/enable', '0')
                write_attr(dev, 'scan_elements/in_distance0_en', '0')
            except OSError:
                pass            # gone with a reconnect
    steady(['ttyNM0'], check)


# --- --watch ---------------------------------------------------------------

def read_until(fd, proc, want, timeout):
    """Read fd until `want` (a regex) matches what was read, or timeout."""
    data = b''
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.1)
        if r:
            try:
                chunk = os.read(fd, 65536)
            except OSError:
                break
            if not chunk:
                break
            data += chunk
            if re.search(want, data.decode(errors='replace')):
                break
        elif proc.poll() is not None:
            break
    return data.decode(errors='replace')


def test_watch_redraws_without_clearing_a_pipe(line):
    emu, path = connect(line, 'us')
    emu.set_values(0, [100])
    assert settle('ttyNM0', 0, 100) == 100
    p = subprocess.Popen([tool(), '--watch=0.3'], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    try:
        out = read_until(p.stdout.fileno(), p, r'value0:  10\.0 cm', 10)
        assert 'value0:  10.0 cm' in out, out
        emu.set_values(0, [77])                 # a new value, seen live
        out += read_until(p.stdout.fileno(), p, r'value0:  7\.7 cm', 10)
        assert 'value0:  7.7 cm' in out, out
    finally:
        p.send_signal(signal.SIGINT)
        rc = p.wait(10)
    assert rc == 0, p.stderr.read()
    frames = re.findall(r'^Every 0\.3s: lego-sensors', out, re.M)
    assert len(frames) >= 2, out
    assert '\033[' not in out                    # no screen control into a pipe


def test_watch_clears_a_terminal(line):
    connect(line, 'gyro')
    master, slave = pty.openpty()
    p = subprocess.Popen([tool(), '-w0.2', 'ttyNM0'], stdout=slave,
                         stderr=subprocess.PIPE)
    os.close(slave)
    try:
        out = read_until(master, p, r'(?s)\033\[H\033\[2J.*\033\[H\033\[2J.*value0', 10)
    finally:
        p.terminate()
        rc = p.wait(10)
        os.close(master)
    assert rc == 0, p.stderr.read()
    assert out.count('\033[H\033[2J') >= 2, repr(out)
    assert 'Driver:  lego-ev3-gyro' in out


def test_watch_json_lines(line):
    emu, path = connect(line, 'color')
    p = subprocess.Popen([tool(), '--watch=0.2', '--json'], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    try:
        out = read_until(p.stdout.fileno(), p, r'(.*\n){3}', 10)
    finally:
        p.send_signal(signal.SIGINT)
        rc = p.wait(10)
    assert rc == 0, p.stderr.read()
    docs = [json.loads(ln) for ln in out.splitlines()[:3]]
    assert len(docs) == 3, out
    for d in docs:
        assert [s['address'] for s in d['sensors']] in (['ttyNM0'], []), d
    assert [d for d in docs if d['sensors']], 'no listing had the sensor: %s' % out

    def check(paths):
        p = subprocess.Popen([tool(), '--watch=0.2', '--json'], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
        try:
            out = read_until(p.stdout.fileno(), p, r'\n', 10)
        finally:
            p.send_signal(signal.SIGINT)
            p.wait(10)
        (s,) = json.loads(out.splitlines()[0])['sensors']
        check_json_sensor(s, paths[0])
    steady(['ttyNM0'], check)


# --- errors and the rest ---------------------------------------------------

def test_no_sensors(ev3_module):
    left = glob.glob(CLASS + '/sensor*')
    if left:
        pytest.skip('sensors of another test still here: %s' % left)
    for args in ([], ['--json'], ['--mode=X']):
        r = run(*args)
        assert r.returncode == 1, (args, r.returncode, r.stderr)
        assert 'no EV3 sensors' in r.stderr and 'lego-ev3-attach' in r.stderr
        assert r.stdout == ''


def test_no_class(tmp_path):
    """Without the module the class does not exist: the message says so."""
    env = dict(os.environ, SYSFS_PATH=str(tmp_path))
    r = run(env=env)
    assert r.returncode == 1
    assert 'lego-sensor class does not exist' in r.stderr
    assert 'modprobe lego_ev3_uart' in r.stderr


def test_unknown_sensor(line):
    connect(line, 'us')

    def check(paths):
        path, = paths
        for sel in (['sensor99'], ['ttyNM9'], ['-s', 'nope'], ['--mode=US-DIST-IN', 'nope']):
            r = run(*sel)
            assert r.returncode == 1, (sel, r.returncode, r.stderr)
            assert 'no sensor "%s"' % sel[-1] in r.stderr
            assert os.path.basename(path) in r.stderr       # the ones there are
        assert read_attr(path, 'mode') == 'US-DIST-CM'
    steady(['ttyNM0'], check)


@pytest.mark.parametrize('args', [
    ['--bogus'],
    ['--watch=0'],
    ['--watch=abc'],
    ['-w0.01'],
    ['--mode='],
    ['--mode=X', 'a', 'b'],
    ['--sensor'],
])
def test_usage_errors(ev3_module, args):
    r = run(*args)
    assert r.returncode == 2, (args, r.returncode, r.stderr)
    assert r.stderr.strip() and r.stdout == ''


def test_help_and_version():
    r = run('--help')
    assert r.returncode == 0
    for opt in ('--watch[=SECONDS]', '--json', '--mode=MODE', '--sensor=SENSOR', '--version'):
        assert opt in r.stdout
    with open(os.path.join(TOP, 'dkms.conf')) as f:
        ver = re.search(r'^PACKAGE_VERSION="([^"]+)"', f.read(), re.M).group(1)
    r = run('--version')
    assert r.returncode == 0 and r.stdout == 'lego-sensors %s\n' % ver
