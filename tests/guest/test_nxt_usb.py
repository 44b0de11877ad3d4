"""The NXT USB driver registers and matches only the brick's interface 0."""
import os
import re
import subprocess

from conftest import module_path


def test_driver_registered():
    assert os.path.isdir('/sys/bus/usb/drivers/lego_nxt_usb')


def test_alias_matches_only_interface_0():
    out = subprocess.run(['modinfo', '-F', 'alias', module_path('lego_nxt_usb')],
                         capture_output=True, text=True, check=True).stdout.split()
    assert len(out) == 1
    alias = out[0]
    assert alias.startswith('usb:v0694p0002d')
    assert re.search(r'in00\*?$', alias), alias
