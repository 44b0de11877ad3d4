# SPDX-License-Identifier: GPL-3.0-or-later
"""An nxt-python backend over the lego_nxt character devices.

lego_nxt gives each NXT brick, on USB (lego_nxt_usb) or on Bluetooth
(lego_nxt_serial), a node ``/dev/nxtN`` that carries
raw telegrams: one ``write()`` sends one telegram (one USB packet), and
when the telegram asks for a reply the next ``read()`` on the same open
file returns the whole reply, or fails with ``ETIMEDOUT`` after the file's
reply timeout (1 s by default). That is the I/O pattern of nxt-python's
own ``usb`` backend, so :class:`DevNodeSock` has the same interface and
the same USB chunking, and :class:`Backend` plugs into the locator::

    import nxt.locator
    import lego_nxt_linux

    with nxt.locator.find(backends=[lego_nxt_linux.get_backend()]) as b:
        print(b.get_device_info())

Only nxt-python's public backend interface is used: a backend object has
``find(**filters)`` yielding :class:`nxt.brick.Brick` objects, and a brick
talks through an object with ``send``, ``recv``, ``close``, ``bsize`` and
``type``.
"""
import errno
import fcntl
import glob
import logging
import os
import re
import stat
import struct

import nxt.brick

__all__ = ["Backend", "DevNodeSock", "get_backend", "list_devices"]

logger = logging.getLogger(__name__)

DEV_DIR = "/dev"
SYSFS_CLASS = "/sys/class/lego-nxt"
#: The class of the nodes, whatever the brick's link (lego_nxt_usb,
#: lego_nxt_serial): every device in it is a brick of the lego_nxt core.
CLASS = "lego-nxt"

#: Longest telegram and reply: one full-speed bulk packet.
TELEGRAM_MAX = 64

#: _IOW(0xE4, 0x01, __u32) from include/uapi/linux/lego_nxt.h.
NXT_IOC_SET_TIMEOUT = (1 << 30) | (4 << 16) | (0xE4 << 8) | 0x01
#: _IOR(0xE4, 0x02, __u32): sends nothing, works on any open file of ours.
NXT_IOC_GET_TIMEOUT = (2 << 30) | (4 << 16) | (0xE4 << 8) | 0x02
TIMEOUT_MAX_MS = 60000

_NODE_RE = re.compile(r"^nxt([0-9]+)$")


def _sysfs_dir(path):
    """The sysfs directory of a node (/sys/class/lego-nxt/nxtN, where the
    driver's attributes are), or None if it is not ours.

    `path` may be a symbolic link such as /dev/nxt/by-serial/001653XXXXXX.
    """
    base = os.path.basename(os.path.realpath(path))
    if not _NODE_RE.match(base):
        return None
    node = os.path.join(SYSFS_CLASS, base)
    return node if _class_of(node) == CLASS else None


def _class_of(sysdir):
    """The class of a device's sysfs directory, or None."""
    try:
        return os.path.basename(os.readlink(os.path.join(sysdir, "subsystem")))
    except OSError:
        return None


def _check_node(fd, filename):
    """Raise OSError unless fd is a brick's node (/dev/nxtN).

    A char device whose driver answers NXT_IOC_GET_TIMEOUT, and which sysfs
    shows in the class lego-nxt (on USB or Bluetooth): anything else
    (/dev/null, a file, a tty) would take the telegrams and fail later,
    obscurely.
    """
    def refuse(why, err=errno.ENODEV):
        raise OSError(err, "%s is not an NXT brick of lego_nxt (%s); "
                      "the bricks are /dev/nxtN" % (filename, why))

    st = os.fstat(fd)
    if not stat.S_ISCHR(st.st_mode):
        refuse("not a character device")
    try:
        fcntl.ioctl(fd, NXT_IOC_GET_TIMEOUT, b"\0" * 4)
    except OSError as e:
        refuse("its driver does not know the lego_nxt ioctls: %s" % os.strerror(e.errno))
    sysdev = "/sys/dev/char/%d:%d" % (os.major(st.st_rdev), os.minor(st.st_rdev))
    if os.path.isdir("/sys/dev/char"):
        cls = _class_of(sysdev)
        if cls != CLASS:
            refuse("its class is %s" % (cls or "unknown"))


def _read_attr(directory, name):
    try:
        with open(os.path.join(directory, name)) as f:
            return f.read().strip()
    except OSError as e:
        logger.debug("cannot read %s/%s: %s", directory, name, e)
        return None


def list_devices():
    """The nodes of the bricks lego_nxt has, in number order.

    :return: Paths such as ``["/dev/nxt0", "/dev/nxt1"]``.
    :rtype: list[str]
    """
    found = []
    for d in glob.glob(os.path.join(SYSFS_CLASS, "nxt*")):
        m = _NODE_RE.match(os.path.basename(d))
        node = os.path.join(DEV_DIR, os.path.basename(d))
        if m and os.path.exists(node) and _sysfs_dir(node):
            found.append((int(m.group(1)), node))
    return [node for _, node in sorted(found)]


def _normal_address(host):
    """'00:16:53:0a:0b:0c', '0016530A0B0C'... -> '0016530A0B0C'."""
    return re.sub(r"[^0-9A-Fa-f]", "", host).upper()


def _may_match(node, name, host):
    """False when the sysfs attributes show that the brick cannot match.

    The host filter compares the USB serial, which is the brick's Bluetooth
    address and costs no transaction; the name filter reads brick_name,
    which costs none either: the driver shows the name from the last
    GetDeviceInfo reply a user of the brick got, and ENODATA before.
    Unreadable attributes do not exclude a brick: the locator checks both
    filters again with GetDeviceInfo on the bricks this backend returns.
    """
    sysfs = _sysfs_dir(node)
    if sysfs is None:
        return True
    if host is not None:
        # The USB device's serial: the parent of the node's interface.
        serial = _read_attr(os.path.join(sysfs, "device", ".."), "serial")
        if serial is not None and _normal_address(serial) != _normal_address(host):
            logger.debug("%s: address %s is not %s", node, serial, host)
            return False
    if name is not None:
        bname = _read_attr(sysfs, "brick_name")
        if bname is not None and bname != name:
            logger.debug("%s: name %r is not %r", node, bname, name)
            return False
    return True


class DevNodeSock:
    """A connection to one brick through its ``/dev/nxtN`` node."""

    #: File I/O chunk. A Read of n bytes is answered with at most 58 data
    #: bytes over USB (the reply is one 64-byte packet) while the firmware
    #: moves on in the file by n, so chunks stay at 58; a Write telegram of
    #: 58 data bytes is 61 bytes long and fits a packet too.
    bsize = 58

    #: Connection type: the latency class nxt-python's motor code uses.
    type = "usb"

    def __init__(self, filename, timeout_ms=None):
        self.filename = filename
        self.timeout_ms = timeout_ms
        self._fd = None

    def __str__(self):
        return "lego_nxt (%s)" % self.filename

    def connect(self):
        """Open the node.

        :return: Connected brick.
        :rtype: nxt.brick.Brick
        :raises OSError: When the node cannot be opened, is not a brick's
           node of lego_nxt (``ENODEV``), or the timeout cannot be set.
        """
        logger.info("connecting via %s", self)
        fd = os.open(self.filename, os.O_RDWR | os.O_CLOEXEC)
        try:
            _check_node(fd, self.filename)
            if self.timeout_ms is not None:
                fcntl.ioctl(fd, NXT_IOC_SET_TIMEOUT, struct.pack("I", self.timeout_ms))
        except OSError:
            os.close(fd)
            raise
        self._fd = fd
        return nxt.brick.Brick(self)

    def close(self):
        """Close the node."""
        if self._fd is not None:
            logger.info("closing %s connection", self)
            os.close(self._fd)
            self._fd = None

    def _check_open(self):
        if self._fd is None:
            raise OSError(errno.EBADF, "%s is closed" % self)

    def send(self, data):
        """Send one telegram.

        :param bytes data: The telegram, type byte first, 2 to 64 bytes.
        :raises OSError: As the driver fails the write (``EMSGSIZE`` for a
           telegram over 64 bytes, ``ENODEV`` once the brick is unplugged...).
        """
        self._check_open()
        logger.debug("send: %s", data.hex())
        n = os.write(self._fd, data)
        if n != len(data):
            raise OSError(errno.EIO, "%s took %d of %d bytes" % (self, n, len(data)))

    def recv(self):
        """Receive the reply to the last telegram sent.

        :return: The whole reply telegram.
        :rtype: bytes
        :raises OSError: ``ETIMEDOUT`` when the brick did not answer within the
           file's timeout, ``EPROTO`` when the answer was not a valid reply.
        """
        self._check_open()
        data = os.read(self._fd, TELEGRAM_MAX)
        logger.debug("recv: %s", data.hex())
        return data


class Backend:
    """Backend for the bricks of the lego_nxt kernel driver, on USB or
    Bluetooth.

    :param devices: Nodes to try instead of every ``/dev/nxtN`` (a symbolic
       link such as ``/dev/nxt/by-serial/001653XXXXXX`` works too).
    :param timeout_ms: Reply timeout for the opened files (1 to 60000 ms),
       ``None`` for the driver's default of 1000 ms.
    """

    def __init__(self, devices=None, timeout_ms=None):
        if timeout_ms is not None and not 1 <= timeout_ms <= TIMEOUT_MAX_MS:
            raise ValueError("timeout_ms must be 1 to %d" % TIMEOUT_MAX_MS)
        self.devices = list(devices) if devices is not None else None
        self.timeout_ms = timeout_ms

    def find(self, name=None, host=None, filename=None, **kwargs):
        """Find bricks through their ``/dev/nxtN`` nodes.

        :param name: Brick name (example: ``"NXT"``).
        :param host: Bluetooth address (example: ``"00:16:53:01:02:03"``).
        :param filename: A node to use; ignored unless lego_nxt owns it
           (the devfile backend takes the same keyword for ``/dev/rfcomm*``).
        :param kwargs: Other parameters are ignored.
        :return: Iterator over the bricks found.
        :rtype: Iterator[nxt.brick.Brick]
        """
        if filename and _sysfs_dir(filename):
            nodes = [filename]
        elif self.devices is not None:
            nodes = self.devices
        else:
            nodes = list_devices()
        for node in nodes:
            if not _may_match(node, name, host):
                continue
            sock = DevNodeSock(node, self.timeout_ms)
            try:
                brick = sock.connect()
            except OSError as e:
                # EACCES: see the group and udev rule in the documentation.
                logger.warning("cannot use %s: %s", node,
                               e.strerror or os.strerror(e.errno or errno.EIO))
                continue
            yield brick


def get_backend(**kwargs):
    """Get a backend instance, for ``nxt.locator.find(backends=[...])``.

    :param kwargs: Given to :class:`Backend`.
    :rtype: Backend
    """
    return Backend(**kwargs)
