"""Trace events (lego_ev3_uart, lego_nxt_usb) and the debugfs counters.

The events are read back from tracefs for an EV3 handshake, a mode switch
and a loss (an emulated colour sensor on a pty), and for NXT transactions
(the emulated brick); the counters in debugfs are compared with what the
emulators did. Documentation/lego/tracing.rst describes both.
"""
import contextlib
import errno
import fcntl
import os
import re
import struct
import subprocess
import termios
import time

import pytest

import nxtdev as nxt
from conftest import wait_for
from ev3 import iio_device
from tracing import DEBUGFS, Trace, counters, tracefs, write

SERIAL = '0016530E1F2A'
N_LEGOEV3 = 29

EV3_EVENTS = {
    'ev3_uart_rx': {'tty', 'msg', 'hdr', 'arg', 'info', 'len', 'accept', 'mode_changed'},
    'ev3_uart_handshake': {'tty', 'type', 'num_modes', 'num_view_modes', 'speed'},
    'ev3_uart_tx': {'tty', 'msg', 'hdr', 'arg', 'len', 'ret'},
    'ev3_uart_speed': {'tty', 'speed', 'ret'},
    'ev3_uart_state': {'tty', 'from', 'to', 'reason'},
    'ev3_uart_sensor': {'tty', 'what', 'type', 'driver', 'dev', 'speed'},
}
NXT_EVENTS = {
    'nxt_usb_tx': {'dev', 'xfer', 'type', 'opcode', 'len', 'ret'},
    'nxt_usb_rx': {'dev', 'xfer', 'type', 'opcode', 'status', 'len'},
    'nxt_usb_done': {'dev', 'xfer', 'opcode', 'err'},
    'nxt_usb_timeout': {'dev', 'xfer', 'opcode', 'what'},
    'nxt_usb_stall': {'dev', 'in', 'stalls'},
    'nxt_usb_reset': {'dev', 'what'},
    'nxt_usb_drain': {'dev', 'ms', 'orphan', 'orphan_op'},
    'nxt_usb_drop': {'dev', 'why', 'type', 'opcode', 'len', 'drain_end'},
}

def event_fields(system, name):
    with open('%s/events/%s/%s/format' % (tracefs(), system, name)) as f:
        return set(re.findall(r'field:[^;]*?(\w+)(?:\[\d*\])?;', f.read()))


@contextlib.contextmanager
def pty_sensor():
    """A pty for the line discipline: yields (tty, attach); attach(kind)
    sets the discipline, starts an emulated sensor of that kind on the
    master and returns (emulator, sensorN directory). Stops and closes all
    on the way out."""
    import ev3
    master, slave = os.openpty()
    tty = 'pts' + os.ttyname(slave).split('/')[-1]
    emus = []

    def attach(kind):
        fcntl.ioctl(slave, termios.TIOCSETD, struct.pack('i', N_LEGOEV3))
        emu = ev3.ev3_sensor.EmulatedSensor(master, kind)
        emus.append(emu)
        emu.start()
        path = ev3.find_sensor(tty, timeout=15)
        assert path, 'no sensor at %s (%s)' % (tty, emu.events)
        return emu, path

    try:
        yield tty, attach
    finally:
        for emu in emus:
            emu.stop()
        os.close(slave)
        os.close(master)


def test_ev3_events_are_in_tracefs(ev3_module):
    have = set(os.listdir('%s/events/lego_ev3_uart' % tracefs()))
    assert set(EV3_EVENTS) <= have
    for name, fields in EV3_EVENTS.items():
        assert fields <= event_fields('lego_ev3_uart', name), name


def test_nxt_events_are_in_tracefs():
    nxt.load_driver()
    have = set(os.listdir('%s/events/lego_nxt_usb' % tracefs()))
    assert set(NXT_EVENTS) <= have
    for name, fields in NXT_EVENTS.items():
        assert fields <= event_fields('lego_nxt_usb', name), name


def test_ev3_handshake_mode_switch_and_loss(ev3_module):
    """A colour sensor's whole life on a pty, read back from the trace, and
    the port's counters against the emulator's."""
    trace = Trace('lego_ev3_uart')
    try:
        with pty_sensor() as (tty, attach):
            emu, path = attach('color')
            check_life(trace, tty, emu, path)
    finally:
        trace.stop()
    assert not os.path.exists('%s/lego_ev3_uart/%s' % (DEBUGFS, tty)), \
        'the port\'s debugfs directory outlived it'


def check_life(trace, tty, emu, path):
    """The handshake, a mode switch and a loss, in the trace and the
    counters."""
    import ev3
    emu.set_values(0, [61])
    assert ev3.wait_value(path, 0, 61) == 61

    # The handshake: TYPE, the state changes, ACK both ways, the
    # speed, the registration, then DATA and keep-alive NACKs.
    rx = trace.events('ev3_uart_rx', tty=tty, msg='TYPE')
    assert rx and rx[0][1]['arg'] == '29', rx
    hs = trace.events('ev3_uart_handshake', tty=tty)
    assert hs and hs[0][1]['type'] == '29' and hs[0][1]['speed'] == '57600', hs
    assert trace.events('ev3_uart_rx', tty=tty, msg='ACK')
    # Each message of the handshake: MODES and SPEED, then the modes'
    # INFO, ending with mode 0's FORMAT.
    hsmsgs = [f for _, f in trace.events('ev3_uart_rx', tty=tty)
              if f['msg'] in ('CMD', 'INFO')]
    assert [(f['hdr'], f['len']) for f in hsmsgs[:2]] == [('0x49', '4'), ('0x52', '6')], hsmsgs
    assert (hsmsgs[-1]['hdr'], hsmsgs[-1]['info']) == ('0x90', '0x80'), hsmsgs
    names = [f for f in hsmsgs if f['msg'] == 'INFO' and f['info'] == '0x00']
    assert len(names) == 6, names                    # the colour sensor's 6 modes
    states = [(f['from'], f['to']) for _, f in trace.events('ev3_uart_state', tty=tty)]
    for step in [('SYNC', 'INFO'), ('INFO', 'ACKED'), ('ACKED', 'DATA')]:
        assert step in states, states
    assert trace.events('ev3_uart_tx', tty=tty, msg='ACK', ret=0)
    assert trace.events('ev3_uart_speed', tty=tty, speed=57600)
    reg = trace.events('ev3_uart_sensor', tty=tty, event='registered')
    assert reg and reg[0][1]['driver'] == 'lego-ev3-color', reg
    assert reg[0][1]['dev'] == os.path.basename(path), reg
    data = trace.events('ev3_uart_rx', tty=tty, msg='DATA', arg=0)
    assert data and data[-1][1]['accept'] == 'checksum', data
    assert trace.wait('ev3_uart_tx', tty=tty, msg='NACK')

    # A mode switch: SELECT out, the first DATA of mode 1 marks it.
    ev3.write_attr(path, 'mode', 'COL-AMBIENT')
    emu.set_values(1, [7])
    assert ev3.wait_value(path, 0, 7) == 7
    assert trace.events('ev3_uart_tx', tty=tty, msg='SELECT', arg=1, ret=0)
    assert trace.events('ev3_uart_rx', tty=tty, msg='DATA', arg=1, mode_changed=1)

    # A loss: the sensor goes silent.
    emu.unplug()
    assert ev3.wait_gone(path, 5.0)
    lost = trace.wait('ev3_uart_sensor', tty=tty, event='lost')
    assert lost and lost[0][1]['driver'] == 'lego-ev3-color', lost
    back = [f for _, f in trace.events('ev3_uart_state', tty=tty)
            if f['from'] == 'DATA' and f['to'] == 'SYNC']
    assert back and back[-1]['reason'], back
    assert trace.events('ev3_uart_speed', tty=tty, speed=2400)

    # The counters, against the emulator's.
    c = counters('%s/lego_ev3_uart/%s/counters' % (DEBUGFS, tty))
    assert c['handshakes'] >= emu.handshakes == 1, c
    assert c['registered'] == 1 and c['lost'] == 1, c
    assert c['resyncs'] >= 1 and c['tx_ack'] == 1 and c['tx_select'] >= 1, c
    assert c['tx_nack'] >= 1 and c['tx_errors'] == 0, c
    assert 0 < c['data_msgs'] <= emu.frames_sent, (c, emu.frames_sent)
    assert c['data_msgs'] == len(trace.events('ev3_uart_rx', tty=tty, msg='DATA'))
    assert c['info_msgs'] == len(hsmsgs), (c, len(hsmsgs))
    assert c['tx_nack'] == len(trace.events('ev3_uart_tx', tty=tty, msg='NACK'))


@pytest.mark.parametrize('kind, mode, quirk, hdr_mode', [
    ('us', 'US-DC-IN', 'us-dc-in-quirk', 5),     # tagged mode 5, taken as 6
    ('color', 'RGB-RAW', 'rgb-raw-quirk', 4),    # checksum not checked
])
def test_ev3_quirks_in_accept(ev3_module, kind, mode, quirk, hdr_mode):
    """A DATA message a quirk let through says which in accept: what a bug
    report needs to tell a quirk from a sensor the parser got wrong."""
    trace = Trace('lego_ev3_uart')
    try:
        with pty_sensor() as (tty, attach):
            _, path = attach(kind)
            check_quirk(trace, tty, path, mode, quirk, hdr_mode)
    finally:
        trace.stop()


def check_quirk(trace, tty, path, mode, quirk, hdr_mode):
    import ev3
    num = ev3.read_attr(path, 'modes').split().index(mode)
    assert not trace.events('ev3_uart_rx', tty=tty, accept=quirk)
    ev3.write_attr(path, 'mode', mode)
    got = trace.wait('ev3_uart_rx', timeout=10, tty=tty, msg='DATA', accept=quirk)
    assert got, 'no DATA with accept=%s in %s' % (quirk, mode)
    for f in (f for _, f in got):
        assert f['arg'] == str(num), f
        assert int(f['hdr'], 16) & 0xc7 == 0xc0 | hdr_mode, f
    # Nothing else is marked: every other DATA passed its checksum.
    other = {f['accept'] for _, f in trace.events('ev3_uart_rx', tty=tty, msg='DATA')
             if f['arg'] != str(num)}
    assert other <= {'checksum'}, other


def test_lego_sensors_trace(ev3_module):
    """lego-sensors --trace=TTY prints a handshake decoded, as it happens."""
    import signal
    tool = os.path.join(os.environ['LEGO_BUILD'], 'tools/lego-sensors')
    write(tracefs() + '/trace', '')
    with pty_sensor() as (tty, attach):
        proc = subprocess.Popen([tool, '--trace=' + tty], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            assert wait_for(lambda: open(tracefs() + '/events/lego_ev3_uart/enable').read()
                            .strip() == '1', 5.0), 'lego-sensors --trace did not enable the events'
            _, path = attach('color')
            # The driver traces the registration once the IIO device is
            # registered too, which comes after the class device that
            # attach() waits for (seconds later on a loaded debug kernel).
            assert iio_device('lego-ev3-color', timeout=20), 'no IIO device'
            time.sleep(0.5)
        finally:
            proc.send_signal(signal.SIGINT)
            out, errs = proc.communicate(timeout=10)
    assert proc.returncode == 0, errs
    lines = [line.split(None, 2)[2] for line in out.splitlines() if line.split()[1:2] == [tty]]
    for want in ('== SYNC -> INFO: TYPE message', '<- TYPE 29', '<- MODES (4 bytes)',
                 '<- SPEED (6 bytes)', '<- INFO mode 0 FORMAT (7 bytes)',
                 '<- ACK: handshake complete, 6 modes', '-> ACK', '== 57600 baud',
                 '== sensor registered: lego-ev3-color as %s' % os.path.basename(path)):
        assert want in lines, (want, out)
    assert any(line.startswith('<- DATA mode 0') for line in lines), out
    assert any(line == '-> NACK' for line in lines), out
    with open(tracefs() + '/events/lego_ev3_uart/enable') as f:
        assert f.read().strip() == '0', 'the events were left enabled'


@pytest.fixture(scope='module')
def brick_dev(brick):
    """The brick and its USB device's name (e.g. 1-1)."""
    return brick, os.path.basename(os.path.realpath(brick.interface() + '/..'))


def test_nxt_transaction(brick_dev):
    brick, dev = brick_dev
    fd = brick.open()
    try:
        # The reader's start-up drain is over before the telegrams go.
        nxt.ok(fd, 'GET_BATTERY_LEVEL')
        path = '%s/lego_nxt/%s/counters' % (DEBUGFS, dev)
        before = counters(path)
        commands = brick.emu.commands
        trace = Trace('lego_nxt_usb')
        try:
            for _ in range(3):
                out = nxt.ok(fd, 'GET_BATTERY_LEVEL')
                assert out['millivolts'] == brick.fw.battery_mv
            err, reply = nxt.transact(fd, b'\x01\x88')          # GetFirmwareVersion
            assert err == 0 and reply[:3] == b'\x02\x88\x00', (err, reply)
            tx = trace.events('nxt_usb_tx', dev=dev)
            rx = trace.events('nxt_usb_rx', dev=dev)
            done = trace.events('nxt_usb_done', dev=dev)
        finally:
            trace.stop()
        after = counters(path)
        commands = brick.emu.commands - commands
    finally:
        os.close(fd)

    # GetBatteryLevel is direct command 0x0b; the reply has type 0x02.
    assert [(f['type'], f['opcode'], f['len']) for _, f in tx] == \
        [('0x00', '0x0b', '2')] * 3 + [('0x01', '0x88', '2')], tx
    assert all(f['ret'] == '0' for _, f in tx), tx
    assert [(f['type'], f['opcode'], f['status']) for _, f in rx] == \
        [('0x02', '0x0b', '0x00')] * 3 + [('0x02', '0x88', '0x00')], rx
    assert [f['err'] for _, f in done] == ['0'] * 4, done
    # Each reply names the transaction its telegram started: the open file's.
    assert len({f['xfer'] for _, f in tx + rx + done}) == 1
    assert [f['len'] for _, f in rx][:3] == ['5'] * 3, rx

    delta = {k: after[k] - before[k] for k in after}
    assert delta['telegrams'] == 4 == commands and delta['replies'] == 4, (delta, commands)
    assert delta['transactions'] == 4 and delta['ok'] == 4, delta
    assert not any(v for k, v in delta.items() if k.startswith('err_')), delta


def test_nxt_timeout_is_traced(brick_dev):
    """A reply that never comes: the timeout, the transaction's -ETIMEDOUT
    and the drain of the late reply are traced and counted."""
    brick, dev = brick_dev
    fd = brick.open()
    path = '%s/lego_nxt/%s/counters' % (DEBUGFS, dev)
    try:
        nxt.ok(fd, 'GET_BATTERY_LEVEL')
        # DeleteUserFlash takes the brick about a second: its reply comes
        # after the 200 ms timeout, and is drained.
        assert nxt.set_timeout(fd, 200) == 0
        before = counters(path)
        trace = Trace('lego_nxt_usb')
        try:
            err, _ = nxt.transact(fd, b'\x01\xa0')
            assert err == errno.ETIMEDOUT, err
            to = trace.wait('nxt_usb_timeout', dev=dev, opcode='0xa0')
            assert to and to[0][1]['what'] == 'no reply', to
            assert trace.events('nxt_usb_done', dev=dev, opcode='0xa0', err=-errno.ETIMEDOUT)
            assert trace.events('nxt_usb_drain', dev=dev, orphan=1, orphan_op='0xa0')
            drop = trace.wait('nxt_usb_drop', timeout=3.0, dev=dev, why='drained',
                              opcode='0xa0', drain_end=1)
            assert drop and drop[0][1]['type'] == '0x02', drop
        finally:
            trace.stop()
        after = counters(path)
    finally:
        os.close(fd)
    assert after['err_timedout'] - before['err_timedout'] == 1
    assert after['drains'] > before['drains']
    assert after['drained'] > before['drained']


def test_nxtctl_trace(brick_dev):
    """nxtctl trace USBDEV prints a transaction decoded, as it happens."""
    import signal
    brick, dev = brick_dev
    tool = os.path.join(os.environ['LEGO_BUILD'], 'tools/nxtctl')
    enable = tracefs() + '/events/lego_nxt_usb/enable'
    fd = brick.open()
    try:
        nxt.ok(fd, 'GET_BATTERY_LEVEL')
        # trace_pipe gives what the buffer holds first: the earlier tests'.
        write(tracefs() + '/trace', '')
        proc = subprocess.Popen([tool, 'trace', dev], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            assert wait_for(lambda: open(enable).read().strip() == '1', 5.0), \
                'nxtctl trace did not enable the events'
            nxt.ok(fd, 'GET_BATTERY_LEVEL')
            err, _ = nxt.transact(fd, b'\x01\x88')
            assert err == 0
            time.sleep(0.5)
        finally:
            proc.send_signal(signal.SIGINT)
            out, errs = proc.communicate(timeout=10)
    finally:
        os.close(fd)
    assert proc.returncode == 0, errs
    lines = [line.split(None, 2)[2] for line in out.splitlines() if line.split()[1:2] == [dev]]
    assert lines[:6] == ['-> GetBatteryLevel (direct, 2 bytes)',
                         '<- GetBatteryLevel reply, 5 bytes',
                         '== GetBatteryLevel done',
                         '-> GetFirmwareVersion (system, 2 bytes)',
                         '<- GetFirmwareVersion reply, 7 bytes',
                         '== GetFirmwareVersion done'], out
    with open(enable) as f:
        assert f.read().strip() == '0', 'the events were left enabled'
