#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""nxt-python through /dev/nxtN: brick information, battery, a tone, a touch
sensor and a motor, with the lego_nxt_linux backend from tools/python.

Needs:  the lego_nxt_usb module, a brick on USB with read/write access to its
        /dev/nxtN, nxt-python 3.x and lego_nxt_linux (tools/python; see
        tools/python/README.md for installing them on Debian 12 or
        Raspberry Pi OS, or run from this repository with
        PYTHONPATH=tools/python).
Run:    python3 nxt-python-hello.py [--name NXT] [--filename /dev/nxt0]
        Prints the brick's name, its Bluetooth address and firmware, the
        battery level, whether the touch sensor on port 1 is pressed, and
        turns motor A by 180 degrees.
"""
import argparse

import nxt.locator
import nxt.motor
import nxt.sensor
import nxt.sensor.generic

import lego_nxt_linux


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--name', help='brick name, e.g. NXT')
    p.add_argument('--filename', help='one node, e.g. /dev/nxt1')
    args = p.parse_args()
    filters = {k: v for k, v in vars(args).items() if v is not None}

    # config=None: ignore ~/.nxt-python.conf, use this backend only.
    with nxt.locator.find(backends=[lego_nxt_linux.get_backend()], config=None,
                          **filters) as brick:
        name, host, _, free_flash = brick.get_device_info()
        _, firmware = brick.get_firmware_version()
        print('brick %s at %s, firmware %d.%02d, %d bytes free'
              % (name, host, firmware[0], firmware[1], free_flash))
        print('battery %d mV' % brick.get_battery_level())
        brick.play_tone(523, 200)
        touch = nxt.sensor.generic.Touch(brick, nxt.sensor.Port.S1)
        print('touch on port 1: %s' % ('pressed' if touch.is_pressed() else 'released'))
        motor = nxt.motor.Motor(brick, nxt.motor.Port.A)
        motor.reset_position(False)
        # emulate=False: the brick itself stops the motor at the tacho limit.
        motor.turn(60, 180, emulate=False)
        print('motor A at %d degrees' % motor.get_tacho().rotation_count)
        motor.idle()


if __name__ == '__main__':
    main()
