"""The emulators stop on SIGTERM, whenever it comes (stop_signals.py).

Runs on the host (make check's harness phase): the serial brick serves a
pty, which needs no VM; the USB bricks share its main loop's helper.
"""
import os
import random
import signal
import subprocess
import sys
import textwrap
import time

HERE = os.path.dirname(os.path.abspath(__file__))

# A program that starts its threads after StopSignals(), as the emulators
# do, and prints what each of them has blocked, then waits to be stopped.
PROGRAM = textwrap.dedent('''
    import signal, sys, threading
    sys.path.insert(0, %r)
    from stop_signals import StopSignals
    stop = StopSignals()
    seen = []
    def worker():
        seen.append(signal.pthread_sigmask(signal.SIG_BLOCK, []))
        while not stop.got:
            sum(range(1000))    # busy: a process-directed signal may pick it
    threads = [threading.Thread(target=worker, daemon=True) for _ in range(3)]
    for t in threads:
        t.start()
    while len(seen) < 3:
        pass
    print(all(signal.SIGTERM in s and signal.SIGINT in s for s in seen), flush=True)
    while not stop.wait(0.1):
        pass
    print(signal.Signals(stop.got).name, flush=True)
''') % HERE


def test_threads_inherit_the_mask_and_the_main_thread_collects_the_signal():
    for sig in (signal.SIGTERM, signal.SIGINT):
        p = subprocess.Popen([sys.executable, '-c', PROGRAM], stdout=subprocess.PIPE,
                             text=True)
        try:
            assert p.stdout.readline().strip() == 'True'
            p.send_signal(sig)
            assert p.wait(10) == 0
            assert p.stdout.read().strip() == sig.name
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()


def test_the_serial_brick_stops_on_sigterm_at_any_moment():
    """SIGTERM at random moments after the brick serves its pty (its main
    loop waits 0.2 s at a time): each run ends at once, status 0."""
    rng = random.Random(os.environ.get('LEGO_TEST_SEED', 1))
    for _ in range(10):
        p = subprocess.Popen([sys.executable, os.path.join(HERE, 'nxt_serial_brick.py'),
                              '--pty'], stdout=subprocess.PIPE, text=True)
        try:
            assert p.stdout.readline().startswith('/dev/pts/')
            time.sleep(rng.uniform(0, 0.4))
            p.terminate()
            assert p.wait(10) == 0
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
