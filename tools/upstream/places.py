#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""Where this repository's files go in a kernel tree.

    places.py PATH...   prints each PATH's place in the tree

tools/upstream/series.sh puts the files there, and tools/upstream/intree.py
rewrites every mention of one of these paths (in a comment, an ABI file, a
documentation page) into its place, so that what names a file in this
repository names the same file in the tree.
"""
import re
import sys

# (this repository's path, its place in the tree); a directory ends in /.
PLACES = (
    ('drivers/lego/ev3/', 'drivers/iio/common/lego_ev3_uart/'),
    ('drivers/lego/nxt/', 'drivers/usb/misc/lego_nxt/'),
    ('Documentation/lego/ev3-uart.rst', 'Documentation/iio/lego_ev3_uart.rst'),
    ('Documentation/lego/nxt-usb.rst', 'Documentation/usb/lego_nxt.rst'),
    ('Documentation/lego/nxt-bluetooth.rst', 'Documentation/usb/lego_nxt_bluetooth.rst'),
    ('Documentation/lego/nxt-i2c.rst', 'Documentation/usb/lego_nxt_i2c.rst'),
    ('Documentation/lego/tracing.rst', 'Documentation/trace/events-lego.rst'),
)

_PATH = re.compile('|'.join(re.escape(src) for src, _ in PLACES))


def place(path):
    """PATH's place in the tree, or None if it has none."""
    for src, dst in PLACES:
        if path == src or (src.endswith('/') and path.startswith(src)):
            return dst + path[len(src):]
        if path == src.rstrip('/'):  # the directory, named without its /
            return dst.rstrip('/')
    return None


def map_paths(text):
    """TEXT with every path of PLACES in it replaced by its place."""
    return _PATH.sub(lambda m: place(m.group(0)), text)


def main():
    for path in sys.argv[1:]:
        p = place(path)
        if p is None:
            sys.exit('places.py: %s has no place in the tree' % path)
        print(p)


if __name__ == '__main__':
    main()
