# SPDX-License-Identifier: GPL-2.0
"""tools/upstream/intree.py and places.py: what a file becomes in the tree.

Quick host tests, part of `make check`: `make upstream-check` (not part of
it) runs the whole series through the kernel's own checks, but these catch
an edit of a page or a comment that would break the series' generation.
"""
import os
import re
import subprocess
import sys

import pytest

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
UP = os.path.join(TOP, 'tools', 'upstream')
sys.path.insert(0, UP)

import intree  # noqa: E402
import places  # noqa: E402

PAGES = ['Documentation/lego/ev3-uart.rst', 'Documentation/lego/nxt-usb.rst',
         'Documentation/lego/nxt-i2c.rst', 'Documentation/lego/tracing.rst']


def run_intree(tmp_path, name, text, *args):
    src = tmp_path / name
    dst = tmp_path / ('out-' + name)
    src.write_text(text)
    r = subprocess.run([sys.executable, os.path.join(UP, 'intree.py'), *args, str(src), str(dst)],
                       capture_output=True, text=True, check=False)
    return r, (dst.read_text() if r.returncode == 0 else None)


def test_places():
    assert places.place('drivers/lego/ev3/ev3_uart_core.h') == \
        'drivers/iio/common/lego_ev3_uart/ev3_uart_core.h'
    assert places.place('drivers/lego/nxt') == 'drivers/usb/misc/lego_nxt'
    assert places.place('Documentation/lego/tracing.rst') == 'Documentation/trace/events-lego.rst'
    assert places.place('Documentation/lego/testing.rst') is None
    assert places.map_paths('see Documentation/lego/nxt-usb.rst; drivers/lego/ev3/x.c') == \
        'see Documentation/usb/lego_nxt.rst; drivers/iio/common/lego_ev3_uart/x.c'


def test_rst_blocks(tmp_path):
    text = '''Title
=====

Kept, see :doc:`tracing`.

.. out-of-tree-begin

Gone: ``tools/udev/x.rules``.

.. out-of-tree-end

.. in-tree

   Number @N_LEGOEV3@::

       ldattach @N_LEGOEV3@ /dev/ttyS1

- item

  .. in-tree

     nested in-tree text

End.
'''
    r, out = run_intree(tmp_path, 'p.rst', text, '--ldisc', '31')
    assert r.returncode == 0, r.stderr
    assert 'Gone' not in out and 'out-of-tree' not in out and '.. in-tree' not in out
    assert 'Kept, see Documentation/trace/events-lego.rst.' in out
    assert '\nNumber 31::\n\n    ldattach 31 /dev/ttyS1\n' in out
    assert '\n- item\n\n  nested in-tree text\n' in out
    assert '\n\n\n' not in out and out.endswith('End.\n')


@pytest.mark.parametrize('text, why', [
    ('.. out-of-tree-begin\n\nx\n', 'without its end'),
    ('x\n\n.. out-of-tree-end\n', 'without a begin'),
    ('.. out-of-tree-begin\n\n.. out-of-tree-begin\n\n.. out-of-tree-end\n', 'inside another'),
    ('see :doc:`testing`\n', 'stays out of it'),
    ('see ``tracing.rst``\n', 'name it with :doc:'),
    ('.. in-tree\n\n   n @N_LEGOEV3@\n', 'left in the page'),
])
def test_rst_errors(tmp_path, text, why):
    r, _ = run_intree(tmp_path, 'p.rst', text)
    assert r.returncode != 0
    assert why in r.stderr


def test_c_comment_paths(tmp_path):
    have = ('--have', 'KUNIT_MEMEQ')
    r, out = run_intree(tmp_path, 'x.c', '#include <linux/x.h>\n\n/* Documentation/lego/ev3-uart.rst */\n',
                        *have)
    assert r.returncode == 0, r.stderr
    assert '/* Documentation/iio/lego_ev3_uart.rst */' in out
    r, _ = run_intree(tmp_path, 'y.c', '/* Documentation/lego/testing.rst */\n', *have)
    assert r.returncode != 0 and 'stays out of the tree' in r.stderr


@pytest.mark.parametrize('have, member', [('I2C_ALGO_XFER', 'xfer'), ('', 'master_xfer')])
def test_i2c_algorithm_member(tmp_path, have, member):
    """LEGO_I2C_XFER is the tree's name of the transfer member."""
    src = ('#include <linux/i2c.h>\n\nstatic const struct i2c_algorithm a = {\n'
           '\t.LEGO_I2C_XFER = f,\n};\n')
    r, out = run_intree(tmp_path, 'a.c', src, '--have', have + ' KUNIT_MEMEQ')
    assert r.returncode == 0, r.stderr
    assert '\t.%s = f,\n' % member in out and 'LEGO_' not in out


@pytest.mark.parametrize('page', PAGES)
def test_pages_go_into_the_tree(tmp_path, page):
    """The real pages: nothing of the package is left in their in-tree text."""
    with open(os.path.join(TOP, page), encoding='utf-8') as f:
        src = f.read()
    out = intree.rst_transform(src, 31)
    out = places.map_paths(out)
    assert len(out) > 0.6 * len(src)
    for word in ('tools/udev', 'lego-sensors', 'nxtctl', 'tests/', 'N_DEVELOPMENT',
                 'Documentation/lego/', '.. out-of-tree', '.. in-tree'):
        assert word not in out, word
    # Every path it names is one of the tree's (or a sysfs/dev path).
    for p in re.findall(r'(?<![\w/.<-])(?:Documentation|drivers|include)/[\w./-]*\w', out):
        assert not p.startswith(('drivers/lego', 'Documentation/lego')), p
