"""The kernel log from now on, record by record from /dev/kmsg: what the
guest tests read to see what the drivers said (and the splats) while they
ran."""
import os


class Kmsg:
    """/dev/kmsg opened at its end: read() gives what was logged since the
    last read; mark() logs a line of the caller's (writable=True)."""

    def __init__(self, writable=False):
        self.fd = os.open('/dev/kmsg', (os.O_RDWR if writable else os.O_RDONLY) | os.O_NONBLOCK)
        os.lseek(self.fd, 0, os.SEEK_END)

    def read(self):
        """[(seconds since boot, the message's first line)]; the rest of a
        record is its dictionary (" SUBSYSTEM=...")."""
        out = []
        while True:
            try:
                rec = os.read(self.fd, 8192)
            except BlockingIOError:
                return out
            except BrokenPipeError:     # records overwritten meanwhile: go on
                continue
            if not rec:
                return out
            head, _, text = rec.decode(errors='replace').partition(';')
            fields = head.split(',')
            usec = int(fields[2]) if len(fields) > 2 and fields[2].isdigit() else 0
            out.append((usec / 1e6, text.split('\n')[0]))

    def texts(self):
        """read() without the times."""
        return [t for _, t in self.read()]

    def mark(self, text):
        try:
            os.write(self.fd, (text + '\n').encode())
        except OSError:
            pass

    def close(self):
        os.close(self.fd)
