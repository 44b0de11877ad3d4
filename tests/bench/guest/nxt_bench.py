#!/usr/bin/env python3
"""NXT benchmark (issue 6, figure 5), run inside the test VM.

    python3 tests/bench/guest/nxt_bench.py --out DIR [--quick] [--seconds S]
        [--client PATH] [--clients 1,4,8]

One emulated brick (tests/emulator/nxt_brick.py, in its own process, on
dummy_udc.0) answers GetBatteryLevel (00 0B) as fast as it can, through

  dev        lego_nxt_usb's /dev/nxtN: the C client, one open file per
             thread, the typed ioctl NXT_IOC_GET_BATTERY_LEVEL;
  libusb     (driver unbound) the C client over libusb-1.0, one claimed
             interface shared by the threads under a mutex (write + read);
  nxt-python (driver unbound) nxt-python 3.5.1's stock usb backend
             (pyusb/libusb): threads sharing one nxt.brick.Brick, whose own
             lock serialises each command and reply,

with 1, 4 and 8 concurrent clients, for S seconds each (10, or 3 with
--quick). Every reply is checked (opcode, status 0, the emulator's
millivolts); failures are counted as errors. The C client is
.build/bench/nxt_bench_client (make -C tests/bench/nxt, on the host).

Writes DIR/nxt.json in the format of tests/bench/report.py. Exits 0 when
the measurements ran (whatever the figures), 1 on a setup error.
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import threading
import time

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'guest'))
import nxtdev                            # noqa: E402  tests/guest/nxtdev.py

SERIAL = '001653B3E4C5'
HOST = '00:16:53:B3:E4:C5'
BATTERY_MV = 7823                        # the emulator's default
EMULATOR = os.path.join(TOP, 'tests', 'emulator', 'nxt_brick.py')
DEFAULT_CLIENT = os.path.join(os.environ.get('LEGO_BUILD_DIR', os.path.join(TOP, '.build')),
                              'bench', 'nxt_bench_client')
# The firmware's comm module handles at most one USB command per 1 ms
# scheduler pass (shared/research/nxt.md 1.2): the physical ceiling.
FIRMWARE_CEILING_TPS = 1000


class SetupError(Exception):
    pass


def log(msg):
    print('nxt_bench: %s' % msg, file=sys.stderr, flush=True)


def percentile(sorted_values, p):
    if not sorted_values:
        return 0
    i = int(round(p / 100.0 * (len(sorted_values) - 1)))
    return sorted_values[min(i, len(sorted_values) - 1)]


class Emulator:
    """nxt_brick.py in its own process (so that its GIL is its own)."""

    def __init__(self, extra_args=()):
        self.proc = subprocess.Popen(
            [sys.executable, EMULATOR, '--udc', 'dummy_udc.0', '--serial', SERIAL]
            + list(extra_args), stdout=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        if 'configured' not in line:
            self.stop()
            raise SetupError('the emulated brick did not come up: %r' % line)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def run_client(client, mode, target, clients, seconds):
    cmd = [client, mode, target, str(clients), str(seconds), str(BATTERY_MV)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=seconds + 60)
    if res.returncode != 0:
        raise SetupError('%s failed (%d): %s' % (' '.join(cmd), res.returncode,
                                                  res.stderr.strip()))
    return json.loads(res.stdout)


def run_nxt_python(clients, seconds):
    import nxt.locator
    import usb.util
    b = nxt.locator.find(backends=['usb'], config=None, host=HOST)
    dev = b._sock._dev
    try:
        for _ in range(3):                  # warm up
            b.get_battery_level()
        lat = [[] for _ in range(clients)]
        errors = [0] * clients
        first = ['']
        barrier = threading.Barrier(clients + 1)
        stop_at = [0.0]

        def worker(i):
            barrier.wait()
            while True:
                t0 = time.perf_counter()
                if t0 >= stop_at[0]:
                    return
                try:
                    mv = b.get_battery_level()
                    ok = mv == BATTERY_MV
                    why = '%r mV' % mv
                except Exception as e:      # any failure is an error of the run
                    ok, why = False, '%s: %s' % (type(e).__name__, e)
                t1 = time.perf_counter()
                if ok:
                    lat[i].append(t1 - t0)
                else:
                    errors[i] += 1
                    first[0] = first[0] or why

        threads = [threading.Thread(target=worker, args=(i,)) for i in range(clients)]
        for t in threads:
            t.start()
        start = time.perf_counter()
        stop_at[0] = start + seconds
        barrier.wait()
        for t in threads:
            t.join()
        elapsed = time.perf_counter() - start
    finally:
        b.close()
        usb.util.dispose_resources(dev)
    all_lat = sorted(x for li in lat for x in li)
    return {'clients': clients, 'ok': len(all_lat), 'errors': sum(errors),
            'seconds': round(elapsed, 3), 'tps': round(len(all_lat) / elapsed, 2),
            'p50_us': round(percentile(all_lat, 50) * 1e6),
            'p99_us': round(percentile(all_lat, 99) * 1e6),
            'max_us': round(all_lat[-1] * 1e6) if all_lat else 0, 'first_error': first[0]}


def clocksource():
    """The guest's clocksource and whether high-resolution timers are on."""
    try:
        with open('/sys/devices/system/clocksource/clocksource0/current_clocksource') as f:
            cs = f.read().strip()
        with open('/proc/timer_list') as f:
            res = next((int(line.split()[1]) for line in f if '.resolution:' in line), 0)
    except (OSError, ValueError, IndexError):
        return 'unknown'
    return '%s, timer resolution %s' % (cs, '%d ns' % res if res < 1000 else '%g ms' % (res / 1e6))


def guest_cpus():
    """"one CPU" or "N CPUs": the CPUs the guest runs on."""
    n = len(os.sched_getaffinity(0))
    return 'one CPU' if n == 1 else '%d CPUs' % n


def wait_for(cond, timeout, what):
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise SetupError(what)
        time.sleep(0.05)


def measure(args):
    results = {}                        # (path, clients) -> result
    nxtdev.load_driver()
    emu = Emulator()
    try:
        node = nxtdev.node_of(SERIAL)
        if not node:
            raise SetupError('no /dev/nxtN for the emulated brick')
        log('brick at %s' % node)
        run_client(args.client, 'dev', node, 1, 0.5)      # warm up
        for n in args.clients:
            results[('dev', n)] = r = run_client(args.client, 'dev', node, n, args.seconds)
            log('dev %d: %s' % (n, r))

        intf = nxtdev.interface_of(SERIAL)
        name = os.path.basename(intf)
        with open(nxtdev.DRIVER + '/unbind', 'w') as f:
            f.write(name)
        try:
            wait_for(lambda: not os.path.exists(node), 5, 'the node outlived the unbind')
            for n in args.clients:
                results[('libusb', n)] = r = run_client(args.client, 'libusb', '0694:0002',
                                                        n, args.seconds)
                log('libusb %d: %s' % (n, r))
            for n in args.clients:
                results[('nxt-python', n)] = r = run_nxt_python(n, args.seconds)
                log('nxt-python %d: %s' % (n, r))
        finally:
            with open(nxtdev.DRIVER + '/bind', 'w') as f:
                f.write(name)
    finally:
        emu.stop()
    return results


LABELS = {
    'dev': '/dev/nxtN (typed ioctl, C)',
    'libusb': 'C libusb-1.0 client',
    'nxt-python': 'nxt-python 3.5.1 (pyusb/libusb)',
}


def figures(results, args):
    figs = []
    for n in args.clients:
        ref = results[('libusb', n)]
        plural = 's' * (n > 1)
        for path in ('dev', 'nxt-python', 'libusb'):
            r = results[(path, n)]
            detail = ('%d transactions in %.1f s, %d errors%s; p50 %.2f ms, p99 %.2f ms, '
                      'max %.2f ms' % (r['ok'], r['seconds'], r['errors'],
                                       ' (first: %s)' % r['first_error'] if r['errors'] else '',
                                       r['p50_us'] / 1e3, r['p99_us'] / 1e3, r['max_us'] / 1e3))
            if path == 'libusb':
                reference, ref_tps, ref_p50 = ('firmware ceiling: one command per 1 ms tick',
                                               FIRMWARE_CEILING_TPS, None)
            else:
                reference, ref_tps, ref_p50 = ('C libusb client, %d client%s' % (n, plural),
                                               ref['tps'], ref['p50_us'] / 1e3)
            base = 'NXT GetBatteryLevel, %s, %d client%s' % (LABELS[path], n, plural)
            figs.append({'name': base + ': rate', 'value': r['tps'], 'unit': 'transactions/s',
                         'reference': reference, 'reference_value': ref_tps,
                         'target': None, 'met': None, 'detail': detail})
            figs.append({'name': base + ': latency p50', 'value': round(r['p50_us'] / 1e3, 3),
                         'unit': 'ms', 'reference': reference if ref_p50 is not None
                         else 'real brick: aNXT waits 6 ms per direct command',
                         'reference_value': ref_p50 if ref_p50 is not None else 6,
                         'target': None, 'met': None, 'detail': detail})
            figs.append({'name': base + ': latency p99', 'value': round(r['p99_us'] / 1e3, 3),
                         'unit': 'ms',
                         'reference': 'C libusb client p99, %d client%s' % (n, plural),
                         'reference_value': round(ref['p99_us'] / 1e3, 3),
                         'target': None, 'met': None, 'detail': detail})
    errors = sum(r['errors'] for r in results.values())
    total = sum(r['ok'] + r['errors'] for r in results.values())
    figs.append({'name': 'NXT benchmark: failed or mismatched replies', 'value': errors,
                 'unit': 'transactions', 'reference': 'all transactions of the run',
                 'reference_value': total, 'target': '0', 'met': errors == 0,
                 'detail': '; '.join('%s/%d: %s' % (p, n, r['first_error'])
                                     for (p, n), r in sorted(results.items()) if r['errors'])
                 or 'every reply had the right opcode, status 0 and %d mV' % BATTERY_MV})
    return figs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', required=True, help='directory for nxt.json')
    ap.add_argument('--quick', action='store_true', help='short run (3 s per measurement)')
    ap.add_argument('--seconds', type=float, help='seconds per measurement (default 10)')
    ap.add_argument('--clients', default='1,4,8', help='concurrent clients (default 1,4,8)')
    ap.add_argument('--client', default=DEFAULT_CLIENT, help='the C client binary')
    args = ap.parse_args()
    args.seconds = args.seconds or (3.0 if args.quick else 10.0)
    args.clients = [int(c) for c in args.clients.split(',')]
    if not os.access(args.client, os.X_OK):
        sys.exit('nxt_bench: %s missing: build it on the host with make -C tests/bench/nxt'
                 % args.client)
    if os.environ.get('LEGO_IN_VM') != '1':
        sys.exit('nxt_bench: run it inside the test VM (tests/vm-run)')
    os.makedirs(args.out, exist_ok=True)
    started = time.monotonic()
    try:
        results = measure(args)
    except (SetupError, OSError, subprocess.SubprocessError) as e:
        sys.exit('nxt_bench: %s' % e)
    clock = clocksource()
    out = {
        'section': 'NXT: transactions through /dev/nxtN, nxt-python and libusb',
        'figures': figures(results, args),
        'notes': [
            'One emulated brick (tests/emulator/nxt_brick.py over raw-gadget on dummy_hcd, '
            'in its own process) answers GetBatteryLevel (00 0B) with no modelled firmware '
            'delay: the real brick handles at most one command per 1 ms scheduler tick, and '
            'aNXT waits 6 ms per direct command; the rates here are the emulated bus, the '
            'emulator and each host stack, under QEMU TCG with %s.' % guest_cpus(),
            '/dev/nxtN: the C client, one open file per client thread, the typed ioctl '
            'NXT_IOC_GET_BATTERY_LEVEL (the driver serialises the brick).',
            'libusb: lego_nxt_usb unbound through sysfs; the C client claims interface 0 once '
            'and its threads share the handle, each taking a mutex around bulk OUT 0x01 + '
            'bulk IN 0x82 (NXT replies carry no transaction id).',
            'nxt-python 3.5.1: stock usb backend (pyusb 1.x, libusb-1.0), driver unbound, '
            'threads sharing one nxt.brick.Brick (its lock serialises each command).',
            'Every reply checked: opcode, status 0 and %d mV; %.1f s per measurement; '
            'whole run %.0f s on %s, kernel %s.' % (BATTERY_MV, args.seconds,
                                                      time.monotonic() - started,
                                                      platform.machine(), platform.release()),
            'Guest clocksource: %s.' % clock + (
                ' On refined-jiffies (the TSC rate unknown: vm-run gives it as tsc_early_khz=) '
                'high-resolution timers are off and dummy_hcd\'s 1 ms frame timer, like every '
                'timer, fires on 4 ms jiffies: latencies come in multiples of 4 ms.'
                if 'jiffies' in clock else ''),
        ],
    }
    path = os.path.join(args.out, 'nxt.json')
    with open(path, 'w') as f:
        json.dump(out, f, indent=1)
    log('wrote %s' % path)


if __name__ == '__main__':
    main()
