#!/usr/bin/env python3
"""NXT over Bluetooth benchmark (issue 31), run inside the test VM.

    python3 tests/bench/guest/nxt_bt_bench.py --out DIR [--quick] [--seconds S]
        [--runs R] [--clients 1,4,8] [--client PATH]

Two virtual controllers (tests/guest/btlink.py: btvirt on the kernel's
vhci) and the emulated brick (tests/emulator/nxt_serial_brick.py) an
RFCOMM server on channel 1 of one of them, with the Bluetooth pacing of
shared/research/nxt.md: each reply leaves 30 ms after its command, and a
command that comes less than 30 ms after the last reply is dropped (LEGO's
developer kit asks hosts for that gap). It answers GetBatteryLevel (00 0B)
through

  dev         `nxtctl connect` to the brick: lego_nxt_serial on an RFCOMM
              tty, /dev/nxtN; the C client of nxt_bench.py (liblegonxt +
              NXT_IOC_TRANSACT, one open file per thread);
  nxt-python  nxt-python 3.5.1's own Bluetooth backend
              (nxt.backend.bluetooth) on an RFCOMM socket of its own to the
              same brick, threads sharing one nxt.brick.Brick. The backend
              wants PyBluez, which does not build any more; all it takes
              from it is an RFCOMM stream socket, which the standard
              library's socket module gives the same way (AF_BLUETOOTH,
              BTPROTO_RFCOMM), so that is what it is handed.

nxt-python keeps no gap after a reply: against the brick that drops what
comes too soon, it loses commands (it has no timeout; one of 2 s is set on
its socket to count them). Its rate is therefore measured against the same
brick with the drop turned off, and its losses on a run of its own with the
drop on. The ceilings: one transaction per latency + gap (16.7/s) with the
gap, per latency (33.3/s) without.

1, 4 and 8 clients, S seconds each (5, or 2 with --quick), in R rounds (3,
or 2 with --quick), both paths at one client count back to back. Every
reply is checked (opcode, status 0, the emulator's millivolts). Writes
DIR/nxt_bt.json in the format of tests/bench/report.py; exits 0 when the
measurements ran, whatever the figures.
"""
import argparse
import json
import os
import socket
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
TOP = os.path.abspath(os.path.join(HERE, '..', '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'guest'))
sys.path.insert(0, HERE)
import btlink                            # noqa: E402  tests/guest/btlink.py
import nxt_bench as nb                   # noqa: E402  the USB bench: its client and helpers
import nxtdev                            # noqa: E402
import nxt_serial_brick as sb            # noqa: E402  (btlink put tests/emulator on the path)

LATENCY, GAP = sb.LATENCY, sb.GAP
CEILING_GAP = 1 / (LATENCY + GAP)
CEILING_NO_GAP = 1 / LATENCY
LOSS_SOCKET_TIMEOUT = 2.0
RUNS = 3


def log(msg):
    print('nxt_bt_bench: %s' % msg, file=sys.stderr, flush=True)


class Brick:
    """The emulated brick's RFCOMM server for one connection; `gap` is the
    brick's drop of commands that come too soon (seconds, 0: off)."""

    def __init__(self, radio, fw, gap):
        self.srv = btlink.BrickServer(radio.brick, fw, latency=LATENCY, gap=gap)

    def wait(self):
        if not self.srv.accepted.wait(10):
            raise nb.SetupError('the brick accepted no connection')
        return self.srv.brick

    def close(self):
        self.srv.close()


def run_dev(args, radio, fw, n):
    brick = Brick(radio, fw, GAP)
    try:
        p = nxtdev.nxtctl('connect', radio.brick, timeout=60)
        if p.returncode != 0:
            raise nb.SetupError('nxtctl connect: %d %s' % (p.returncode, p.stderr.strip()))
        node = p.stdout.strip()
        sbrick = brick.wait()
        try:
            nb.run_client(args.client, 'dev', node, 1, 0.5)         # warm up
            dropped = len(sbrick.dropped)
            r = nb.run_client(args.client, 'dev', node, n, args.seconds)
            r['dropped'] = len(sbrick.dropped) - dropped
        finally:
            nxtdev.nxtctl('-d', node, 'disconnect', timeout=30)
        return r
    finally:
        brick.close()


def run_nxt_python(radio, fw, n, seconds, gap, timeout=None):
    """nxt_python_measure() in a process of its own, against a brick that
    drops commands `gap` s after a reply (0: none); its result, with the
    commands the brick dropped."""
    brick = Brick(radio, fw, gap)
    try:
        extra = ['--host', radio.brick] + (['--timeout', str(timeout)] if timeout else [])
        r = nb.run_nxt_python_process(n, seconds, __file__, extra)
        r['dropped'] = len(brick.wait().dropped)     # it connected: accepted
        return r
    finally:
        brick.close()


class RfcommShim:
    """What nxt.backend.bluetooth takes from PyBluez, from the standard
    library: an RFCOMM stream socket and the error it raises."""
    BluetoothError = OSError

    def __init__(self):
        # Looked up here: a Python built without Bluetooth lacks them.
        self.RFCOMM = socket.BTPROTO_RFCOMM

    @staticmethod
    def BluetoothSocket(proto):
        return socket.socket(socket.AF_BLUETOOTH, socket.SOCK_STREAM, proto)


def nxt_python_measure(host, clients, seconds, timeout):
    """In its own process: nxt-python's Bluetooth backend, `clients`
    threads sharing one Brick; the result as nxt_bench.run_nxt_python()'s."""
    import nxt.backend.bluetooth as bt
    b = next(bt.Backend(RfcommShim()).find(host=host))
    if timeout:
        b._sock._sock.settimeout(timeout)
    try:
        return nb.threaded_battery_levels(b, clients, seconds)
    finally:
        b.close()


def measure(args):
    from conftest import loaded, module_path
    for name in ('lego_nxt', 'lego_nxt_serial'):
        if not loaded(name):
            subprocess.run(['insmod', module_path(name)], check=True)
    radio = btlink.Radio()
    results = {}
    try:
        fw = sb.nxt_brick.Firmware(name='BT-NXT')
        for rnd in range(1, args.runs + 1):
            for n in args.clients:
                r = run_dev(args, radio, fw, n)
                results.setdefault(('dev', n), []).append(r)
                log('round %d: dev %d: %s' % (rnd, n, r))
                r = run_nxt_python(radio, fw, n, args.seconds, 0)
                results.setdefault(('nxt-python', n), []).append(r)
                log('round %d: nxt-python %d: %s' % (rnd, n, r))
            r = run_nxt_python(radio, fw, 1, args.seconds, GAP, LOSS_SOCKET_TIMEOUT)
            results.setdefault(('nxt-python-gap', 1), []).append(r)
            log('round %d: nxt-python against the gap: %s' % (rnd, r))
    finally:
        radio.stop()
    return results


LABELS = {'dev': '/dev/nxtN over Bluetooth (lego_nxt_serial, liblegonxt + NXT_IOC_TRANSACT, C)',
          'nxt-python': 'nxt-python 3.5.1 Bluetooth backend, brick without the gap'}


def figures(results, args):
    figs = []
    plural = lambda n: 's' * (n > 1)
    for n in args.clients:
        py = nb.summary(results[('nxt-python', n)])
        for path in ('dev', 'nxt-python'):
            runs = results[(path, n)]
            r = nb.summary(runs)
            dropped = sum(x['dropped'] for x in runs)
            detail = ('%d rounds of %.1f s: %d transactions, %d errors%s; rate %s '
                      'transactions/s, p50 %s ms, p99 %s ms (median, min to max of the '
                      'rounds); max %.2f ms; %d commands the brick dropped for coming '
                      'less than %d ms after a reply; the client took %.0f us of CPU per '
                      'transaction (user and system, median)'
                      % (r['rounds'], args.seconds, r['ok'], r['errors'],
                         ' (first: %s)' % r['first_error'] if r['errors'] else '',
                         nb.spread_text([x['tps'] for x in runs]),
                         nb.spread_text([x['p50_us'] / 1e3 for x in runs], '%.2f'),
                         nb.spread_text([x['p99_us'] / 1e3 for x in runs], '%.2f'),
                         r['max_us_max'] / 1e3, dropped, GAP * 1000, r['cpu_us']))
            if path == 'dev':
                ceiling = ('ceiling: one transaction per %d ms reply latency + %d ms gap'
                           % (LATENCY * 1000, GAP * 1000), round(CEILING_GAP, 1))
            else:
                ceiling = ('ceiling: one transaction per %d ms reply latency (no gap)'
                           % (LATENCY * 1000), round(CEILING_NO_GAP, 1))
            base = 'NXT over Bluetooth, GetBatteryLevel, %s, %d client%s' % (
                LABELS[path], n, plural(n))
            figs.append({'name': base + ': rate', 'value': round(r['tps'], 1),
                         'unit': 'transactions/s', 'reference': ceiling[0],
                         'reference_value': ceiling[1], 'target': None, 'met': None,
                         'detail': detail})
            figs.append({'name': base + ': latency p99', 'value': round(r['p99_us'] / 1e3, 2),
                         'unit': 'ms',
                         'reference': 'nxt-python Bluetooth backend p99, %d client%s'
                         % (n, plural(n)) if path == 'dev' else
                         'reply latency of the emulated brick',
                         'reference_value': round(py['p99_us'] / 1e3, 2) if path == 'dev'
                         else LATENCY * 1000,
                         'target': None, 'met': None, 'detail': detail})
    gap = results[('nxt-python-gap', 1)]
    sent = sum(x['ok'] + x['errors'] for x in gap)
    lost = sum(x['errors'] for x in gap)
    figs.append({
        'name': 'NXT over Bluetooth, nxt-python 3.5.1 Bluetooth backend against the brick '
                'that drops commands within %d ms of a reply: commands lost' % (GAP * 1000),
        'value': lost, 'unit': 'commands', 'reference': 'commands sent',
        'reference_value': sent, 'target': None, 'met': None,
        'detail': '%d rounds of %.1f s, 1 client, a %.0f s timeout on its socket (it has '
                  'none of its own: each loss would hang it); the brick dropped %d commands; '
                  'first error: %s'
                  % (len(gap), args.seconds, LOSS_SOCKET_TIMEOUT,
                     sum(x['dropped'] for x in gap),
                     next((x['first_error'] for x in gap if x['errors']), 'none'))})
    dev_runs = [r for (p, _), runs in results.items() if p == 'dev' for r in runs]
    errors = sum(r['errors'] for r in dev_runs)
    dropped = sum(r['dropped'] for r in dev_runs)
    figs.append({'name': 'NXT over Bluetooth: /dev/nxtN replies failed or mismatched, '
                         'commands the brick dropped', 'value': errors + dropped,
                 'unit': 'transactions', 'reference': 'all /dev/nxtN transactions of the run',
                 'reference_value': sum(r['ok'] + r['errors'] for r in dev_runs),
                 'target': '0', 'met': errors + dropped == 0,
                 'detail': '%d failed or mismatched replies, %d commands dropped by the brick '
                           'for coming too soon after a reply' % (errors, dropped)})
    return figs


def data_notes(results, args):
    """What the figures say, worked out from them."""
    notes = []
    plural = lambda n: 's' * (n > 1)
    parts = []
    for n in args.clients:
        rl = [a['tps'] / b['tps'] if b['tps'] else 0.0
              for a, b in zip(results[('dev', n)], results[('nxt-python', n)])]
        dev = nb.summary(results[('dev', n)])
        parts.append('%d client%s: %s; /dev/nxtN at %.0f%% of its ceiling'
                     % (n, plural(n), nb.lead_text(rl, '/dev/nxtN', 'nxt-python'),
                        dev['tps'] / CEILING_GAP * 100))
    notes.append('Rate ratios, median of the rounds (min to max), /dev/nxtN keeping the '
                 'gap against nxt-python on a brick that needs none: %s.' % '; '.join(parts))
    gap = results[('nxt-python-gap', 1)]
    sent = sum(x['ok'] + x['errors'] for x in gap)
    lost = sum(x['errors'] for x in gap)
    notes.append('Against the brick that drops commands within %d ms of a reply, nxt-python '
                 'lost %d of its %d commands (%.0f%%); /dev/nxtN lost %d.'
                 % (GAP * 1000, lost, sent, lost / sent * 100 if sent else 0,
                    sum(r['dropped'] + r['errors'] for (p, _), runs in results.items()
                        if p == 'dev' for r in runs)))
    return notes


def main():
    ap = nb.arguments(__doc__, 'nxt_bt.json', RUNS)
    ap.add_argument('--host', help=argparse.SUPPRESS)
    ap.add_argument('--timeout', type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.nxt_python:
        print(json.dumps(nxt_python_measure(args.host, args.nxt_python, args.seconds or 5.0,
                                            args.timeout)))
        return
    nb.settle(ap, args, 'nxt_bt_bench', RUNS)
    started = time.monotonic()
    try:
        results = measure(args)
    except (nb.SetupError, OSError, RuntimeError, subprocess.SubprocessError) as e:
        sys.exit('nxt_bt_bench: %s' % e)
    out = {
        'section': 'NXT over Bluetooth: /dev/nxtN and nxt-python over a virtual link',
        'figures': figures(results, args),
        'notes': data_notes(results, args) + [
            'Two virtual controllers in the guest (btvirt on the kernel\'s vhci, the kernel\'s '
            'own Bluetooth and RFCOMM stack); the emulated brick (tests/emulator/'
            'nxt_serial_brick.py) an RFCOMM server on channel 1 of one, answering '
            'GetBatteryLevel (00 0B) %d ms after each command and dropping a command that '
            'comes less than %d ms after its last reply (shared/research/nxt.md: about 30 ms '
            'asked between a reply and the next command; users measure 100-150 ms a round '
            'trip on real bricks, which this emulator does not model).'
            % (LATENCY * 1000, GAP * 1000),
            '/dev/nxtN: `nxtctl connect` for each measurement (lego_nxt_serial on the RFCOMM '
            'tty, which waits 30 ms after each reply before the next command); the C client '
            'of the USB bench, one open file per client thread. nxt-python 3.5.1: its '
            'Bluetooth backend (nxt.backend.bluetooth) on an RFCOMM socket of the standard '
            'library (it takes PyBluez\'s, which does not build any more), threads sharing '
            'one nxt.brick.Brick, in a process of its own for each measurement; it sends the '
            'next command as soon as it has a reply, so its rate is measured against the '
            'brick with the drop off, and its losses on a run with it on.',
            'Every reply checked: opcode, status 0 and %d mV. %d rounds; in each, for %s '
            'clients, both paths for %.1f s each, back to back; figures are the median of '
            'the rounds. Whole run %.0f s, guest on %s, under QEMU TCG.'
            % (nb.BATTERY_MV, args.runs, '/'.join(str(n) for n in args.clients),
               args.seconds, time.monotonic() - started, nb.guest_cpus()),
        ],
    }
    log('wrote %s' % nb.write_section(args.out, 'nxt_bt.json', out))


if __name__ == '__main__':
    main()
