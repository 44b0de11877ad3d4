"""tests/guest/kmsg.py (host side, no VM): records read as /dev/kmsg hands
them over give the text the driver logged, with the kernel's \\xNN escapes
undone (a fuzzed sensor's mode name with a backslash was once not found in
the log, because the log shows it as \\x5c).

  python3 -m pytest -v tests/lib/test_kmsg.py
"""
import os
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tests', 'guest'))

import kmsg  # noqa: E402


class FakeKmsg(kmsg.Kmsg):
    """Kmsg reading records from a list instead of /dev/kmsg."""

    def __init__(self, records):         # pylint: disable=super-init-not-called
        self.records = list(records)
        self.fd = None


def read_records(records, monkeypatch):
    k = FakeKmsg(records)

    def fake_read(fd, size):
        if not k.records:
            raise BlockingIOError
        return k.records.pop(0)

    monkeypatch.setattr(kmsg.os, 'read', fake_read)
    return k.read()


def test_backslash_and_control_bytes(monkeypatch):
    got = read_records([
        b'4,812,5123456,-;lego-ev3-uart: ttyS1:ev3-ports:in1: mode \\x5c2V4 not confirmed\n',
        b'6,813,5123999,-;a\\x0ab \\x09tab \\xc3\\xa9\n SUBSYSTEM=tty\n DEVICE=c4:65\n',
    ], monkeypatch)
    assert got == [(5.123456, 'lego-ev3-uart: ttyS1:ev3-ports:in1: mode \\2V4 not confirmed'),
                   (5.123999, 'a\nb \ttab \u00e9')]


def test_plain_text_unchanged(monkeypatch):
    got = read_records([b'6,1,7,-;nothing to undo: x5c \\ alone\n'], monkeypatch)
    assert got == [(7e-06, 'nothing to undo: x5c \\ alone')]
