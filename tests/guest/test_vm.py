"""The test VM itself: what the other tests take for granted of it."""
import os

import pytest


def test_guest_runs_on_every_cpu_it_was_given():
    """The drivers' locking is tested on as many CPUs as QEMU was given.

    On x86 the guest has no ACPI and takes its CPUs from the BIOS's MP
    table, which lists one CPU per socket: vm-run must give QEMU sockets,
    or the guest quietly runs on one CPU. os.cpu_count() is the online
    CPUs (glibc reads /sys/devices/system/cpu/online).
    """
    want = os.environ.get('LEGO_VM_CPUS')
    if not want:
        pytest.skip('vm-run did not say how many CPUs it gave QEMU')
    with open('/sys/devices/system/cpu/online') as f:
        online = f.read().strip()
    assert os.cpu_count() == int(want), f'{want} CPUs given to QEMU, online: {online}'
