"""The discipline's timing on a null-modem line, from kernel timestamps.

The null modem (tests/kmod/lego_nullmodem.c) logs in debugfs
(lego_nullmodem/wire) when each byte the discipline's end of a line (an
even port, ttyNM0, ttyNM2...) wrote was written and when it was on the
wire, and when each burst of
the sensor's end (the odd port) that ended in 0x04 did: a sensor's ACK ends
its handshake so. The times are ktime_get_ns(), the guest's CLOCK_MONOTONIC
(time.monotonic_ns() reads the same clock): what the emulator's thread or
the test's were doing does not enter into them.

check() finds every handshake the discipline answered on a line (its ACK)
and checks, against uart-peers.md (1.7, 1.10) and ev3dev.md (1.6):

- the ACK deadline: the sensor waits 80 ms from its ACK for the host's, and
  the discipline waits 10 ms on purpose (LEGO's UART_ACK_DELAY): its ACK
  must be on the wire 10 ms plus the byte's own time after the sensor's, and
  less than 80 ms after it;
- the keep-alive period (when the NACKs were written): a NACK every 100 ms
  from the speed switch on, as long as the connection lasts. The
  discipline queues each keep-alive
  100 ms after the last one ran, so a period is 100 ms plus the time its
  work took to wake up: never less than 100 ms less PERIOD_SLACK_MS (the
  test kernel's timers tick every 4 ms; on the wire, the null modem sends
  what was written at its next tick), the median no more than MEDIAN_LATE_MS over
  100 ms (a few ticks of wake-up), and no period, nor the time from the ACK
  to the first NACK or from the last NACK to the end of the connection (a
  detach, the time the caller gives, or the discipline's probe after a
  loss, plus the time its work takes), of two periods or more: a keep-alive
  missed.

The guest's clock is the host's (TCG): a guest starved by its host sees
late timers in kernel time too (with four test VMs on two cores the
discipline's keep-alive periods were measured up to 1084 ms and its ACKs up
to 535 ms late). The null modem measures that: a pinned hard-interrupt
timer on each CPU logs a stall record ('s', port 255) whenever it fires 10
ms late or more, which only a CPU that did not run makes it; and a probe
work item, queued every 5 ms on a workqueue of the keep-alive's kind, logs
one ('q') whenever it ran 10 ms late or more: CPUs that ran other things
than the guest's high-priority work (an emulated CPU slowed by its host, a
long section without preemption elsewhere) delay the keep-alive as much,
and a CPU's heartbeat does not see it. A keep-alive gap, a late first or
last keep-alive or a late ACK is the discipline's only for the time the
guest was not stalled: the time the records of either kind cover in that
interval (stalled_ms()) is taken off before the upper bound is applied,
and the excuse is noted on the connection. Nothing else is excused: a
keep-alive the discipline skipped, or one late while the guest's CPUs ran
and the probe ran on time (the discipline's lock held, its work not
queued), still fails; the lower bounds are never adjusted, and the
median's upper bound only by taking each period's stalled time off.
"""
import os
import statistics
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'emulator'))
from ev3_gen import msg_len  # noqa: E402

PATH = '/sys/kernel/debug/lego_nullmodem/wire'
STALL_PORT = 255            # the port of the null modem's stall records
SYS_NACK, SYS_ACK = 0x02, 0x04
ACK_DELAY_MS = 10           # the discipline's wait before its ACK (on purpose)
ACK_DEADLINE_MS = 80        # the sensor's wait for it
KEEPALIVE_MS = 100
PERIOD_SLACK_MS = 12        # three 4 ms ticks: timer, work, null-modem pacing
MEDIAN_LATE_MS = 12         # the work's wake-up, a few ticks
MISSED_MS = 2 * KEEPALIVE_MS
PROBE_WORK_MS = 50          # from the keep-alive that finds a sensor lost to the probe


def available():
    return os.path.exists(PATH)


def read(since=0):
    """Records with seq >= since: [(seq, ns, port, baud, kind, byte)], and
    whether some of them were overwritten before they were read."""
    recs = []
    with open(PATH) as f:
        for line in f:
            seq, ns, port, baud, kind, byte = line.split()
            seq = int(seq)
            if seq >= since:
                recs.append((seq, int(ns), int(port), int(baud), kind, int(byte, 16)))
    lost = bool(recs) and recs[0][0] > since
    return recs, lost


def head():
    """The seq the next record will have (read at the start of what a caller
    checks)."""
    last = -1
    with open(PATH) as f:
        for line in f:
            last = int(line.split(' ', 1)[0])
    return last + 1


def clear():
    with open(PATH, 'w') as f:
        f.write('0')


# The bytes of one message follow each other on the wire: after a pause
# this long, or at another speed, what was left of a message was flushed
# (a sensor lost in the middle of a WRITE) and a new one begins.
MSG_GAP_NS = 50 * 10 ** 6


def host_messages(recs, port, which='b'):
    """The messages port sent, framed by their headers: [(ns of the last
    byte, baud, bytes)], when they were on the wire ('b') or written ('w')."""
    out, cur, last = [], b'', (0, 0)
    for _, ns, p, baud, kind, byte in recs:
        if p != port or kind != which:
            continue
        if cur and (baud != last[1] or ns - last[0] > MSG_GAP_NS + 10 ** 10 // baud):
            cur = b''
        last = (ns, baud)
        cur += bytes([byte])
        if len(cur) == msg_len(cur[0]):
            out.append((ns, baud, cur))
            cur = b''
    return out


def stalls(recs):
    """The guest's stalls in recs: [(start ns, end ns)], from the records of
    a CPU that did not run ('s': how many microseconds late its heartbeat
    fired, in the baud field) and of a probe work item that waited ('q': how
    many microseconds after it was queued it ran)."""
    return [(ns - baud * 1000, ns) for _, ns, port, baud, kind, _ in recs
            if port == STALL_PORT and kind in ('s', 'q')]


def stalled_ms(spans, a, b):
    """How much of [a, b] (ns) some CPU of the guest was stalled, in ms."""
    cut = sorted((max(s, a), min(e, b)) for s, e in spans if e > a and s < b)
    total, end = 0, a
    for s, e in cut:
        if e > end:
            total += e - max(s, end)
            end = e
    return total / 1e6


class Connection:
    """One handshake the discipline answered and what followed it."""

    def __init__(self, port, ack_ns, baud):
        self.port, self.ack_ns, self.baud = port, ack_ns, baud
        self.sensor_ack_ns = None
        self.nacks = []
        self.end_ns = None          # the next probe or ACK
        self.end_why = None
        self.excused = []           # what a stall of the guest's CPUs excused

    @property
    def ack_delay_ms(self):
        if self.sensor_ack_ns is None:
            return None
        return (self.ack_ns - self.sensor_ack_ns) / 1e6

    def periods_ms(self):
        t = [self.ack_ns] + self.nacks
        return [(b - a) / 1e6 for a, b in zip(t[1:], t[2:])]

    def __repr__(self):
        return ('ttyNM%d: ACK at %.3f s (%s baud) %s after the sensor\'s, %d NACKs, periods %s%s'
                % (self.port, self.ack_ns / 1e9, self.baud,
                   '%.1f ms' % self.ack_delay_ms if self.ack_delay_ms is not None else '?',
                   len(self.nacks), summary(self.periods_ms()),
                   ''.join('; excused: ' + e for e in self.excused)))


def summary(periods):
    if not periods:
        return '-'
    return 'min %.1f median %.1f max %.1f ms' % (min(periods), statistics.median(periods),
                                                max(periods))


def is_ack(msg):
    return msg == bytes([SYS_ACK])


def is_speed(msg):
    """A SPEED message: the discipline's next probe."""
    return msg[0] & 0xc7 == 0x42


# What ends a connection in connections(), by its end_why.
ENDED_BY = {'next ACK': is_ack, 'probe': is_speed}


def connections(recs, port):
    """The handshakes the discipline on `port` answered, in order."""
    conns = []
    sensor_acks = [ns for _, ns, p, _, kind, _ in recs if p == port + 1 and kind == 'a']
    cur = None
    for ns, baud, msg in host_messages(recs, port):
        if is_ack(msg):
            if cur:
                cur.end_ns, cur.end_why = ns, 'next ACK'
            cur = Connection(port, ns, baud)
            before = [t for t in sensor_acks if t < ns]
            cur.sensor_ack_ns = before[-1] if before else None
            conns.append(cur)
        elif cur is None or cur.end_ns is not None:
            continue
        elif msg == bytes([SYS_NACK]):
            cur.nacks.append(ns)
        elif is_speed(msg):
            cur.end_ns, cur.end_why = ns, 'probe'
    # The keep-alives as the discipline wrote them, where the log has that:
    # the null modem's pacing (a late tick sends two at once) is not the
    # discipline's doing. They go to the connection whose ACK was written
    # before them, by the times the ACK and the end were written too: the
    # first keep-alive is written as soon as the ACK is, before the ACK is
    # on the wire (a byte at 2400 baud takes 4 ms), and after a sensor lost
    # at 2400 baud no probe ends the connection, the next ACK does.
    written = host_messages(recs, port, 'w')
    nacks = [ns for ns, _, msg in written if msg == bytes([SYS_NACK])]
    if nacks:
        def written_at(ns, kind):
            """When the message of `kind` on the wire at ns was written: the
            last one of its kind written by then."""
            ts = [t for t, _, msg in written if t <= ns and kind(msg)]
            return ts[-1] if ts else ns
        for c in conns:
            start = written_at(c.ack_ns, is_ack)
            end = None if c.end_ns is None else written_at(c.end_ns, ENDED_BY[c.end_why])
            c.nacks = [t for t in nacks if t > start and (end is None or t < end)]
    return conns


def check(recs, port, end_ns=None, lost=False, detached=()):
    """Problems with the ACKs and keep-alives of the discipline on ttyNM<port>
    in `recs` (read() since before its attach): a list of texts, empty if
    none, and the connections found. end_ns: when the test ended (the line
    about to be detached: time.monotonic_ns()), for the last connection;
    detached: when the discipline was detached before that (it may be
    attached again), which ends the connection then."""
    errors = []
    conns = connections(recs, port)
    spans = stalls(recs)
    if lost:
        errors.append('ttyNM%d: the wire log overflowed: records lost' % port)
    for c in conns:
        ends = [t for t in detached if t > c.ack_ns]
        if ends and (c.end_ns is None or min(ends) < c.end_ns):
            c.end_ns, c.end_why = min(ends), 'detach'
        errors += check_connection(c, end_ns, spans)
    return errors, conns


def late(c, spans, a, b, limit, what):
    """Whether the interval [a, b] (ns) is `limit` ms or more once the time
    the guest's CPUs were stalled in it is taken off; an interval only a
    stall made that long is noted on c as excused."""
    ms = (b - a) / 1e6
    if ms < limit:
        return False
    stalled = stalled_ms(spans, a, b)
    if ms - stalled < limit:
        c.excused.append('%s %.1f ms, %.1f ms of it a stall of the guest (its CPUs or '
                         'its work queues)' % (what, ms, stalled))
        return False
    return True


def check_connection(c, end_ns=None, spans=()):
    errs = []
    name = 'ttyNM%d' % c.port
    d = c.ack_delay_ms
    low = ACK_DELAY_MS + 10e3 / c.baud
    if d is None:
        errs.append('%s: ACK at %.3f s with no ACK of the sensor before it in the log'
                    % (name, c.ack_ns / 1e9))
    elif d < low or late(c, spans, c.sensor_ack_ns, c.ack_ns, ACK_DEADLINE_MS, 'ACK after'):
        errs.append('%s: ACK %.1f ms after the sensor\'s (want %.1f <= d < %d ms): %r'
                    % (name, d, low, ACK_DEADLINE_MS, c))
    hi = MISSED_MS
    lo = KEEPALIVE_MS - PERIOD_SLACK_MS
    end = c.end_ns if c.end_ns is not None else end_ns
    if not c.nacks:
        if end is not None and late(c, spans, c.ack_ns, end, hi, 'ACK to end'):
            errs.append('%s: no keep-alive in the %.0f ms from the ACK to the %s'
                        % (name, (end - c.ack_ns) / 1e6, c.end_why or 'end'))
        return errs
    first = (c.nacks[0] - c.ack_ns) / 1e6
    if late(c, spans, c.ack_ns, c.nacks[0], hi, 'first keep-alive'):
        errs.append('%s: first keep-alive %.1f ms after the ACK (want < %d ms): %r'
                    % (name, first, hi, c))
    t = [c.ack_ns] + c.nacks
    periods = c.periods_ms()
    bad = [(p, a) for p, a, b in zip(periods, t[1:], t[2:])
           if p < lo or late(c, spans, a, b, hi, 'period')]
    if bad:
        # When, and how much of it the guest was seen stalled: a failure
        # report tells what the wire log knew.
        errs.append('%s: keep-alive periods out of %d..<%d ms: %s (%s): %r'
                    % (name, lo, hi,
                       ', '.join('%.1f at %.3f s (%.1f ms stalled)'
                                 % (p, a / 1e9, stalled_ms(spans, a, a + p * 1e6))
                                 for p, a in bad[:10]),
                       summary(periods), c))
    if len(periods) >= 5:
        med = statistics.median(periods)
        top = KEEPALIVE_MS + MEDIAN_LATE_MS
        if med > top:
            # The upper bound, like the others, on the periods less the
            # time the guest's CPUs were stalled in each.
            own = statistics.median([p - stalled_ms(spans, a, b)
                                     for p, a, b in zip(periods, t[1:], t[2:])])
            if own <= top:
                c.excused.append('median period %.1f ms, %.1f ms without the stalls of the '
                                 'guest\'s CPUs' % (med, own))
                med = own
        if not KEEPALIVE_MS - PERIOD_SLACK_MS / 3 <= med <= top:
            errs.append('%s: median keep-alive period %.1f ms, want %d..%d ms: %r'
                        % (name, med, KEEPALIVE_MS - PERIOD_SLACK_MS / 3, top, c))
    # A lost sensor: the keep-alive that finds no data sends nothing, and
    # the probe follows from the port's work queue. Before another ACK
    # without a probe (a tty that cannot probe) the line may rest.
    last = hi + (PROBE_WORK_MS if c.end_why == 'probe' else 0)
    if end is not None and c.end_why != 'next ACK' and \
            late(c, spans, c.nacks[-1], end, last, 'last keep-alive to end'):
        errs.append('%s: no keep-alive in the last %.0f ms before the %s (want < %d): %r'
                    % (name, (end - c.nacks[-1]) / 1e6, c.end_why or 'end', last, c))
    return errs
