#!/usr/bin/env python3
"""Where the CPU of EV3 sample delivery goes, in the test VM (issue 32).

    python3 tests/bench/guest/ev3_profile.py --out DIR [--sensors N] [--seconds S]

One run of each path of ev3_bench.py's sample delivery (N gyros at 1 kHz
from lego_nullmodem's generator: the line discipline with IIO and a C
reader, and the userspace reference, N_TTY with the same reader decoding)
under `perf record -g -e cpu-clock -a`, the only event a TCG guest has.
Each sample goes to a group by the first of these functions in its call
chain: ev3_uart_port_receive (the discipline's parsing and IIO push, in
the tty layer's receive work), n_tty_receive_* (N_TTY), flush_to_ldisc
(the rest of the tty layer's flip buffer work), the discipline's
keep-alive, port and send work; else by its task: the reader's system
calls and user space, the interrupts and soft interrupts that ran while
the CPU was otherwise idle (the swapper task outside the idle loop: not in
ev3_bench.py's task time, so shown apart, at the same scale), kworkers
waking and sleeping (worker_thread with no work of ours in the chain), the
idle loop (left out), and the rest; the profiler's own tasks (perf, its
sleep) are left out. perf's throttling (kernel.perf_cpu_time_max_percent),
which TCG's slow interrupts would trip, is lifted for the runs. Each group's share of the busy
samples times the run's CPU per sample (measured as ev3_bench.py does,
from se.sum_exec_runtime) gives its microseconds per sample. Writes
DIR/ev3_profile.json, a section of tests/bench/results.md.

Under TCG a timer sample is taken when the guest next enables interrupts:
it lands a few instructions late, in the same function or its caller, so
the groups are by call chain, not by the innermost function.
"""
import argparse
import collections
import json
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ev3_bench as eb                  # noqa: E402

PERF_HZ = 997
KEEP = '.'          # main() sets it to --out
# The groups, and the functions in a sample's call chain that put it there,
# the first found from the innermost frame outwards.
GROUPS = ('the discipline: parsing and IIO push', 'N_TTY receive',
          'tty layer: flip buffer work', 'lego_ev3_uart keep-alive and port work',
          'reader: read() in the kernel', 'reader: user space',
          'kworkers waking and sleeping', 'other', 'interrupts on an idle CPU')
# The last group is not in the CPU per sample that ev3_bench.py measures
# (task time only): shown at the same scale, apart.
IRQ_IDLE = GROUPS[-1]
# (A name ending in _ stands for every function it begins: n_tty_receive_buf2(),
# n_tty_receive_buf_common() and the rest.)
FRAMES = (('ev3_uart_port_receive', GROUPS[0]), ('n_tty_receive_', GROUPS[1]),
          ('flush_to_ldisc', GROUPS[2]), ('ev3_uart_keepalive_work', GROUPS[3]),
          ('ev3_uart_work', GROUPS[3]), ('ev3_uart_tx_work', GROUPS[3]))
IDLE = ('default_idle', 'cpuidle', 'do_idle', 'pv_native_safe_halt', 'acpi_idle')


def group(comm, frames):
    """The group of a sample of task `comm` with call chain `frames`
    (innermost first), or None for the idle loop."""
    for fn in frames:
        for name, g in FRAMES:
            if fn == name or (name.endswith('_') and fn.startswith(name)):
                return g
    if comm.startswith('ev3_read'):
        return GROUPS[4] if any(fn.startswith(('__x64_sys', 'entry_SYSCALL', 'do_syscall'))
                                for fn in frames) else GROUPS[5]
    if comm.startswith('swapper'):
        inner = frames[0] if frames else ''
        if any(k in inner for k in IDLE) or inner.startswith('__cpuidle'):
            return None
        return IRQ_IDLE
    if comm.startswith('kworker/') and 'worker_thread' in frames:
        return GROUPS[6]
    return GROUPS[7]


# The profiler's own tasks: left out, as the bench's own are from its CPU time.
PROFILER = ('perf', 'perf-exec', 'sleep')


def split(data):
    """{group: share of the busy samples}, and the idle share, of a perf.data
    recorded with call chains."""
    # (perf script prints a sample's call chain only with its ip.)
    out = subprocess.run(['perf', 'script', '-i', data, '-F', 'comm,ip,sym'],
                         capture_output=True, text=True, check=True).stdout
    # The first samples, beside the JSON, to see what was grouped how.
    with open(os.path.join(KEEP, os.path.basename(data) + '.txt'), 'w') as f:
        f.write('\n'.join(out.splitlines()[:5000]) + '\n')
    counts = dict.fromkeys(GROUPS, 0)
    others = collections.Counter()
    idle = total = 0
    for block in out.split('\n\n'):
        lines = [ln for ln in block.splitlines() if ln.strip()]
        if not lines:
            continue
        comm = lines[0].split()[0]
        if comm in PROFILER:
            continue
        frames = [ln.split()[-1].split('+')[0] for ln in lines[1:]]
        total += 1
        g = group(comm, frames)
        if g is None:
            idle += 1
        else:
            counts[g] += 1
            if g == GROUPS[7]:
                others[re.sub(r'[/:][\w:.+-]*$', '', comm.split('-')[0])] += 1
    busy = total - idle - counts[IRQ_IDLE]
    if busy <= 0:
        raise eb.BenchError('perf recorded no busy samples in %s' % data)
    return {g: n / busy for g, n in counts.items()}, idle, busy, others


def profile_run(binary, reader, work, nsensors, seconds, path):
    """One run of `path` under perf: (its figures as ev3_bench measures them, split)."""
    # In the guest's tmpfs: perf cannot write its file on 9p.
    data = os.path.join(work, 'perf-%s.data' % path)
    orig = eb.generate

    def generate(n, secs, *a, **k):
        p = subprocess.Popen(['perf', 'record', '-q', '-g', '-e', 'cpu-clock', '-a', '-F', str(PERF_HZ),
                              '-o', data, '--', 'sleep', '%.1f' % max(secs - 1.0, 1.0)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            return orig(n, secs, *a, **k)
        finally:
            _, err = p.communicate(timeout=60)
            if p.returncode:
                raise eb.BenchError('perf record failed (%d): %s' % (p.returncode, err.strip()))

    eb.generate = generate
    try:
        res = eb.sample_run(binary, reader, work, nsensors, seconds, path, 0.0)
    finally:
        eb.generate = orig
    return res, split(data)


def unthrottled():
    """Lift perf's limit on the time its interrupts take (kernel.perf_cpu_time_max_percent),
    which TCG's slow interrupts hit at once: perf would then lower its rate to a
    few tens of samples a second. Returns the old value, to put back."""
    path = '/proc/sys/kernel/perf_cpu_time_max_percent'
    with open(path) as f:
        old = f.read().strip()
    with open(path, 'w') as f:
        f.write('0')
    return old


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', required=True, help='directory for ev3_profile.json')
    ap.add_argument('--sensors', type=int, default=16)
    ap.add_argument('--seconds', type=float, default=10.0)
    ap.add_argument('--quick', action='store_true', help='(as the other benchmarks take it)')
    args = ap.parse_args()
    if os.environ.get('LEGO_IN_VM') != '1':
        print('ev3_profile: run me in the test VM (tests/vm-run)', file=sys.stderr)
        return 1
    os.makedirs(args.out, exist_ok=True)
    global KEEP
    KEEP = args.out
    work = tempfile.mkdtemp(prefix='ev3profile.')
    figures, notes, status = [], [], 0
    try:
        binary = eb.build(work, 'ev3_stream')
        reader = eb.build(work, 'ev3_read')
        eb.ensure_ev3_module()
        eb.nullmodem(args.sensors)
        # As ev3_bench: a short reference run first starts the tty layer's workers.
        eb.sample_run(binary, reader, work, args.sensors, 1.0, 'tty', 0.0)
        names = {'iio': 'lego_ev3_uart + IIO + C reader', 'tty': 'reference: N_TTY + C reader'}
        per = {}
        old = unthrottled()
        try:
            for path in ('iio', 'tty'):
                res, (shares, idle, busy, others) = profile_run(binary, reader, work,
                                                                args.sensors, args.seconds, path)
                per[path] = res['per_sample']
                for g in GROUPS:
                    figures.append(eb.figure(
                        '%d sensors at 1 kHz, %s: %s' % (args.sensors, names[path], g),
                        round(shares[g] * res['per_sample'], 2), 'us/sample', None, None, None,
                        None, '%s%.1f %% of %d busy perf samples of tasks (cpu-clock, %d Hz, '
                        'all CPUs; %d idle) of one %.0f s run, which used %.1f us per sample '
                        'in all' % ('not in the CPU per sample (task time only), at its scale: '
                                    if g == IRQ_IDLE else '', shares[g] * 100, busy, PERF_HZ,
                                    idle, args.seconds, res['per_sample'])))
                notes.append('%s, %d sensors, %d busy samples: %s; "other" was %s' % (
                    names[path], args.sensors, busy,
                    ', '.join('%s %.2f us' % (g, shares[g] * res['per_sample']) for g in GROUPS),
                    ', '.join('%s %d' % kv for kv in others.most_common(5)) or 'nothing'))
        finally:
            with open('/proc/sys/kernel/perf_cpu_time_max_percent', 'w') as f:
                f.write(old)
        notes.append('In this profile the line discipline used %.2f x the reference\'s CPU per '
                     'sample (one run of each, %.1f and %.1f us).'
                     % (per['iio'] / per['tty'], per['iio'], per['tty']))
    except (eb.BenchError, OSError, subprocess.SubprocessError) as e:
        print('ev3_profile: %s' % e, file=sys.stderr)
        notes.append('ERROR: %s' % e)
        status = 1
    notes.append(__doc__.split('\n\n', 2)[2].replace('\n', ' ').strip())
    notes.append('Run %s in a TCG VM.' % time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime()))
    with open(os.path.join(args.out, 'ev3_profile.json'), 'w') as f:
        json.dump({'section': 'EV3 sample delivery: where the CPU goes (perf, by task)',
                   'figures': figures, 'notes': notes}, f, indent=1)
    for fig in figures:
        print('%-75s %8s %s' % (fig['name'], fig['value'], fig['unit']))
    return status


if __name__ == '__main__':
    sys.exit(main())
