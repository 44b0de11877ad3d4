#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""Write one source file of this repository as it goes into a kernel tree.

    intree.py --have "FLAG ..." SRC DST

The out-of-tree build keeps every difference between the kernels it
supports in drivers/lego/lego_compat.h, chosen by the LEGO_HAVE_* flags the
top-level Kbuild probes. A kernel tree needs none of it, so each shim is
replaced by what it stands for in the target tree, whose flags are given
with --have (tools/upstream/lib.sh's up_have runs the same probes on it):

- the line '#include "lego_compat.h"' goes; the headers it supplied that
  the file uses are included instead, in the file's first block of
  '#include <...>' lines, in order: <kunit/visibility.h> for
  EXPORT_SYMBOL_IF_KUNIT(), <linux/unaligned.h> for the unaligned
  accessors (before 6.12 <asm/unaligned.h>, in a block of its own after
  that one, as IIO drivers have it);
- LEGO_TTY_FLAG, LEGO_TTY_COUNT, LEGO_TTY_WRITE_RET, LEGO_UEVENT_CONST,
  LEGO_BIN_ATTR, LEGO_BIN_ATTR_CONST, LEGO_ATTR_CONST, LEGO_GROUP_ATTRS, LEGO_CLASS_CONST,
  LEGO_I2C_XFER, LEGO_IMPORT_KUNIT_NS() and lego_assign_str() become the
  kernel's types, qualifiers, fields and macros, as lego_compat.h defines
  them for those flags;
- the current kernel API the code is written against is turned back into
  the target's where the target predates it: hrtimer_setup() into
  hrtimer_init() and a ->function assignment (before 6.13),
  timer_container_of() into from_timer() (before 6.16), timer_delete*()
  into del_timer*() (before 6.2), KUNIT_EXPECT_MEMEQ(test, a, b, n) into
  KUNIT_EXPECT_EQ(test, memcmp(a, b, n), 0) (before 6.2),
  system_dfl_wq and system_percpu_wq into system_unbound_wq and system_wq,
  iio_push_to_buffers_with_ts(d, p, size, ts) into
  iio_push_to_buffers_with_timestamp(d, p, ts) (before 6.16),
  iio_for_each_active_channel(d, ch) into for_each_set_bit() over the
  device's active_scan_mask and masklength (before 6.12), kzalloc_obj(obj,
  gfp) into kzalloc(sizeof(obj), gfp) where the tree has no kzalloc_obj();
- unifdef -DN_LEGOEV3 -DN_LEGONXT: the uapi headers' fallback ldisc
  numbers go, the tree reserves them in <linux/tty.h>.

A documentation page (.rst) keeps what it says about the drivers and loses
what it says about this repository's package (its tools, udev rules,
tests): the lines from '.. out-of-tree-begin' to '.. out-of-tree-end' go,
and a comment '.. in-tree' is replaced by its indented block, dedented
(both are comments to Sphinx, so the package's own pages show the
out-of-tree text and not the in-tree one). @N_LEGOEV3@ is the number the
tree gives the EV3 line discipline (--ldisc), @N_LEGONXT@ the next one, and :doc:`page` a link to another
page of Documentation/lego, which must have a place in the tree.

In every file, each path that tools/upstream/places.py gives a place in the
tree (a directory of drivers/lego, a page of Documentation/lego) is
replaced by that place. A page of Documentation/lego that has none must
not be named: it stays out of the tree.

Anything left that belongs to the shims (a LEGO_HAVE_, LEGO_TTY_,
LEGO_UEVENT_, LEGO_IMPORT_ name or one of the qualifier macros above,
lego_compat, lego_assign_str) is an error: a new shim needs a rule here.
"""
import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from places import map_paths, place  # noqa: E402

LEGO_DOCS = os.path.join(HERE, '..', '..', 'Documentation', 'lego')

LEFTOVER = re.compile(r'lego_compat|\bLEGO_(HAVE|TTY|UEVENT|IMPORT)_?\w*|lego_assign_str|lego_hrtimer'
                      r'|\bLEGO_(BIN_ATTR|BIN_ATTR_CONST|ATTR_CONST|GROUP_ATTRS|CLASS_CONST|I2C_XFER)\b')


def die(msg):
    sys.exit('intree.py: ' + msg)


def add_includes(text, headers):
    """Insert '#include <h>' lines into the first block of angle includes."""
    lines = text.split('\n')
    block = [i for i, ln in enumerate(lines) if ln.startswith('#include <')]
    for h in headers:
        inc = '#include <%s>' % h
        if inc in lines:
            continue
        if not block:
            die('no #include <...> block to put <%s> in' % h)
        # The first block: consecutive lines from the first angle include.
        first = block[0]
        end = first
        while end + 1 < len(lines) and lines[end + 1].startswith('#include <'):
            end += 1
        at = end + 1
        if h.startswith('asm/'):
            # After the block, apart.
            lines[at:at] = ['', inc]
            block = [i for i, ln in enumerate(lines) if ln.startswith('#include <')]
            continue
        for i in range(first, end + 1):
            name = lines[i][len('#include <'):].rstrip('>')
            # kunit/ sorts before linux/; within linux/, alphabetically,
            # ahead of an out-of-order uapi header at the end.
            if name > h:
                at = i
                break
        lines.insert(at, inc)
        block = [i for i, ln in enumerate(lines) if ln.startswith('#include <')]
    return '\n'.join(lines)


def drop_compat_include(text, have):
    text = '\n'.join(ln for ln in text.split('\n')
                     if ln.strip() != '#include "lego_compat.h"')
    need = []
    if re.search(r'\b(EXPORT_SYMBOL_IF_KUNIT|VISIBLE_IF_KUNIT)\b', text):
        need.append('kunit/visibility.h')
    if re.search(r'\b(get|put)_unaligned', text):
        need.append('linux/unaligned.h' if 'LINUX_UNALIGNED' in have else 'asm/unaligned.h')
    return add_includes(text, need)


def hrtimer_init_back(m):
    indent, timer, func, clock, mode = (m.group(i).strip() if i > 1 else m.group(i)
                                        for i in range(1, 6))
    if not timer.startswith('&'):
        die('hrtimer_setup() on something other than &timer: ' + timer)
    call = '%shrtimer_init(%s, %s, %s);' % (indent, timer, clock, mode)
    if len(call.expandtabs(8)) > 100:
        die('hrtimer_init() line too long: ' + call)
    return '%s\n%s%s.function = %s;' % (call, indent, timer[1:], func)


def push_with_ts_back(m):
    """iio_push_to_buffers_with_ts(d, p, size, ts) as ..._with_timestamp(d, p, ts)."""
    indent, dev, data, ts = m.group(1), m.group(2), m.group(3), m.group(4).strip()
    call = '%siio_push_to_buffers_with_timestamp(%s, %s, %s);' % (indent, dev, data, ts)
    if len(call.expandtabs(8)) <= 100:
        return call
    head = '%siio_push_to_buffers_with_timestamp(%s, %s,' % (indent, dev, data)
    col = len(head.split(',')[0].expandtabs(8)) - len(dev)
    return '%s\n%s%s);' % (head, '\t' * (col // 8) + ' ' * (col % 8), ts)


def memeq_back(text):
    """KUNIT_EXPECT_MEMEQ(test, a, b, n) as KUNIT_EXPECT_EQ() of a memcmp()."""
    out = []
    pos = 0
    for m in re.finditer(r'\bKUNIT_EXPECT_MEMEQ\(', text):
        if m.start() < pos:
            continue
        # The arguments, split at the commas outside parentheses.
        depth, args, arg, i = 1, [], '', m.end()
        while depth:
            if i == len(text):
                die('KUNIT_EXPECT_MEMEQ( without its closing parenthesis')
            ch = text[i]
            i += 1
            depth += {'(': 1, '[': 1, ')': -1, ']': -1}.get(ch, 0)
            if depth == 1 and ch == ',':
                args.append(arg.strip())
                arg = ''
            elif depth:
                arg += ch
        args.append(arg.strip())
        if len(args) != 4 or '\n' in text[m.start():i]:
            die('KUNIT_EXPECT_MEMEQ() other than on one line with 4 arguments')
        out += [text[pos:m.start()],
                'KUNIT_EXPECT_EQ(%s, memcmp(%s), 0)' % (args[0], ', '.join(args[1:]))]
        pos = i
    text = ''.join(out) + text[pos:]
    for ln in text.split('\n'):
        if 'KUNIT_EXPECT_EQ' in ln and 'memcmp' in ln and len(ln.expandtabs(8)) > 100:
            die('KUNIT_EXPECT_EQ(memcmp()) line too long: ' + ln.strip())
    return text


def transform(text, have):
    text = drop_compat_include(text, have)
    rx = 'TTY_RX_SIZE_T' in have
    subs = [
        (r'\bLEGO_TTY_FLAG\b', 'u8' if rx else 'char'),
        (r'\bLEGO_TTY_COUNT\b', 'size_t' if rx else 'int'),
        (r'\bLEGO_TTY_WRITE_RET\b', 'ssize_t' if 'TTY_WRITE_SSIZE_T' in have else 'int'),
        (r'\bLEGO_UEVENT_CONST ', 'const ' if 'CONST_UEVENT' in have else ''),
        (r'\bLEGO_BIN_ATTR\b', 'const struct bin_attribute' if 'CONST_BIN_ATTR' in have
         else 'struct bin_attribute'),
        (r'\bLEGO_BIN_ATTR_CONST ', 'const ' if 'CONST_BIN_ATTR' in have else ''),
        (r'\bLEGO_ATTR_CONST ', 'const ' if 'ATTRS_CONST' in have else ''),
        (r'\bLEGO_GROUP_ATTRS\b', 'attrs_const' if 'ATTRS_CONST' in have else 'attrs'),
        (r'\bLEGO_CLASS_CONST ', 'const ' if 'CONST_CLASS' in have else ''),
        (r'\bLEGO_I2C_XFER\b', 'xfer' if 'I2C_ALGO_XFER' in have else 'master_xfer'),
        (r'\bLEGO_IMPORT_KUNIT_NS\(\)',
         'MODULE_IMPORT_NS(EXPORTED_FOR_KUNIT_TESTING)' if 'IDENT_NS' in have
         else 'MODULE_IMPORT_NS("EXPORTED_FOR_KUNIT_TESTING")'),
        (r'\blego_assign_str\((\w+), *(\w+)\)',
         r'__assign_str(\1)' if 'ASSIGN_STR_1' in have else r'__assign_str(\1, \2)'),
    ]
    if 'TIMER_CONTAINER_OF' not in have:
        subs.append((r'\btimer_container_of\(', 'from_timer('))
    if 'TIMER_DELETE' not in have:
        subs += [(r'\btimer_delete_sync\(', 'del_timer_sync('), (r'\btimer_delete\(', 'del_timer(')]
    if 'KZALLOC_OBJ' not in have:
        subs.append((r'\bkzalloc_obj\(([^,()]+), ', r'kzalloc(sizeof(\1), '))
    if 'SYSTEM_DFL_WQ' not in have:
        subs += [(r'\bsystem_dfl_wq\b', 'system_unbound_wq'), (r'\bsystem_percpu_wq\b', 'system_wq')]
    if 'IIO_ACTIVE_CHANNELS' not in have:
        subs.append((r'\biio_for_each_active_channel\(([\w>-]+), (\w+)\)',
                     r'for_each_set_bit(\2, \1->active_scan_mask, \1->masklength)'))
    for pat, rep in subs:
        text = re.sub(pat, rep, text)
    if 'IIO_PUSH_WITH_TS' not in have:
        text = re.sub(r'^([ \t]*)iio_push_to_buffers_with_ts\(([^,]+), ([^,]+), [^,]+,\s*([^;]+)\);',
                      push_with_ts_back, text, flags=re.M)
    if 'KUNIT_MEMEQ' not in have:
        text = memeq_back(text)
    if 'HRTIMER_SETUP' not in have:
        text = re.sub(r'^([ \t]*)hrtimer_setup\(([^,]+),([^,]+),([^,]+),([^;]+)\);',
                      hrtimer_init_back, text, flags=re.M)
    return text


def indent_of(line):
    return len(line) - len(line.lstrip(' '))


def rst_transform(text, ldisc):
    """A page of Documentation/lego as it goes into the tree."""
    lines = text.split('\n')
    out = []
    skipping = False
    i = 0
    while i < len(lines):
        ln = lines[i]
        s = ln.strip()
        i += 1
        if s == '.. out-of-tree-begin':
            if skipping:
                die('line %d: out-of-tree-begin inside another' % i)
            skipping = True
        elif s == '.. out-of-tree-end':
            if not skipping:
                die('line %d: out-of-tree-end without a begin' % i)
            skipping = False
        elif skipping:
            pass
        elif s == '.. in-tree':
            base = indent_of(ln)
            block = []
            while i < len(lines) and (not lines[i].strip() or indent_of(lines[i]) > base):
                block.append(lines[i])
                i += 1
            body = [b for b in block if b.strip()]
            if not body:
                die('line %d: an empty in-tree block' % i)
            cut = min(indent_of(b) for b in body) - base
            out.extend(b[cut:] if b.strip() else '' for b in block)
        else:
            out.append(ln)
    if skipping:
        die('an out-of-tree-begin without its end')
    text = '\n'.join(out)
    if ldisc is not None:
        text = text.replace('@N_LEGOEV3@', str(ldisc))
        text = text.replace('@N_LEGONXT@', str(ldisc + 1))

    def doc(m):
        p = place('Documentation/lego/%s.rst' % m.group(1))
        if p is None:
            die(':doc:`%s` in the tree: that page stays out of it' % m.group(1))
        return p
    text = re.sub(r':doc:`([\w-]+)`', doc, text)
    # Nothing of the package is left: no placeholder, no :doc: link, no
    # page of Documentation/lego named by its file name alone ("see
    # tracing.rst"), which means nothing in the tree.
    m = re.search(r'@\w+@|:doc:`', text)
    if m:
        die('"%s" left in the page' % m.group(0))
    ours = set(os.listdir(LEGO_DOCS))
    for m in re.finditer(r'(?<![\w/.-])([\w-]+\.rst)\b', text):
        if m.group(1) in ours:
            die('"%s" named in the page: name it with :doc:' % m.group(1))
    return re.sub(r'\n\n\n+', '\n\n', text).rstrip('\n') + '\n'


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--have', default='', help='the target tree\'s LEGO_HAVE_* flags, without the prefix')
    ap.add_argument('--ldisc', type=int, help='the line discipline number the tree reserves')
    ap.add_argument('src')
    ap.add_argument('dst')
    a = ap.parse_args()
    have = set(a.have.split())
    with open(a.src, encoding='utf-8') as f:
        text = f.read()
    if a.src.endswith(('.c', '.h')):
        text = transform(text, have)
        # unifdef exits 0 (unchanged), 1 (changed) or 2 (trouble).
        r = subprocess.run(['unifdef', '-DN_LEGOEV3', '-DN_LEGONXT'], input=text, capture_output=True,
                           text=True, check=False)
        if r.returncode not in (0, 1):
            die('unifdef on %s: %s' % (a.src, r.stderr.strip()))
        # No two blank lines where a line or a block was taken out (kernel
        # style has none anyway).
        text = re.sub(r'\n\n\n+', '\n\n', r.stdout)
        m = LEFTOVER.search(text)
        if m:
            die('%s: "%s" left after the in-tree rules: add a rule' % (a.src, m.group(0)))
    elif a.src.endswith('.rst'):
        text = rst_transform(text, a.ldisc)
    text = map_paths(text)
    if 'Documentation/lego/' in text:
        die('%s names a page of Documentation/lego that stays out of the tree' % a.src)
    with open(a.dst, 'w', encoding='utf-8') as f:
        f.write(text)


if __name__ == '__main__':
    main()
