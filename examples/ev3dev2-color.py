#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-2.0
"""Read an EV3 colour sensor with python-ev3dev2: reflected light and colour.

Needs:  the lego_ev3_uart module and the sensor attached to its tty (see
        Documentation/lego/ev3-uart.rst), python-ev3dev2
        (pip install python-ev3dev2, in a venv on Debian 12: apt install
        python3-venv, python3 -m venv DIR, DIR/bin/pip install ...), and write
        access to the sensor's mode attribute: the udev rule
        tools/udev/90-lego-ev3-sensors.rules makes it group-writable for
        the group "lego" (python-ev3dev2 opens it read-write only then).
Run:    python3 ev3dev2-color.py [--address ADDRESS] [--count N] [--interval S]
        ADDRESS is matched against the sensor's address attribute, e.g.
        ttyAMA0 or ttyUSB0; without it the first colour sensor is used.
        Prints one line per reading, e.g. "reflected 37 %  colour 5 Red".
"""
import argparse
import time

from ev3dev2.sensor.lego import ColorSensor


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--address', help='part of the sensor address, e.g. ttyAMA0')
    p.add_argument('--count', type=int, default=5, help='readings (default 5)')
    p.add_argument('--interval', type=float, default=0.5, help='seconds between readings')
    args = p.parse_args()

    # ColorSensor() finds the first sensor whose driver_name is
    # lego-ev3-color (and whose address contains ADDRESS, if given).
    sensor = ColorSensor(args.address)
    print('sensor at %s' % sensor.address)
    for i in range(args.count):
        if i:
            time.sleep(args.interval)
        # Each property selects its mode first (COL-REFLECT, COL-COLOR).
        reflected = sensor.reflected_light_intensity
        colour = sensor.color
        print('reflected %d %%  colour %d %s' % (reflected, colour, ColorSensor.COLORS[colour]),
              flush=True)


if __name__ == '__main__':
    main()
