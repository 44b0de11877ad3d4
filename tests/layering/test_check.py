"""tests/layering/check.py can fail: a tree of small objects built with the
host's compiler, laid out as the EV3 driver's, passes; each of the faults
the check is for, planted in a copy, fails it with its message.

  python3 -m pytest -q tests/layering
"""
import os
import shutil
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
CHECK = os.path.join(HERE, 'check.py')

# transport -> core <- views, the transport registering the views: no circle.
GOOD = {
    'ev3_uart_ldisc.c': 'void core_rx(void); void class_init(void); void iio_init(void);\n'
                        'void ldisc_send(void)\n{\n}\n'
                        'void ldisc_rx(void)\n{\n\tcore_rx();\n\tclass_init();\n\tiio_init();\n}\n',
    'ev3_uart_core.c': 'void core_rx(void)\n{\n}\nint core_get(void)\n{\n\treturn 1;\n}\n',
    'ev3_uart_class.c': 'int core_get(void);\nvoid class_init(void)\n{\n\tcore_get();\n}\n',
    'ev3_uart_iio.c': 'int core_get(void);\nvoid iio_init(void)\n{\n\tcore_get();\n}\n',
}


def run(tmp_path, files):
    src = tmp_path / 'src/drivers/lego/ev3'
    obj = tmp_path / 'build/drivers/lego/ev3'
    for d in (src, obj):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
    for name, text in files.items():
        (src / name).write_text(text)
    for name in files:
        if name.endswith('.c'):
            subprocess.run(['cc', '-c', '-o', str(obj / name.replace('.c', '.o')),
                            str(src / name)], check=True)
    r = subprocess.run([sys.executable, CHECK, str(tmp_path / 'build'), '--driver', 'ev3',
                        '--src', str(tmp_path / 'src')], capture_output=True, text=True)
    return r.returncode, r.stdout + r.stderr


@pytest.fixture
def good(tmp_path):
    rc, out = run(tmp_path, GOOD)
    assert rc == 0 and 'layering: 0 problem(s)' in out, out
    return dict(GOOD)


def test_a_circle_fails(tmp_path, good):
    good['ev3_uart_core.c'] += 'void class_init(void);\nvoid core_tick(void)\n{\n\tclass_init();\n}\n'
    rc, out = run(tmp_path, good)
    assert rc == 1 and 'a circle: ev3_uart_class.o <-> ev3_uart_core.o' in out, out


def test_a_view_using_its_transport_fails(tmp_path, good):
    good['ev3_uart_iio.c'] += 'void ldisc_send(void);\nvoid iio_tx(void)\n{\n\tldisc_send();\n}\n'
    rc, out = run(tmp_path, good)
    assert rc == 1 and 'the view ev3_uart_iio.o uses its transport ev3_uart_ldisc.o' in out, out


def test_a_long_function_fails(tmp_path, good):
    body = ''.join('\tx += %d;\n' % i for i in range(58))
    good['ev3_uart_core.c'] += 'int core_long(int x)\n{\n%s\treturn x;\n}\n' % body
    rc, out = run(tmp_path, good)
    assert rc == 1 and 'core_long() is 61 lines (at most 60)' in out, out
    good['ev3_uart_core.c'] = good['ev3_uart_core.c'].replace('\tx += 0;\n', '')
    rc, out = run(tmp_path, good)
    assert rc == 0, out


def test_a_view_including_the_transport_header_fails(tmp_path, good):
    good['ev3_uart_ldisc.h'] = '/* the discipline */\n'
    good['ev3_uart_class.c'] = '#include "ev3_uart_ldisc.h"\n' + good['ev3_uart_class.c']
    rc, out = run(tmp_path, good)
    assert rc == 1 and "ev3_uart_class.c: the view includes the transport's ev3_uart_ldisc.h" \
        in out, out


def test_reading_the_parsers_fields_fails(tmp_path, good):
    good['ev3_uart_core.c'] += ('struct parser { int state; };\n'
                                'int core_state(struct parser *parser)\n{\n'
                                '\treturn parser->state;\n}\n')
    rc, out = run(tmp_path, good)
    assert rc == 1 and "ev3_uart_core.c: reads the parser's fields state " \
        "(only ev3_uart_proto.c may)" in out, out
    # The parser's own file may.
    good['ev3_uart_proto.c'] = good['ev3_uart_core.c']
    good['ev3_uart_core.c'] = GOOD['ev3_uart_core.c']
    rc, out = run(tmp_path, good)
    assert rc == 0, out
