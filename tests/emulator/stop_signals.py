"""How an emulator run as a program waits for SIGTERM or SIGINT.

Not with a Python signal handler that sets a threading.Event: the handler
runs in the main thread between two of its bytecodes, and when those are
inside the same Event's wait() (which holds the Event's lock while it
looks at the flag), set() waits for that lock for ever. The emulator then
never stops, and the UDC or pty it holds stays busy for every test after
it. Instead the two signals are blocked, before any thread is started (a
thread inherits the mask, so none of them takes the signal either), and
the main thread collects them with sigtimedwait().
"""
import signal

STOP = {signal.SIGTERM, signal.SIGINT}


class StopSignals:
    """Create it first thing in main(), before any thread starts."""

    def __init__(self):
        signal.pthread_sigmask(signal.SIG_BLOCK, STOP)
        self.got = None

    def wait(self, timeout):
        """True once SIGTERM or SIGINT came (within `timeout` seconds)."""
        if self.got is None:
            info = signal.sigtimedwait(STOP, timeout)
            if info is not None:
                self.got = info.si_signo
        return self.got is not None
