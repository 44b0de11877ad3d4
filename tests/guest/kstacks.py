"""The kernel stacks of a process's threads, for the report of a hang
(shared by tests/guest/ev3_fuzz.py, tests/soak/nxt_fuzz.py and
tests/soak/soak.py)."""
import glob
import os


def kernel_stacks(pid):
    """/proc/PID/task/*/stack of every thread of `pid`, one after another."""
    out = []
    for task in glob.glob('/proc/%d/task/*' % pid):
        try:
            with open(task + '/stack') as f:
                out.append('%s:\n%s' % (os.path.basename(task), f.read()))
        except OSError:
            pass
    return '\n'.join(out)
