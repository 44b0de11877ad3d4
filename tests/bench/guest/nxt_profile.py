#!/usr/bin/env python3
"""Where an NXT transaction's time goes, in the test VM (issue 19).

    python3 tests/bench/guest/nxt_profile.py [--seconds S] [--cases dev1,dev8,...]
        [--client PATH] [--emulator PATH] [--tick-ms MS]

Runs the cases of nxt_bench.py one after the other (dev N: /dev/nxtN with N
clients; libusb N; py N: nxt-python; the driver is unbound at the first
libusb or py case and stays so), and for each prints the rate and, per
transaction, the CPU time of the emulated brick's process and of the
client's (user and system), the guest's CPU time by kind (/proc/stat: user,
system, softirq, idle), the local timer interrupts and the context
switches. The idle time is what the path spent waiting with nothing to run
(dummy_hcd moves data from an hrtimer). A diagnostic, not a benchmark: no
rounds, no JSON; run it on the benchmark kernel:

    LEGO_VM_SMP=1 tests/vm-run --variant bench -- \\
        python3 tests/bench/guest/nxt_profile.py --cases dev1,dev8,libusb1,libusb8,py1
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import nxt_bench as nb                  # noqa: E402  (it sets up tests/guest too)
import nxtdev                           # noqa: E402

HZ = os.sysconf('SC_CLK_TCK')


def sysstat():
    with open('/proc/stat') as f:
        v = [int(x) for x in f.readline().split()[1:]]
        ctxt = next(int(line.split()[1]) for line in f if line.startswith('ctxt'))
    return dict(zip('user nice system idle iowait irq softirq steal'.split(), v)), ctxt


def proc_ticks(pid):
    with open('/proc/%d/stat' % pid) as f:
        s = f.read().rsplit(')', 1)[1].split()
    return int(s[11]), int(s[12])       # utime, stime


def local_timer_irqs():
    with open('/proc/interrupts') as f:
        for line in f:
            if line.split()[:1] == ['LOC:']:
                return sum(int(x) for x in line.split()[1:] if x.isdigit())
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seconds', type=float, default=4.0, help='seconds per case (default 4)')
    ap.add_argument('--cases', default='dev1,dev4,dev8,libusb1,libusb8,py1,py8',
                    help='cases, in order (default %(default)s)')
    ap.add_argument('--client', default=nb.DEFAULT_CLIENT, help='the C client binary')
    ap.add_argument('--emulator', default=nb.EMULATOR, help='the emulated brick script')
    ap.add_argument('--tick-ms', type=float, default=0, help='the brick\'s --tick-ms')
    args = ap.parse_args()
    if os.environ.get('LEGO_IN_VM') != '1':
        sys.exit('nxt_profile: run it inside the test VM (tests/vm-run)')
    nb.EMULATOR = args.emulator
    nxtdev.load_driver()
    emu = nb.Emulator(['--tick-ms', str(args.tick_ms)] if args.tick_ms else [])
    try:
        node = nxtdev.node_of(nb.SERIAL)
        nb.run_client(args.client, 'dev', node, 1, 0.5)      # warm up
        for case in args.cases.split(','):
            path = case.rstrip('0123456789')
            n = int(case[len(path):])
            if path != 'dev' and os.path.exists(node):
                with open(nxtdev.DRIVER + '/unbind', 'w') as f:
                    f.write(os.path.basename(nxtdev.interface_of(nb.SERIAL)))
                nb.wait_for(lambda: not os.path.exists(node), 5, 'the node outlived the unbind')
            s0, c0 = sysstat()
            e0, l0 = proc_ticks(emu.proc.pid), local_timer_irqs()
            if path == 'py':
                r = nb.run_nxt_python_process(n, args.seconds)
            elif path in ('dev', 'libusb'):
                r = nb.run_client(args.client, path, node if path == 'dev' else '0694:0002',
                                  n, args.seconds)
            else:
                sys.exit('nxt_profile: unknown case %s' % case)
            s1, c1 = sysstat()
            e1, l1 = proc_ticks(emu.proc.pid), local_timer_irqs()
            ok = max(r['ok'], 1)
            us = lambda ticks: '%.0f' % (ticks / HZ / ok * 1e6)
            print('%-8s %7.1f/s p50 %6.2f p99 %6.2f ms | us per transaction: brick user %s '
                  'sys %s, client %.0f | guest user %s sys %s softirq %s idle %s | '
                  'timer irqs %.1f, context switches %.1f' % (
                      case, r['tps'], r['p50_us'] / 1e3, r['p99_us'] / 1e3,
                      us(e1[0] - e0[0]), us(e1[1] - e0[1]), r['cpu_us'],
                      us(s1['user'] + s1['nice'] - s0['user'] - s0['nice']),
                      us(s1['system'] - s0['system']), us(s1['softirq'] - s0['softirq']),
                      us(s1['idle'] - s0['idle']), (l1 - l0) / ok, (c1 - c0) / ok), flush=True)
    finally:
        emu.stop()


if __name__ == '__main__':
    main()
