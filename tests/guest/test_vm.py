"""The test VM itself: what the other tests take for granted of it."""
import os

import pytest


def cpu_list(text):
    """CPUs in a sysfs cpu list such as "0-1" or "0,2-3"."""
    cpus = set()
    for part in text.strip().split(','):
        if not part:
            continue
        first, _, last = part.partition('-')
        cpus.update(range(int(first), int(last or first) + 1))
    return cpus


def test_cpu_list_parser():
    assert cpu_list('0\n') == {0}
    assert cpu_list('0-1\n') == {0, 1}
    assert cpu_list('0,2-3\n') == {0, 2, 3}
    assert cpu_list('\n') == set()


def test_guest_runs_on_every_cpu_it_was_given():
    """The drivers' locking is tested on as many CPUs as QEMU was given.

    On x86 the guest has no ACPI and takes its CPUs from the BIOS's MP
    table, which lists one CPU per socket: vm-run must give QEMU sockets,
    or the guest quietly runs on one CPU.
    """
    want = os.environ.get('LEGO_VM_CPUS')
    if not want:
        pytest.skip('vm-run did not say how many CPUs it gave QEMU')
    with open('/sys/devices/system/cpu/online') as f:
        online = cpu_list(f.read())
    assert len(online) == int(want), \
        f'{want} CPUs given to QEMU, online: {sorted(online)}'
