"""The kernel log from now on, record by record from /dev/kmsg: what the
guest tests read to see what the drivers said (and the splats) while they
ran."""
import os
import re

# /dev/kmsg shows a record's control bytes, bytes of 127 and more and the
# backslash itself as \xNN (kernel/printk/printk.c, msg_add_ext_text()):
# a sensor's mode name "\2V4" is logged as "\x5c2V4".
_ESCAPE = re.compile(rb'\\x([0-9a-f]{2})')


def unescape(text):
    """A record's text as the driver logged it, from /dev/kmsg's form."""
    return _ESCAPE.sub(lambda m: bytes([int(m.group(1), 16)]), text)


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
            head, _, text = rec.partition(b';')
            fields = head.split(b',')
            usec = int(fields[2]) if len(fields) > 2 and fields[2].isdigit() else 0
            # The first line is the message (its own newlines escaped);
            # the lines after it are the record's dictionary.
            line = unescape(text.split(b'\n')[0]).decode(errors='replace')
            out.append((usec / 1e6, line))

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
