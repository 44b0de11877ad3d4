#!/usr/bin/env python3
"""NXT benchmark (issue 6, figure 5; issue 19), run inside the test VM.

    python3 tests/bench/guest/nxt_bench.py --out DIR [--quick] [--seconds S]
        [--runs R] [--client PATH] [--clients 1,4,8] [--models fast,tick]

One emulated brick (tests/emulator/nxt_brick.py, in its own process, on
dummy_udc.0) answers GetBatteryLevel (00 0B), through

  dev        lego_nxt_usb's /dev/nxtN: the C client, one open file per
             thread, as a C program on the telegram ABI: liblegonxt builds
             the telegram, NXT_IOC_TRANSACT sends it and returns the reply,
             liblegonxt checks and parses it;
  libusb     (driver unbound) the C client over libusb-1.0, one claimed
             interface shared by the threads under a mutex (write + read);
  nxt-python (driver unbound) nxt-python 3.5.1's stock usb backend
             (pyusb/libusb): threads sharing one nxt.brick.Brick, whose own
             lock serialises each command and reply,

with 1, 4 and 8 concurrent clients, for S seconds each (5, or 2 with
--quick), in R rounds (3, or 2 with --quick): each round runs every path
at every client count once, so that the host's load, which moves the
figures by more than some of their differences, falls on all of them; the
figures are the medians of the rounds, with their min and max. All of it
twice: with the brick as fast as the emulator goes, and with the firmware's
1 ms scheduler tick (--tick-ms 1), against its ceiling of 1000 commands/s.
Every reply is checked (opcode, status 0, the emulator's millivolts);
failures are counted as errors. The C client is
.build/bench/nxt_bench_client (make -C tests/bench/nxt, on the host).

Writes DIR/nxt.json in the format of tests/bench/report.py, with the goals
of issue 19 as targets (/dev/nxtN at least libusb's rate with a lower p99,
and 3 times nxt-python's), reported, never gating anything. Exits 0 when
the measurements ran (whatever the figures), 1 on a setup error.
"""
import argparse
import json
import os
import platform
import resource
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
    """One run of the C client; its result, with the CPU time the client
    process took (user and system: the kernel's path for it included)."""
    cmd = [client, mode, target, str(clients), str(seconds), str(BATTERY_MV)]
    before = cpu_seconds(resource.RUSAGE_CHILDREN)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=seconds + 60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise
    # communicate() has reaped it: its CPU time is in RUSAGE_CHILDREN.
    if proc.returncode != 0:
        raise SetupError('%s failed (%d): %s' % (' '.join(cmd), proc.returncode, err.strip()))
    res = json.loads(out)
    res['cpu_us'] = (cpu_seconds(resource.RUSAGE_CHILDREN) - before) / max(res['ok'], 1) * 1e6
    return res


def cpu_seconds(who):
    ru = resource.getrusage(who)
    return ru.ru_utime + ru.ru_stime


def run_nxt_python_process(clients, seconds, script=__file__, extra=()):
    """run_nxt_python() in a process of its own: pyusb's libusb context,
    kept in a long-lived process, would still list the brick of an emulator
    that has been stopped and started again since (ENODEV). `script`
    --nxt-python N with `extra` options: another benchmark's measurement."""
    cmd = [sys.executable, os.path.abspath(script), '--nxt-python', str(clients),
           '--seconds', str(seconds)] + list(extra)
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=seconds + 120)
    if res.returncode != 0:
        raise SetupError('%s failed (%d): %s' % (' '.join(cmd), res.returncode,
                                                  res.stderr.strip()[-2000:]))
    return json.loads(res.stdout)


def run_nxt_python(clients, seconds):
    import nxt.locator
    import usb.util
    b = nxt.locator.find(backends=['usb'], config=None, host=HOST)
    dev = b._sock._dev
    try:
        for _ in range(3):                  # warm up
            b.get_battery_level()
        return threaded_battery_levels(b, clients, seconds)
    finally:
        b.close()
        usb.util.dispose_resources(dev)


def threaded_battery_levels(b, clients, seconds):
    """`clients` threads calling nxt-python's b.get_battery_level() for
    `seconds`: the result as run_client()'s, every reply checked (an
    exception or another value than BATTERY_MV is an error of the run)."""
    cpu0 = cpu_seconds(resource.RUSAGE_SELF)
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
    cpu = cpu_seconds(resource.RUSAGE_SELF) - cpu0
    all_lat = sorted(x for li in lat for x in li)
    return {'clients': clients, 'ok': len(all_lat), 'errors': sum(errors),
            'seconds': round(elapsed, 3), 'tps': round(len(all_lat) / elapsed, 2),
            'p50_us': round(percentile(all_lat, 50) * 1e6),
            'p99_us': round(percentile(all_lat, 99) * 1e6),
            'max_us': round(all_lat[-1] * 1e6) if all_lat else 0, 'first_error': first[0],
            'cpu_us': cpu / max(len(all_lat), 1) * 1e6}


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


def median(values):
    v = sorted(values)
    n = len(v)
    return v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2


def one_round(args, node, results, model, rnd):
    """One round: every path at every client count, once. The three paths
    at one client count run back to back, so that a change in the host's
    load falls on all of them as much as it can."""
    for n in args.clients:
        r = run_client(args.client, 'dev', node, n, args.seconds)
        results.setdefault((model, 'dev', n), []).append(r)
        log('%s round %d: dev %d: %s' % (model, rnd, n, r))
        intf = nxtdev.interface_of(SERIAL)
        name = os.path.basename(intf)
        with open(nxtdev.DRIVER + '/unbind', 'w') as f:
            f.write(name)
        try:
            wait_for(lambda: not os.path.exists(node), 5, 'the node outlived the unbind')
            r = run_client(args.client, 'libusb', '0694:0002', n, args.seconds)
            results.setdefault((model, 'libusb', n), []).append(r)
            log('%s round %d: libusb %d: %s' % (model, rnd, n, r))
            r = run_nxt_python_process(n, args.seconds)
            results.setdefault((model, 'nxt-python', n), []).append(r)
            log('%s round %d: nxt-python %d: %s' % (model, rnd, n, r))
        finally:
            with open(nxtdev.DRIVER + '/bind', 'w') as f:
                f.write(name)
        node = nxtdev.node_of(SERIAL)
        if not node:
            raise SetupError('no /dev/nxtN after binding the driver again')
        run_client(args.client, 'dev', node, 1, 0.5)      # warm up: open drains 20 ms
    return node


def measure(args):
    results = {}                        # (model, path, clients) -> [result of each round]
    nxtdev.load_driver()
    for model, extra in MODELS:
        if model not in args.models:
            continue
        emu = Emulator(extra)
        try:
            node = nxtdev.node_of(SERIAL)
            if not node:
                raise SetupError('no /dev/nxtN for the emulated brick')
            log('brick (%s) at %s' % (model, node))
            run_client(args.client, 'dev', node, 1, 0.5)      # warm up
            for rnd in range(1, args.runs + 1):
                node = one_round(args, node, results, model, rnd)
        finally:
            emu.stop()
        wait_for(lambda: not nxtdev.interface_of(SERIAL), 10, 'the brick outlived its emulator')
    return results


# The emulated brick's two models: as fast as it goes, and the firmware's
# scheduler (one command per 1 ms tick, shared/research/nxt.md 1.2).
MODELS = (('fast', []), ('tick', ['--tick-ms', '1']))
MODEL_TEXT = {'fast': 'emulated brick as fast as it goes',
              'tick': 'emulated brick with the 1 ms firmware tick'}

LABELS = {
    'dev': '/dev/nxtN (liblegonxt + NXT_IOC_TRANSACT, C)',
    'libusb': 'C libusb-1.0 client',
    'nxt-python': 'nxt-python 3.5.1 (pyusb/libusb)',
}
SHORT = {'dev': '/dev/nxtN', 'libusb': 'libusb', 'nxt-python': 'nxt-python'}


def summary(runs):
    """Median, min and max of each figure over the rounds, plus the totals."""
    out = {'rounds': len(runs), 'ok': sum(r['ok'] for r in runs),
           'errors': sum(r['errors'] for r in runs),
           'first_error': next((r['first_error'] for r in runs if r['errors']), '')}
    for k in ('tps', 'p50_us', 'p99_us', 'max_us', 'cpu_us'):
        vals = [r[k] for r in runs]
        out[k] = median(vals)
        out[k + '_min'], out[k + '_max'] = min(vals), max(vals)
    return out


def ratios(results, model, a, b, n):
    """a's rate over b's, round by round (the rounds ran back to back)."""
    return [ra['tps'] / rb['tps'] if rb['tps'] else 0.0
            for ra, rb in zip(results[(model, a, n)], results[(model, b, n)])]


def spread_text(values, fmt='%.1f'):
    return (fmt + ' (' + fmt + ' to ' + fmt + ')') % (median(values), min(values), max(values))


def figures(results, args):
    figs = []
    plural = lambda n: 's' * (n > 1)
    for model in args.models:
        tag = '' if model == 'fast' else ', 1 ms tick'
        for n in args.clients:
            ref = summary(results[(model, 'libusb', n)])
            for path in ('dev', 'nxt-python', 'libusb'):
                r = summary(results[(model, path, n)])
                detail = ('%d rounds of %.1f s: %d transactions, %d errors%s; rate %s '
                          'transactions/s, p50 %s ms, p99 %s ms (median, min to max of the '
                          'rounds); max %.2f ms; the client took %.0f us of CPU per '
                          'transaction (user and system, median)'
                          % (r['rounds'], args.seconds, r['ok'], r['errors'],
                             ' (first: %s)' % r['first_error'] if r['errors'] else '',
                             spread_text([x['tps'] for x in results[(model, path, n)]]),
                             spread_text([x['p50_us'] / 1e3 for x in results[(model, path, n)]],
                                         '%.2f'),
                             spread_text([x['p99_us'] / 1e3 for x in results[(model, path, n)]],
                                         '%.2f'),
                             r['max_us_max'] / 1e3, r['cpu_us']))
                if path == 'libusb' or model == 'tick':
                    reference, ref_tps = ('firmware ceiling: one command per 1 ms tick',
                                          FIRMWARE_CEILING_TPS)
                else:
                    reference, ref_tps = ('C libusb client, %d client%s' % (n, plural(n)),
                                          ref['tps'])
                base = 'NXT GetBatteryLevel%s, %s, %d client%s' % (tag, LABELS[path], n,
                                                                  plural(n))
                figs.append({'name': base + ': rate', 'value': round(r['tps'], 1),
                             'unit': 'transactions/s', 'reference': reference,
                             'reference_value': ref_tps, 'target': None, 'met': None,
                             'detail': detail})
                figs.append({'name': base + ': latency p50', 'value': round(r['p50_us'] / 1e3, 3),
                             'unit': 'ms', 'reference': 'real brick: aNXT waits 6 ms per '
                             'direct command', 'reference_value': 6,
                             'target': None, 'met': None, 'detail': detail})
                figs.append({'name': base + ': latency p99', 'value': round(r['p99_us'] / 1e3, 3),
                             'unit': 'ms',
                             'reference': 'C libusb client p99, %d client%s' % (n, plural(n)),
                             'reference_value': round(ref['p99_us'] / 1e3, 3),
                             'target': None, 'met': None, 'detail': detail})
        # The goals of issue 19, on the brick as fast as it goes: targets
        # reported, never gating anything.
        for n in args.clients:
            dev = summary(results[(model, 'dev', n)])
            lib = summary(results[(model, 'libusb', n)])
            rl = ratios(results, model, 'dev', 'libusb', n)
            rp = ratios(results, model, 'dev', 'nxt-python', n)
            name = 'NXT%s, %d client%s: /dev/nxtN rate' % (tag, n, plural(n))
            figs.append({
                'name': name + ' over libusb\'s', 'value': round(median(rl), 2), 'unit': 'x',
                'reference': 'C libusb client', 'reference_value': 1.0,
                'target': None if model == 'tick' else 'at least 1.0x, with a lower p99',
                'met': None if model == 'tick' else
                median(rl) >= 1.0 and dev['p99_us'] < lib['p99_us'],
                'detail': 'round by round %s; p99 %.2f ms against %.2f ms (medians)'
                          % (', '.join('%.2f' % x for x in rl), dev['p99_us'] / 1e3,
                             lib['p99_us'] / 1e3)})
            figs.append({
                'name': name + ' over nxt-python\'s', 'value': round(median(rp), 2), 'unit': 'x',
                'reference': 'nxt-python 3.5.1', 'reference_value': 1.0,
                'target': None if model == 'tick' else 'at least 3x',
                'met': None if model == 'tick' else median(rp) >= 3.0,
                'detail': 'round by round %s' % ', '.join('%.2f' % x for x in rp)})
    errors = sum(r['errors'] for runs in results.values() for r in runs)
    total = sum(r['ok'] + r['errors'] for runs in results.values() for r in runs)
    figs.append({'name': 'NXT benchmark: failed or mismatched replies', 'value': errors,
                 'unit': 'transactions', 'reference': 'all transactions of the run',
                 'reference_value': total, 'target': '0', 'met': errors == 0,
                 'detail': '; '.join('%s %s/%d: %s' % (m, p, n, summary(runs)['first_error'])
                                     for (m, p, n), runs in sorted(results.items())
                                     if summary(runs)['errors'])
                 or 'every reply had the right opcode, status 0 and %d mV' % BATTERY_MV})
    return figs


def lead_text(values, name, other):
    """One comparison, claimed only beyond the spread of the rounds."""
    lo, hi, med = min(values), max(values), median(values)
    if lo > 1.0:
        verdict = 'faster than %s in every round' % other
    elif hi < 1.0:
        verdict = 'slower than %s in every round' % other
    else:
        verdict = 'level with %s within the spread of the rounds' % other
    return '%s %.2fx %s (%.2f to %.2f): %s' % (name, med, other, lo, hi, verdict)


def data_notes(results, args):
    """What the figures say, worked out from them (not written by hand)."""
    notes = []
    plural = lambda n: 's' * (n > 1)
    for model in args.models:
        parts = []
        for n in args.clients:
            parts.append('%d client%s: %s; %s' % (
                n, plural(n),
                lead_text(ratios(results, model, 'dev', 'libusb', n), '/dev/nxtN', 'libusb'),
                lead_text(ratios(results, model, 'dev', 'nxt-python', n), '/dev/nxtN',
                          'nxt-python')))
        notes.append('Rate ratios, %s, median of the rounds (min to max): %s.'
                     % (MODEL_TEXT[model], '; '.join(parts)))
    first = args.models[0]
    for n in args.clients:
        dev = summary(results[(first, 'dev', n)])
        lib = summary(results[(first, 'libusb', n)])
        if n == 1:
            continue
        text = ('%d clients, p50 and p99: /dev/nxtN %.1f and %.1f ms, libusb %.1f and %.1f ms; '
                '/dev/nxtN serves the clients in the order they asked, so its p50 is near '
                'clients / rate (%.1f ms).' % (n, dev['p50_us'] / 1e3, dev['p99_us'] / 1e3,
                                               lib['p50_us'] / 1e3, lib['p99_us'] / 1e3,
                                               n / dev['tps'] * 1e3 if dev['tps'] else 0))
        if lib['p50_us'] < dev['p50_us'] and lib['p99_us'] > dev['p99_us']:
            text += (' libusb\'s lower p50 and longer tail: its threads take a mutex in no '
                     'order, and the one that has just let it go often takes it again.')
        notes.append(text)
    cpu = ', '.join('%s %s us' % (SHORT[p], '/'.join(
        '%.0f' % summary(results[(first, p, n)])['cpu_us'] for n in args.clients))
        for p in ('dev', 'libusb', 'nxt-python'))
    notes.append('CPU time of the client process per transaction (user and system, the '
                 'kernel\'s work for its system calls included; the emulated brick\'s and '
                 'dummy_hcd\'s work, which all paths share, not), %s, at %s clients: %s.'
                 % (MODEL_TEXT[first], '/'.join(str(n) for n in args.clients), cpu))
    if 'tick' not in args.models:
        return notes
    tick = [summary(results[('tick', 'dev', n)])['tps'] for n in args.clients]
    notes.append('With the 1 ms tick, /dev/nxtN reaches %s transactions/s at %s clients: '
                 '%s of the firmware\'s ceiling of one command per tick.'
                 % ('/'.join('%.0f' % t for t in tick),
                    '/'.join(str(n) for n in args.clients),
                    '/'.join('%.0f%%' % (t / FIRMWARE_CEILING_TPS * 100) for t in tick)))
    return notes


RUNS = 5


def arguments(doc, out_name, runs):
    """The options the NXT benchmarks share (argparse)."""
    ap = argparse.ArgumentParser(description=doc.split('\n')[0])
    ap.add_argument('--out', help='directory for ' + out_name)
    ap.add_argument('--quick', action='store_true',
                    help='short run (2 rounds of 2 s per measurement)')
    ap.add_argument('--seconds', type=float, help='seconds per measurement (default 5)')
    ap.add_argument('--runs', type=int, help='rounds (default %d)' % runs)
    ap.add_argument('--clients', default='1,4,8', help='concurrent clients (default 1,4,8)')
    ap.add_argument('--client', default=DEFAULT_CLIENT, help='the C client binary')
    ap.add_argument('--nxt-python', type=int, metavar='N', help=argparse.SUPPRESS)
    return ap


def settle(ap, args, prog, runs):
    """The shared options' defaults, and the checks before a run: the C
    client built, inside the VM, the output directory made."""
    if not args.out:
        ap.error('--out is required')
    args.seconds = args.seconds or (2.0 if args.quick else 5.0)
    args.runs = args.runs or (2 if args.quick else runs)
    args.clients = [int(c) for c in args.clients.split(',')]
    if not os.access(args.client, os.X_OK):
        sys.exit('%s: %s missing: build it on the host with make -C tests/bench/nxt'
                 % (prog, args.client))
    if os.environ.get('LEGO_IN_VM') != '1':
        sys.exit('%s: run it inside the test VM (tests/vm-run)' % prog)
    os.makedirs(args.out, exist_ok=True)


def main():
    ap = arguments(__doc__, 'nxt.json', RUNS)
    ap.add_argument('--models', default='fast,tick',
                    help='the emulated brick\'s models to run: fast (as fast as it goes), '
                    'tick (the 1 ms firmware tick); default both')
    args = ap.parse_args()
    if args.nxt_python:
        # One nxt-python measurement, in a process of its own: JSON on stdout.
        print(json.dumps(run_nxt_python(args.nxt_python, args.seconds or 5.0)))
        return
    args.models = [m for m in args.models.split(',') if m]
    if not args.models or set(args.models) - {m for m, _ in MODELS}:
        sys.exit('nxt_bench: --models takes fast and tick')
    settle(ap, args, 'nxt_bench', RUNS)
    started = time.monotonic()
    try:
        results = measure(args)
    except (SetupError, OSError, subprocess.SubprocessError) as e:
        sys.exit('nxt_bench: %s' % e)
    clock = clocksource()
    out = {
        'section': 'NXT: transactions through /dev/nxtN, nxt-python and libusb',
        'figures': figures(results, args),
        'notes': data_notes(results, args) + [
            'One emulated brick (tests/emulator/nxt_brick.py over raw-gadget on dummy_hcd, '
            'in its own process) answers GetBatteryLevel (00 0B). Two models: as fast as it '
            'goes, and with --tick-ms 1, the firmware\'s scheduler: a command waits for the '
            'next 1 ms tick and at most one is handled per tick, the physical ceiling of '
            '1000 transactions/s. aNXT waits 6 ms per direct command on a real brick. The '
            'rates are the emulated bus, the emulator and each host stack, under QEMU TCG '
            'with %s.' % guest_cpus(),
            '/dev/nxtN: the C client, one open file per client thread, as a C program on '
            'the telegram ABI: liblegonxt builds GetBatteryLevel (lnxt_get_battery_level()), '
            'NXT_IOC_TRANSACT sends it and returns the reply, liblegonxt checks that it '
            'answers the telegram and reads the millivolts (lnxt_reply_check(), '
            'lnxt_parse_battery_level()); the driver serialises the brick.',
            'libusb: lego_nxt_usb unbound through sysfs; the C client claims interface 0 once '
            'and its threads share the handle, each taking a mutex around bulk OUT 0x01 + '
            'bulk IN 0x82 (NXT replies carry no transaction id).',
            'nxt-python 3.5.1: stock usb backend (pyusb 1.x, libusb-1.0), driver unbound, '
            'threads sharing one nxt.brick.Brick (its lock serialises each command), in a '
            'Python process of its own for each measurement.',
            'Every reply checked: opcode, status 0 and %d mV. %d rounds; in each, for 1, 4 '
            'and 8 clients, /dev/nxtN, libusb and nxt-python for %.1f s each, back to back; '
            'figures are the median of the rounds. Whole run %.0f s on %s, kernel %s.'
            % (BATTERY_MV, args.runs, args.seconds, time.monotonic() - started,
               platform.machine(), platform.release()),
            'Guest clocksource: %s.' % clock + (
                ' On refined-jiffies (the TSC rate unknown: vm-run gives it as tsc_early_khz=) '
                'high-resolution timers are off and dummy_hcd\'s 1 ms frame timer, like every '
                'timer, fires on 4 ms jiffies: latencies come in multiples of 4 ms.'
                if 'jiffies' in clock else ''),
        ],
    }
    log('wrote %s' % write_section(args.out, 'nxt.json', out))


def write_section(directory, name, section):
    """The section as tests/bench/report.py reads it: DIRECTORY/NAME, its path."""
    path = os.path.join(directory, name)
    with open(path, 'w') as f:
        json.dump(section, f, indent=1)
    return path


if __name__ == '__main__':
    main()
