#!/bin/sh
# SPDX-License-Identifier: GPL-2.0
# A first session with the drivers from a shell. Every line works on its own
# at a prompt; run as a script, each command is printed ("$ ...") before its
# output.
#
# Needs:  for the EV3 part, the lego_ev3_uart module and a sensor attached to
#         its tty (lego-ev3-attach or ldattach, see
#         Documentation/lego/ev3-uart.rst), and for `echo MODE > mode`,
#         write access to the sensor's mode (root, or the group "lego" with
#         tools/udev/90-lego-ev3-sensors.rules); for the NXT part, the
#         lego_nxt_usb module, a brick on USB and nxtctl. A part whose
#         device is missing is skipped.
# Run:    sh shell-session.sh [MODE]
#         MODE is a mode of the first sensor to switch to, e.g. COL-COLOR.

PS4='$ '
mode=${1:-}

# The EV3 sensors: one directory each in the lego-sensor class.
for s in /sys/class/lego-sensor/sensor*; do
	[ -d "$s" ] || break
	set -x
	cd "$s"
	cat address driver_name modes mode
	# value0 is an integer: divide by 10^decimals for the value in units.
	cat num_values decimals units value0
	set +x
	if [ -n "$mode" ]; then
		set -x
		# Returns once the sensor sends values of the new mode.
		echo "$mode" > mode
		cat mode units value0
		set +x
	fi
	break
done

# The NXT bricks: one node each, and their attributes in sysfs. Reading
# them sends nothing to the brick: they show what it last answered a user
# of its node (ENODATA before), so ask it first.
for n in /dev/nxt[0-9]*; do
	[ -c "$n" ] || break
	set -x
	ls -l /dev/nxt*
	nxtctl -d "$n" info >/dev/null
	cd /sys/class/lego-nxt/"${n#/dev/}"
	cat brick_name bt_address firmware_version battery_mv
	set +x
	break
done
