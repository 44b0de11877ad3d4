#!/usr/bin/env python3
"""`make demo`, inside the test VM: what a user sees with both drivers.

Four emulated EV3 sensors are plugged into serial lines (a colour sensor on
a real 16550A UART, ttyS1, and an ultrasonic, a gyro and an infrared sensor
on null-modem ttys), attached with lego-ev3-attach, and read through the
lego-sensor class, IIO and python-ev3dev2. An emulated NXT brick is plugged
into a USB port and driven with nxtctl, and another is reached over
Bluetooth (two virtual controllers in the VM) with nxtctl connect. Every
step checks what it shows;
the exit status is the number of failed steps (0: all passed).
"""
import contextlib
import io
import os
import re
import shlex
import signal
import subprocess
import sys
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', 'guest'))
import btlink  # noqa: E402
import ev3  # noqa: E402
import nxtdev as nxt  # noqa: E402

TOOLS = os.path.join(os.environ.get('LEGO_BUILD', ''), 'tools')
ATTACH = os.path.join(TOOLS, 'lego-ev3-attach')
NXTCTL = os.path.join(TOOLS, 'nxtctl')

failed = []
children = []
STEPS = []          # (part, title, function), in the order they are defined


def say(text=''):
    print(text, flush=True)


def step(part, title):
    """Decorator: register a demo step of `part`."""
    def wrap(fn):
        STEPS.append((part, title, fn))
        return fn
    return wrap


def run_step(title, fn):
    """Run one step, report ok or FAILED; a failed step never stops the demo."""
    say()
    say('-- ' + title)
    try:
        fn()
    except Exception as e:
        failed.append(title)
        say('   FAILED: %s' % (e or type(e).__name__))
        if os.environ.get('DEMO_DEBUG'):
            traceback.print_exc()
    else:
        say('   ok')


def check(cond, what):
    if not cond:
        raise AssertionError(what)


def shell(argv, expect=0):
    """Run a command as a user would, echoing it and its output."""
    say('   $ ' + ' '.join(os.path.basename(a) if a in (NXTCTL, ATTACH) else shlex.quote(a)
                           for a in argv))
    r = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    for line in (r.stdout + r.stderr).splitlines():
        say('     ' + line)
    check(r.returncode == expect, '%s exited with %d' % (os.path.basename(argv[0]), r.returncode))
    return r.stdout


def wait_for(fn, want, timeout=5.0):
    deadline = time.monotonic() + timeout
    got = fn()
    while got != want and time.monotonic() < deadline:
        time.sleep(0.05)
        got = fn()
    return got


def attr(path, name):
    return ev3.read_attr(path, name)


# ---------------------------------------------------------------- EV3

EV3 = 'EV3 UART sensors (lego_ev3_uart)'
NXT = 'NXT brick over USB (lego_nxt_usb)'

SENSORS = []        # (label, kind, Line, emulator)
PATHS = {}          # label -> /sys/class/lego-sensor/sensorN


def attach_line(ln, label):
    """Attach the discipline with the project's helper, as a user would."""
    p = subprocess.Popen([ATTACH, '--foreground', '--label', label, ln.host],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    children.append(p)
    say('   $ lego-ev3-attach --foreground --label %s %s &' % (label, ln.host))


def plug_sensors():
    ev3.load_nullmodem()
    pair = ev3.serial_pair()
    lines = []
    if pair:
        lines.append(('in1', 'color', ev3.SerialLine(*pair)))
    else:
        lines.append(('in1', 'color', ev3.Line(3)))
    for label, kind, n in (('in2', 'us', 0), ('in3', 'gyro', 1), ('in4', 'ir', 2)):
        lines.append((label, kind, ev3.Line(n)))
    for label, kind, ln in lines:
        attach_line(ln, label)
    time.sleep(0.5)
    for label, kind, ln in lines:
        # Several emulators share one Python process in an emulated
        # machine: slow their continuous streams (keep-alives stay exact).
        emu = ln.plug(kind, period_scale=10)
        SENSORS.append((label, kind, ln, emu))
        say('   plugged an emulated %s sensor into %s (%s)' % (kind, ln.host, label))
        time.sleep(0.3)


@step(EV3, 'Plug four EV3 sensors into serial lines and attach the line discipline')
def _():
    check(os.access(ATTACH, os.X_OK), 'lego-ev3-attach was not built')
    plug_sensors()
    for label, kind, ln, emu in SENSORS:
        path = ev3.find_sensor('%s:%s' % (ln.address, label), timeout=20)
        check(path, 'the %s sensor on %s did not register' % (kind, ln.host))
        PATHS[label] = path
    say('   %-32s %-8s %-16s %-13s %s' % ('sysfs', 'address', 'driver_name', 'mode', 'modes'))
    for label, kind, ln, emu in SENSORS:
        p = PATHS[label]
        say('   %-32s %-8s %-16s %-13s %s' % (p, label, attr(p, 'driver_name'), attr(p, 'mode'),
                                              ' '.join(attr(p, 'modes').split()[:4]) + ' ...'))


def emu_of(label):
    return next(e for lab, _, _, e in SENSORS if lab == label)


@step(EV3, 'Sensor values change in sysfs (value0 of each sensor, three readings)')
def _():
    check(PATHS, 'no sensors')
    course = {'in1': [(0, [12]), (0, [48]), (0, [85])],          # reflected light, %
              'in2': [(0, [1200]), (0, [640]), (0, [263])],      # distance, 0.1 cm
              'in3': [(0, [0]), (0, [45]), (0, [90])],           # angle, degrees
              'in4': [(0, [70]), (0, [40]), (0, [10])]}          # proximity, %
    say('   %-6s %-12s %-12s %-12s %s' % ('', 'in1 COL-REF', 'in2 US-DIST', 'in3 GYRO-ANG', 'in4 IR-PROX'))
    for i in range(3):
        row = []
        for label in ('in1', 'in2', 'in3', 'in4'):
            mode, values = course[label][i]
            emu_of(label).set_values(mode, values)
            got = ev3.wait_value(PATHS[label], 0, values[0], timeout=5)
            check(got == values[0], '%s value0 is %s, the sensor sends %d' % (label, got, values[0]))
            scaled = got / 10 ** int(attr(PATHS[label], 'decimals'))
            row.append('%g %s' % (scaled, attr(PATHS[label], 'units')))
        say('   t%-5d %-12s %-12s %-12s %s' % (i, *row))
        time.sleep(0.3)


@step(EV3, 'The same sensors through IIO (scaled to SI units)')
def _():
    dev = ev3.iio_device('lego-ev3-us')
    check(dev, 'no IIO device for the ultrasonic sensor')
    emu_of('in2').set_values(0, [505])
    raw = ev3.wait_attr_int(dev, 'in_distance0_raw', 505)
    check(raw == 505, 'in_distance0_raw is %s' % raw)
    scale = float(attr(dev, 'in_distance0_scale'))
    say('   %s: in_distance0_raw=%d in_distance0_scale=%s -> %.3f m' % (dev, raw, attr(dev, 'in_distance0_scale'),
                                                                       raw * scale))
    check(abs(raw * scale - 0.505) < 1e-6, 'distance in metres')
    dev = ev3.iio_device('lego-ev3-gyro')
    check(dev, 'no IIO device for the gyro')
    emu_of('in3').set_values(0, [-30])
    raw = ev3.wait_attr_int(dev, 'in_angl0_raw', -30)
    check(raw == -30, 'in_angl0_raw is %s' % raw)
    say('   %s: in_angl0_raw=%d in_angl0_scale=%s -> %.4f rad' % (dev, raw, attr(dev, 'in_angl0_scale'),
                                                                 raw * float(attr(dev, 'in_angl0_scale'))))


@step(EV3, 'Switch the colour sensor to COL-COLOR by writing its mode attribute')
def _():
    p = PATHS['in1']
    emu_of('in1').set_values(2, [5])
    say('   $ echo COL-COLOR > %s/mode' % p)
    ev3.write_attr(p, 'mode', 'COL-COLOR')
    check(attr(p, 'mode') == 'COL-COLOR', 'mode reads %s' % attr(p, 'mode'))
    got = ev3.wait_value(p, 0, 5, timeout=5)
    check(got == 5, 'value0 is %s after the switch, the sensor sends 5 (red)' % got)
    say('   mode=%s value0=%d (5 is red) num_values=%s' % (attr(p, 'mode'), got, attr(p, 'num_values')))
    ev3.write_attr(p, 'mode', 'COL-REFLECT')


@step(EV3, 'python-ev3dev2, unmodified, reads a colour and a distance')
def _():
    for label in PATHS:
        # What the shipped udev rule does on a real system: group-writable
        # mode and direct attributes (python-ev3dev2 opens them read-write).
        for a in ('mode', 'direct'):
            os.chmod(os.path.join(PATHS[label], a), 0o664)
    os.environ['FAKE_SYS'] = ''
    # python-ev3dev2 warns on stderr that buttons need evdev: not used here.
    with contextlib.redirect_stderr(io.StringIO()):
        from ev3dev2.sensor import INPUT_1, INPUT_2
        from ev3dev2.sensor.lego import ColorSensor, UltrasonicSensor
    emu_of('in1').set_values(2, [3])
    emu_of('in2').set_values(0, [427])
    cs = ColorSensor(INPUT_1)
    us = UltrasonicSensor(INPUT_2)
    say('   >>> ColorSensor(INPUT_1).color_name')
    name = wait_for(lambda: cs.color_name, 'Green')
    say('   %r' % name)
    check(name == 'Green', 'color_name is %r, the sensor sends 3 (green)' % name)
    say('   >>> UltrasonicSensor(INPUT_2).distance_centimeters')
    cm = wait_for(lambda: us.distance_centimeters, 42.7)
    say('   %r' % cm)
    check(abs(cm - 42.7) < 1e-9, 'distance is %r cm, the sensor sends 42.7' % cm)


@step(EV3, 'Unplug the ultrasonic sensor: its devices go away, and come back on replug')
def _():
    emu = emu_of('in2')
    p = PATHS['in2']
    emu.unplug()
    check(ev3.wait_gone(p, 10), '%s still there after unplug' % p)
    say('   unplugged: %s is gone' % p)
    emu.plug()
    ln = next(ln for lab, _, ln, _ in SENSORS if lab == 'in2')
    q = ev3.find_sensor('%s:in2' % ln.address, timeout=20)
    check(q, 'no sensor after replug')
    PATHS['in2'] = q
    say('   plugged back: %s (%s)' % (q, attr(q, 'driver_name')))


def kernel_log(pattern):
    """The lines of the kernel log that match `pattern` (a regex)."""
    out = subprocess.run(['dmesg'], capture_output=True, text=True).stdout
    return [ln for ln in out.splitlines() if re.search(pattern, ln)]


@step(EV3, 'What the driver logged (dmesg)')
def _():
    lines = kernel_log(r'lego_ev3_uart: ')
    for ln in lines[-10:]:
        say('   ' + ln)
    connected = [ln for ln in lines if ' connected as ' in ln]
    check(len(connected) >= 5, 'expected five connections (four sensors and a replug), saw %d' % len(connected))


# ---------------------------------------------------------------- NXT

BRICK = {}


@step(NXT, 'Plug an emulated NXT brick into USB')
def _():
    check(os.access(NXTCTL, os.X_OK), 'nxtctl was not built')
    b = nxt.Brick(serial='001653DE0001', name='Demo')
    b.plug()
    BRICK['b'] = b
    say('   %s appeared' % b.node)
    shell([NXTCTL, 'list'])


@step(NXT, 'nxtctl info: name, firmware, battery, Bluetooth address')
def _():
    out = shell([NXTCTL, '-d', BRICK['b'].node, 'info'])
    check('Demo' in out, 'the brick name is missing')
    check('00:16:53:DE:00:01' in out.upper() or '001653DE0001' in out.upper(), 'the Bluetooth address is missing')


@step(NXT, 'nxtctl tone: play 440 Hz for half a second')
def _():
    fw = BRICK['b'].fw
    shell([NXTCTL, '-d', BRICK['b'].node, 'tone', '440', '500'])
    with fw.lock:
        sound = fw.sound
    check(sound and sound[0] == 'tone' and sound[1] == 440, 'the brick is not playing 440 Hz: %r' % (sound,))
    say('   the brick beeps at %d Hz' % sound[1])


@step(NXT, 'nxtctl motor: turn motor A one revolution and read it back')
def _():
    node = BRICK['b'].node
    shell([NXTCTL, '-d', node, 'motor', 'A', '75', '--tacho-limit', '360'])

    def tacho():
        r = subprocess.run([NXTCTL, '-d', node, 'motor-state', 'A'], capture_output=True, text=True,
                           timeout=30)
        m = re.search(r'^tacho_count: (-?\d+)$', r.stdout, re.M)
        return int(m.group(1)) if m else None
    got = wait_for(tacho, 360, timeout=10)
    check(got == 360, 'motor A stopped at %s degrees, not 360' % got)
    out = shell([NXTCTL, '-d', node, 'motor-state', 'A'])
    check('run_state: idle' in out, 'motor A still running after its tacho limit')


@step(NXT, 'i2cget: the ultrasonic sensor on port 4, through the port\'s I2C adapter')
def _():
    b = BRICK['b']
    shell(['i2cdetect', '-l'])
    adapter = 'NXT %s port 4' % b.serial
    for cm in (42, 17):
        b.fw.ultrasonic.distance = cm
        out = shell(['i2cget', '-y', '-a', adapter, '0x01', '0x42'])
        check(out.strip() == '0x%02x' % cm, 'read %r, the sensor says %d cm' % (out.strip(), cm))
        say('   %d cm' % int(out, 16))


@step(NXT, 'What the driver logged (dmesg)')
def _():
    lines = kernel_log(r'lego_nxt_usb|idVendor=0694')
    for ln in lines[-6:]:
        say('   ' + ln)
    check(any('now at nxt' in ln for ln in lines), 'the driver did not log the brick')


# ---------------------------------------------------------------- Bluetooth

BT = 'NXT brick over Bluetooth (lego_nxt_serial)'
RADIO = {}
# Where nxtctl connect's daemon leaves its file (/run/nxtctl on a real
# system): the VM's root is the host's, read-only.
os.environ['NXTCTL_RUNDIR'] = '/tmp/nxtctl-demo'


@step(BT, 'Connect an emulated NXT brick over Bluetooth with nxtctl connect')
def _():
    if not os.path.isdir('/sys/module/lego_nxt_serial'):
        subprocess.run(['insmod', os.path.join(os.environ.get('LEGO_BUILD', ''), 'drivers',
                                               'lego', 'nxt', 'lego_nxt_serial.ko')], check=True)
    RADIO['radio'] = radio = btlink.Radio()
    say('   two virtual Bluetooth controllers: the brick at %s, this computer at %s'
        % (radio.brick, radio.host))
    RADIO['server'] = btlink.BrickServer(radio.brick, nxt.nxt_brick.Firmware(name='Rover'))
    out = shell([NXTCTL, 'connect', radio.brick])
    node = out.strip()
    check(node.startswith('/dev/nxt') and os.path.exists(node), 'no node: %r' % out)
    RADIO['node'] = node


@step(BT, 'nxtctl info and tone on the Bluetooth brick, through the same kind of node')
def _():
    node = RADIO['node']
    out = shell([NXTCTL, '-d', node, 'info'])
    check('Rover' in out, 'the brick name is missing')
    shell([NXTCTL, '-d', node, 'tone', '880', '200'])
    fw = RADIO['server'].fw
    with fw.lock:
        sound = fw.sound
    check(sound and sound[1] == 880, 'the brick is not playing 880 Hz: %r' % (sound,))
    shell([NXTCTL, 'list'])


@step(BT, 'nxtctl disconnect: the node and the Bluetooth link go')
def _():
    node = RADIO.pop('node')
    shell([NXTCTL, '-d', node, 'disconnect'])
    check(not os.path.exists(node), node + ' is still there')
    srv = RADIO['server']
    check(srv.brick.gone.wait(5), 'the link is still up')


def cleanup():
    for label, kind, ln, emu in SENSORS:
        ln.close()
    for p in children:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            p.kill()
    if 'b' in BRICK:
        BRICK['b'].unplug()
    if 'node' in RADIO:
        subprocess.run([NXTCTL, '-d', RADIO['node'], 'disconnect'], capture_output=True)
    if 'server' in RADIO:
        RADIO['server'].close()
    if 'radio' in RADIO:
        RADIO['radio'].stop()


def main():
    t0 = time.monotonic()
    part = None
    try:
        for p, title, fn in STEPS:
            if p != part:
                part = p
                say()
                say('=' * 72)
                say('== ' + part)
            run_step(title, fn)
    finally:
        cleanup()
    say()
    say('=' * 72)
    if failed:
        say('make demo: %d of %d steps FAILED:' % (len(failed), len(STEPS)))
        for title in failed:
            say('  - ' + title)
    else:
        say('make demo: all %d steps passed in %.0f s' % (len(STEPS), time.monotonic() - t0))
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
