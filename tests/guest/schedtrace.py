"""Where a late keep-alive spent its time: a tracefs instance for the line
fixture (conftest.py) that records, on the guest's CLOCK_MONOTONIC (the
wire log's clock, wire.py), the keep-alive's path through the kernel:

- workqueue_queue_work on lego_ev3_keepalive (the hrtimer fired and queued
  the work), workqueue_execute_start and _end of ev3_uart_keepalive_work
  (filtered on the work function's address), the discipline's own
  ev3_uart_tx events (the NACK sent);
- sched_wakeup of kworkers (where the work's worker was woken, and when),
  and each sched_switch to or from a kworker on any CPU: when it got a
  CPU, and what ran there before it (every switch would say more, at a
  cost the whole run of tests paid).

When a wire check fails on a keep-alive, lines() gives what the instance
holds for the late interval, and the fixture adds it to the failure. A
test that is not about timing never reads it; its cost is the events'.
"""
import os

import tracing
import wire

KEEPALIVE_NS = wire.KEEPALIVE_MS * 10 ** 6

NAME = 'lego_wire'
KB_PER_CPU = 2048


def _symbol(name):
    """The address of a kernel (or module) symbol, or None."""
    with open('/proc/kallsyms') as f:
        for line in f:
            fields = line.split()
            if len(fields) >= 3 and fields[2] == name:
                addr = int(fields[0], 16)
                return addr or None
    return None


class SchedTrace:
    """The instance, created for one test and removed after it."""

    def __init__(self, name=NAME):
        self.root = None
        func = _symbol('ev3_uart_keepalive_work')
        if func is None:
            return
        root = os.path.join(tracing.tracefs(), 'instances', name)
        if os.path.isdir(root):
            os.rmdir(root)
        os.mkdir(root)
        self.root = root
        tracing.write(root + '/trace_clock', 'mono')
        tracing.write(root + '/buffer_size_kb', str(KB_PER_CPU))
        ev = root + '/events/'
        tracing.write(ev + 'workqueue/workqueue_queue_work/filter',
                      'workqueue == "lego_ev3_keepalive"')
        for e in ('workqueue_execute_start', 'workqueue_execute_end'):
            tracing.write(ev + 'workqueue/%s/filter' % e, 'function == 0x%x' % func)
        tracing.write(ev + 'sched/sched_wakeup/filter', 'comm ~ "kworker*"')
        tracing.write(ev + 'sched/sched_switch/filter',
                      'prev_comm ~ "kworker*" || next_comm ~ "kworker*"')
        for e in ('workqueue/workqueue_queue_work', 'workqueue/workqueue_execute_start',
                  'workqueue/workqueue_execute_end', 'sched/sched_wakeup',
                  'sched/sched_switch', 'lego_ev3_uart/ev3_uart_tx'):
            tracing.write(ev + e + '/enable', '1')
        tracing.write(root + '/tracing_on', '1')

    def lines(self, a_ns, b_ns, before_ms=5, most=300):
        """The instance's lines from before_ms before a_ns to b_ns, at most
        `most` of them (the first and the last halves); tracing pauses while
        they are read."""
        if self.root is None:
            return ['(no trace: ev3_uart_keepalive_work not in /proc/kallsyms)']
        tracing.write(self.root + '/tracing_on', '0')
        lo, hi = (a_ns - before_ms * 10 ** 6) / 1e9, b_ns / 1e9
        out = []
        with open(self.root + '/trace') as f:
            for line in f:
                m = tracing.LINE.match(line)
                if m and lo <= float(m.group(1)) <= hi:
                    out.append(line.rstrip())
        tracing.write(self.root + '/tracing_on', '1')
        if not out:
            out.append('(nothing in the trace from %.6f to %.6f: overwritten?)' % (lo, hi))
        if len(out) > most:
            out[most // 2:-most // 2] = ['(%d lines)' % (len(out) - most)]
        return out

    def explain(self, conns, most=2):
        """The kernel's lines for the first `most` intervals wire.check()
        found too long on the connections conns (their .late), each from 5
        ms before the keep-alive's timer was due when it is a period."""
        out = []
        for c in conns:
            for a, b in c.late:
                if len(out) // 2 >= most:
                    return [x for part in out for x in part]
                if b - a > KEEPALIVE_NS:
                    a += KEEPALIVE_NS - 5 * 10 ** 6
                out.append(['the kernel from %.6f to %.6f s:' % (a / 1e9, b / 1e9)])
                out.append(self.lines(a, b, before_ms=0))
        return [x for part in out for x in part]

    def close(self):
        if self.root is not None:
            tracing.write(self.root + '/tracing_on', '0')
            for e in ('workqueue', 'sched', 'lego_ev3_uart'):
                tracing.write(self.root + '/events/%s/enable' % e, '0')
            os.rmdir(self.root)
            self.root = None
