"""The EV3 UART line discipline registers and attaches to ttys."""
import errno
import fcntl
import os
import struct
import subprocess
import termios

import pytest

from conftest import module_path, loaded

N_TTY = 0
N_LEGOEV3 = 29


def set_ldisc(fd, num):
    fcntl.ioctl(fd, termios.TIOCSETD, struct.pack('i', num))


def get_ldisc(fd):
    return struct.unpack('i', fcntl.ioctl(fd, termios.TIOCGETD, b'\0' * 4))[0]


def registered_ldiscs():
    with open('/proc/tty/ldiscs') as f:
        return dict((name, int(num)) for name, num in (line.split() for line in f))


def test_ldisc_registered_as_29(ev3_module):
    assert registered_ldiscs().get('n_legoev3') == N_LEGOEV3


def test_attach_to_pty_and_detach(ev3_module):
    master, slave = os.openpty()
    try:
        set_ldisc(slave, N_LEGOEV3)
        assert get_ldisc(slave) == N_LEGOEV3
        # Bytes from the "sensor" side reach the discipline without harm.
        os.write(master, bytes(range(256)) * 4)
        set_ldisc(slave, N_TTY)
        assert get_ldisc(slave) == N_TTY
    finally:
        os.close(slave)
        os.close(master)


def test_attach_to_pty_master_and_detach(ev3_module):
    """The master side of a pty has no set_termios (nor break_ctl,
    chars_in_buffer, wait_until_sent): the discipline must do without."""
    master, slave = os.openpty()
    try:
        set_ldisc(master, N_LEGOEV3)
        assert get_ldisc(master) == N_LEGOEV3
        os.write(slave, bytes(range(256)) * 4)
        set_ldisc(master, N_TTY)
    finally:
        os.close(slave)
        os.close(master)


@pytest.mark.parametrize('side', ['slave', 'master'])
def test_sensor_on_a_pty(ev3_module, side):
    """A whole connection over a pty (no speeds, no line errors): the
    discipline on one side, an emulated colour sensor on the other."""
    import ev3
    master, slave = os.openpty()
    host, far = (slave, master) if side == 'slave' else (master, slave)
    name = os.ttyname(slave).split('/')[-1]
    address = ('pts' if side == 'slave' else 'ptm') + name
    emu = None
    try:
        set_ldisc(host, N_LEGOEV3)
        emu = ev3.ev3_sensor.EmulatedSensor(far, 'color')
        emu.start()
        path = ev3.find_sensor(address, timeout=15)
        assert path, 'no sensor at %s (%s)' % (address, emu.events)
        assert ev3.read_attr(path, 'driver_name') == 'lego-ev3-color'
        emu.set_values(0, [61])
        assert ev3.wait_value(path, 0, 61) == 61
        ev3.write_attr(path, 'mode', 'COL-AMBIENT')
        emu.set_values(1, [7])
        assert ev3.wait_value(path, 0, 7) == 7
    finally:
        if emu:
            emu.stop()
        os.close(host)
        os.close(far)
    assert ev3.wait_gone(path, 2.0)


def test_attach_needs_privilege(ev3_module):
    pid = os.fork()
    if pid == 0:
        code = 3
        try:
            os.setgid(65534)
            os.setuid(65534)
            master, slave = os.openpty()
            try:
                set_ldisc(slave, N_LEGOEV3)
                code = 1
            except OSError as e:
                code = 0 if e.errno == errno.EPERM else 2
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, \
        'an unprivileged user attached the discipline (or got the wrong errno)'


def test_module_pinned_while_attached(ev3_module):
    master, slave = os.openpty()
    try:
        set_ldisc(slave, N_LEGOEV3)
        r = subprocess.run(['rmmod', 'lego_ev3_uart'], capture_output=True)
        assert r.returncode != 0
        assert loaded('lego_ev3_uart')
    finally:
        os.close(slave)
        os.close(master)


def test_module_unload_and_reload(ev3_module):
    subprocess.run(['rmmod', 'lego_ev3_uart'], check=True)
    assert 'n_legoev3' not in registered_ldiscs()
    master, slave = os.openpty()
    try:
        with pytest.raises(OSError) as e:
            set_ldisc(slave, N_LEGOEV3)
        assert e.value.errno == errno.EINVAL
    finally:
        os.close(slave)
        os.close(master)
    subprocess.run(['insmod', module_path('lego_ev3_uart')], check=True)
    assert registered_ldiscs().get('n_legoev3') == N_LEGOEV3
