"""tools/python's nxt-python backend on the host, without a brick: it
refuses what is not a brick's /dev/nxtN of lego_nxt (a character device
whose driver knows the lego_nxt ioctls and whose class is lego-nxt in sysfs) with
ENODEV and a message that says so, instead of sending telegrams into
/dev/null and failing later in nxt-python with struct.error. The bricks
themselves: tests/guest/test_nxt_python.py.

  python3 -m pytest -v tests/packaging/test_python_backend.py
"""
import errno
import logging
import os
import sys

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
sys.path.insert(0, os.path.join(TOP, 'tools/python'))

backend = pytest.importorskip('lego_nxt_linux.backend')


@pytest.fixture
def regular_file(tmp_path):
    p = tmp_path / 'nxt0'
    p.write_bytes(b'')
    return str(p)


@pytest.mark.parametrize('path,why', [
    ('/dev/null', 'does not know the lego_nxt ioctls'),
    ('/dev/zero', 'does not know the lego_nxt ioctls'),
    (None, 'not a character device'),
])
def test_connect_refuses_what_is_not_a_brick(path, why, regular_file):
    path = path or regular_file
    sock = backend.DevNodeSock(path)
    with pytest.raises(OSError) as e:
        sock.connect()
    assert e.value.errno == errno.ENODEV, e.value
    assert '%s is not an NXT brick of lego_nxt' % path in str(e.value), e.value
    assert why in str(e.value), e.value
    # Nothing left open.
    assert sock._fd is None


def test_find_skips_a_node_that_is_not_a_brick(caplog):
    b = backend.Backend(devices=['/dev/null'])
    with caplog.at_level(logging.WARNING, logger=backend.__name__):
        assert list(b.find()) == []
    assert 'is not an NXT brick' in caplog.text, caplog.text


def test_get_timeout_ioctl_number():
    """_IOR(0xE4, 0x02, __u32) of include/uapi/linux/lego_nxt.h."""
    assert backend.NXT_IOC_GET_TIMEOUT == 0x8004E402
    assert backend.NXT_IOC_SET_TIMEOUT == 0x4004E401
