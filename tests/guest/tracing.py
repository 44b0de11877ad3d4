"""The drivers' trace events in tracefs and their debugfs counters, for the
guest tests (Documentation/lego/tracing.rst)."""
import os
import re
import shlex
import subprocess

from conftest import wait_for

DEBUGFS = '/sys/kernel/debug'
# One line of tracefs's trace: task, CPU, flags, timestamp, event, fields.
LINE = re.compile(r'^\s*\S.*?\s+\[\d+\].*?\s(\d+\.\d+): (\w+): (.*)$')


def tracefs():
    """The tracefs mount: /sys/kernel/tracing, mounted if need be."""
    path = '/sys/kernel/tracing'
    if not os.path.isdir(path + '/events'):
        subprocess.run(['mount', '-t', 'tracefs', 'tracefs', path], check=True)
    return path


def write(path, value):
    with open(path, 'w') as f:
        f.write(value)


def counters(path):
    """A debugfs counters file, as {name: value}."""
    with open(path) as f:
        return {k: int(v) for k, v in (line.split() for line in f)}


class Trace:
    """One trace system's events, enabled for a test, read back parsed."""

    def __init__(self, system):
        self.root = tracefs()
        self.system = system
        write(self.root + '/buffer_size_kb', '4096')
        write(self.root + '/trace', '')
        write(self.root + '/events/%s/enable' % system, '1')
        write(self.root + '/tracing_on', '1')

    def stop(self):
        write(self.root + '/events/%s/enable' % self.system, '0')

    def timed(self):
        """Every event recorded so far, as (time, name, fields), in order."""
        out = []
        with open(self.root + '/trace') as f:
            for line in f:
                m = LINE.match(line)
                if m:
                    fields = dict(kv.split('=', 1) for kv in shlex.split(m.group(3))
                                  if '=' in kv)
                    out.append((float(m.group(1)), m.group(2), fields))
        return out

    def events(self, name=None, **match):
        """The events recorded so far, as (name, fields) in order; only
        those called name with fields equal to match, if given."""
        return [(n, f) for _, n, f in self.timed()
                if (not name or n == name) and
                all(f.get(k) == str(v) for k, v in match.items())]

    def wait(self, name, timeout=5.0, **match):
        wait_for(lambda: self.events(name, **match), timeout)
        return self.events(name, **match)
