"""tests/coverage.py on a small program built with gcov, as the modules are.

The program stands in for a module: two objects below drivers/lego of a
build directory, one of them never run (an unloaded module), and a header
with a static inline function emitted in both. Each --check rule is shown
to fail.
"""
import os
import shutil
import subprocess
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
import coverage  # noqa: E402

HEADER = '''static inline int twice(int x)
{
	return 2 * x;
}
'''
MAIN = '''#include "../../../include/h.h"
int other(int x);
static int reached(int x) { return twice(x) + 1; }
static int not_reached(int x) { return x - 1; }
int main(int argc, char **argv)
{
	(void)argv;
	if (argc > 5)
		return not_reached(argc);
	return reached(argc) == 3 ? 0 : 1;
}
'''
OTHER = '''#include "../../../include/h.h"
int other(int x) { return twice(x); }
'''


@pytest.fixture
def run(tmp_path):
    """(build, gcda): the objects built with gcov, main.c's run saved the
    way run-suite.sh saves the guest's data; other.c never ran."""
    if not shutil.which('gcc') or not shutil.which('gcov'):
        pytest.fail('gcc and gcov are needed (tests/install-deps.sh installs them)')
    build = tmp_path / 'build'
    src = build / 'drivers' / 'lego' / 'x'
    src.mkdir(parents=True)
    (build / 'include').mkdir()
    (build / 'include' / 'h.h').write_text(HEADER)
    (src / 'main.c').write_text(MAIN)
    (src / 'other.c').write_text(OTHER)
    for name in ('main', 'other'):
        subprocess.run(['gcc', '--coverage', '-O0', '-c', f'{name}.c', '-o', f'{name}.o'],
                       cwd=src, check=True)
    subprocess.run(['gcc', '--coverage', 'main.o', 'other.o', '-o', 'prog'], cwd=src, check=True)
    subprocess.run([str(src / 'prog')], cwd=src, check=True)
    gcda = tmp_path / 'gcda'
    (gcda / 'drivers' / 'lego' / 'x').mkdir(parents=True)
    for f in src.glob('*.gcda'):
        f.rename(gcda / 'drivers' / 'lego' / 'x' / f.name)
    # other.o's data would only exist had it run: it did not (prog never
    # calls other()), but gcov writes a .gcda for every linked object.
    (gcda / 'drivers' / 'lego' / 'x' / 'other.gcda').unlink()
    return str(build), str(gcda)


def allow(tmp_path, text):
    p = tmp_path / 'allow.txt'
    p.write_text(text)
    return str(p)


def calls(funcs):
    return {k: f.calls for k, f in funcs.items()}


def test_counts_each_function_of_our_sources(run):
    funcs, objects, with_data = coverage.collect(*run)
    assert (objects, with_data) == (2, 1)
    c = calls(funcs)
    assert c['drivers/lego/x/main.c:reached'] == 1
    assert c['drivers/lego/x/main.c:main'] == 1
    assert c['drivers/lego/x/main.c:not_reached'] == 0
    # An object that was never loaded: its functions are all unreached.
    assert c['drivers/lego/x/other.c:other'] == 0
    # The header's inline function, emitted in both objects, run in one.
    assert c['include/h.h:twice'] == 1
    assert not [k for k in c if not k.startswith(('drivers/lego/', 'include/'))]


def test_report_lists_what_no_test_reached(run, capsys):
    funcs, _, _ = coverage.collect(*run)
    coverage.report(funcs, show_all=False)
    out = capsys.readouterr().out
    assert 'drivers/lego/x/main.c: 2 of 3 functions reached' in out
    assert 'not_reached (line 4): not reached' in out
    assert 'reached (line 3)' not in out
    assert 'total: 3 of 5 functions reached' in out


def test_check_fails_on_an_unreached_function_not_listed(run, tmp_path, capsys):
    a = allow(tmp_path, 'not_reached the test program never takes that branch\n')
    assert coverage.main(['--check', a, '--build', *run]) == 1
    out = capsys.readouterr().out
    assert 'other is reached by no test' in out
    assert 'not_reached is reached by no test' not in out


def test_check_passes_when_every_unreached_function_is_listed(run, tmp_path, capsys):
    a = allow(tmp_path, '# comment\n\nnot_reached never called\n'
                        'drivers/lego/x/other.c:other its object is never loaded\n')
    assert coverage.main(['--check', a, '--build', *run]) == 0
    assert 'every function not reached is named' in capsys.readouterr().out


def test_check_fails_on_a_listed_name_that_is_no_function(run, tmp_path, capsys):
    a = allow(tmp_path, 'not_reached x\nother x\nremoved_long_ago it was here once\n')
    assert coverage.main(['--check', a, '--build', *run]) == 1
    assert 'removed_long_ago is no function of the drivers' in capsys.readouterr().out


def test_check_fails_on_a_line_without_a_reason(run, tmp_path, capsys):
    a = allow(tmp_path, 'not_reached\nother x\n')
    assert coverage.main(['--check', a, '--build', *run]) == 1
    assert 'not_reached is listed without a reason' in capsys.readouterr().out


def test_listed_but_reached_is_reported_not_failed(run, tmp_path, capsys):
    a = allow(tmp_path, 'not_reached x\nother x\nreached some runs miss it\n')
    assert coverage.main(['--check', a, '--build', *run]) == 0
    assert 'main.c:reached is listed' in capsys.readouterr().out


def test_check_fails_without_any_gcov_data(run, tmp_path, capsys):
    build, gcda = run
    shutil.rmtree(gcda)
    a = allow(tmp_path, 'not_reached x\nother x\nreached x\nmain x\ntwice x\n')
    assert coverage.main(['--check', a, '--build', build, gcda]) == 1
    assert 'no gcov data' in capsys.readouterr().out


def test_build_directory_from_the_data(run, tmp_path, capsys):
    build, gcda = run
    with open(os.path.join(gcda, 'BUILD'), 'w') as f:
        f.write(build + '\n')
    assert coverage.main([gcda]) == 0
    assert 'total: 3 of 5 functions reached' in capsys.readouterr().out
    assert coverage.main([str(tmp_path / 'none')]) == 1
    assert 'no gcov data' in capsys.readouterr().out


def test_fails_when_the_modules_have_no_gcov_notes(tmp_path, capsys):
    (tmp_path / 'drivers' / 'lego').mkdir(parents=True)
    assert coverage.main(['--build', str(tmp_path), str(tmp_path)]) == 1
    assert 'not built with gcov' in capsys.readouterr().out
