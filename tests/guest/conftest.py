"""Shared fixtures for the guest tests (run inside the test VM)."""
import contextlib
import grp
import os
import shutil
import signal
import subprocess
import time

import pytest


# The project's modules in load order (a transport after the NXT core it
# uses), and in the order rmmod takes them.
MODULES = ['lego_ev3_uart', 'lego_nxt', 'lego_nxt_usb', 'lego_nxt_serial']
UNLOAD = list(reversed(MODULES))


def module_path(name):
    """Path of a module built for the running test kernel."""
    for mod in os.environ.get('LEGO_MODULES', '').split():
        if os.path.basename(mod) == name + '.ko':
            return mod
    raise LookupError(f'{name}.ko not in LEGO_MODULES')


def loaded(name):
    return os.path.isdir(f'/sys/module/{name}')


def pid_alive(pid):
    """True while pid runs. A zombie (the VM's init may not reap a daemon
    that is not our child) counts as gone, and so does a process that ends
    between the open and the read of its stat file (ESRCH)."""
    try:
        with open('/proc/%d/stat' % pid) as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except OSError:
        return False


def run(cmd, **kw):
    """Run a command and return its stdout; on failure, the assertion shows
    the command, its exit code and the tail of its output."""
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert r.returncode == 0, '%s: exit %d\n%s%s' % (' '.join(cmd), r.returncode,
                                                     r.stdout[-3000:], r.stderr[-3000:])
    return r.stdout


def wait_for(cond, timeout=3.0, interval=0.05):
    """Poll cond() until it is true or timeout seconds passed; its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(interval)
    return cond()


def owned(node, gid, mode=0o660):
    """Whether node has group gid and permissions mode (udev sets them in two calls)."""
    st = os.stat(node)
    return st.st_gid == gid and st.st_mode & 0o777 == mode


def unload(*names):
    """rmmod each of the modules that is loaded."""
    for name in names:
        if loaded(name):
            run(['rmmod', name])


@contextlib.contextmanager
def udevd_with_rules(work, rules):
    """systemd-udevd with the rule files RULES of tools/udev (or given by
    their absolute paths) in /run/udev/rules.d and a group lego (added to a private copy of
    /etc/group, bind-mounted, when the system has none); yields its GID.
    udevadm control refuses to act in a chroot, as the tests run: the
    daemon is stopped with signals."""
    top = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
    os.makedirs(work, exist_ok=True)
    group = os.path.join(work, 'group')
    mounted = False
    with open('/etc/group') as f:
        lines = f.read()
    try:
        gid = grp.getgrnam('lego').gr_gid
    except KeyError:
        used = {int(line.split(':')[2]) for line in lines.splitlines() if line.count(':') >= 3}
        gid = next(g for g in range(990, 100, -1) if g not in used)
        with open(group, 'w') as f:
            f.write(lines + 'lego:x:%d:\n' % gid)
        run(['mount', '--bind', group, '/etc/group'])
        mounted = True
    rules_dir = '/run/udev/rules.d'
    os.makedirs(rules_dir, exist_ok=True)
    for r in rules:
        shutil.copy(os.path.join(top, 'tools/udev', r), rules_dir)
    try:
        run(['/lib/systemd/systemd-udevd', '--daemon'])
        yield gid
    finally:
        out = subprocess.run(['pidof', 'systemd-udevd'], capture_output=True, text=True).stdout
        pids = [int(p) for p in out.split()]
        for pid in pids:
            os.kill(pid, signal.SIGTERM)
        if not wait_for(lambda: not any(pid_alive(p) for p in pids), 20):
            for pid in pids:
                if pid_alive(pid):
                    os.kill(pid, signal.SIGKILL)
        for r in rules:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(os.path.join(rules_dir, os.path.basename(r)))
        if mounted:
            subprocess.run(['umount', '/etc/group'])


@pytest.fixture(autouse=True)
def in_vm():
    if os.environ.get('LEGO_IN_VM') != '1':
        pytest.skip('guest tests run inside the test VM (tests/vm-run)')


@pytest.fixture
def ev3_module():
    """The EV3 module loaded (and left loaded) for a test."""
    if not loaded('lego_ev3_uart'):
        subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)
    yield 'lego_ev3_uart'
    if not loaded('lego_ev3_uart'):
        subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    """The kernel log from the start of each test, for its failure report."""
    import kmsg
    try:
        item.kmsg = kmsg.Kmsg()
    except OSError:
        item.kmsg = None
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failed test's report shows what the kernel logged meanwhile (the
    reason a sensor was lost, a warning), which the part of the console a
    CI report keeps may not."""
    outcome = yield
    rep = outcome.get_result()
    log = getattr(item, 'kmsg', None)
    if log is None:
        return
    if rep.failed:
        lines = ['[%12.6f] %s' % rec for rec in log.read()]
        if lines:
            rep.sections.append(('kernel log since the test started', '\n'.join(lines[-60:])))
    if call.when == 'teardown':
        log.close()
        item.kmsg = None


def pytest_configure(config):
    config.addinivalue_line('markers', 'no_wire_timing(why): the line fixture does not check '
                            'the ACK deadline and keep-alive period (the test breaks them)')


@pytest.fixture
def line(ev3_module, request):
    """A null-modem line with the EV3 discipline attached on ttyNM0. After
    the test, every handshake the discipline answered on it is checked for
    its ACK deadline and keep-alive period on the wire (wire.py), unless
    the test is marked no_wire_timing."""
    import ev3
    import wire
    ev3.load_nullmodem()
    since = wire.head() if wire.available() else None
    ln = ev3.Line(0)
    ln.attach()
    yield ln
    end = time.monotonic_ns()
    ln.close()
    left = [d for d in ev3.glob.glob(ev3.CLASS + '/sensor*')
            if ev3.read_attr(d, 'address').split(':')[0] == ln.address]
    assert not left, 'sensor left behind after detach: %s' % left
    if since is not None and not request.node.get_closest_marker('no_wire_timing'):
        recs, lost = wire.read(since)
        errors, conns = wire.check(recs, 0, end, lost, ln.detached_ns)
        for c in conns:
            if c.excused:
                print('wire: %r' % c)
        assert not errors, 'timing on the wire:\n' + '\n'.join(errors)


@pytest.fixture(scope='module')
def brick(request):
    """An emulated NXT brick on dummy_udc.0, with the test module's SERIAL,
    plugged in (with its /dev/nxtN) for the module's tests, then unplugged.
    A module with BRICK_TICK (seconds) gets a brick with the firmware's
    scheduler tick (nxt_brick.py `tick`: one command per 1 ms tick)."""
    import nxtdev
    b = nxtdev.Brick('dummy_udc.0', request.module.SERIAL,
                     tick=getattr(request.module, 'BRICK_TICK', None))
    b.plug()
    yield b
    b.unplug()
    assert b.wait_gone(), 'the node outlived the brick'
