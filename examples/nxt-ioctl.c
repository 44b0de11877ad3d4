// SPDX-License-Identifier: GPL-2.0
/*
 * nxt-ioctl: talk to an NXT brick through /dev/nxtN with the typed ioctls
 * of <linux/lego_nxt.h>: read the battery, play a tone, read a sensor port,
 * turn a motor by a number of degrees.
 *
 * Needs:  the lego_nxt_usb module, a brick on USB (its /dev/nxtN), read and
 *         write access to the node (the group "lego", or the logged-in
 *         user through the udev rule), and the uapi header: in this
 *         repository include/uapi/linux/lego_nxt.h (the Makefile adds
 *         -I../include/uapi).
 * Build:  make nxt-ioctl
 * Run:    ./nxt-ioctl [-d /dev/nxt0] battery
 *         ./nxt-ioctl tone 440 500          (Hz, ms)
 *         ./nxt-ioctl touch 1               (sensor port 1 to 4)
 *         ./nxt-ioctl motor A 75 360        (port, power -100..100, degrees)
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#include <linux/lego_nxt.h>

static int fd;

/* Every typed ioctl copies the brick's status byte back; errno says what failed. */
static int xioctl(unsigned long request, void *arg, const char *what)
{
	if (ioctl(fd, request, arg) < 0) {
		fprintf(stderr, "%s: %s\n", what, strerror(errno));
		return -1;
	}
	return 0;
}

static int cmd_battery(void)
{
	struct nxt_battery b = { 0 };

	if (xioctl(NXT_IOC_GET_BATTERY_LEVEL, &b, "GET_BATTERY_LEVEL"))
		return 1;
	printf("battery %u mV\n", b.millivolts);
	return 0;
}

static int cmd_tone(int hz, int ms)
{
	struct nxt_tone t = { .frequency = hz, .duration = ms };

	if (xioctl(NXT_IOC_PLAY_TONE, &t, "PLAY_TONE"))
		return 1;
	printf("tone %d Hz %d ms\n", hz, ms);
	return 0;
}

static int cmd_touch(int port)
{
	struct nxt_input_mode m = {
		.port = port, .type = NXT_SENSOR_SWITCH, .mode = NXT_SENSOR_MODE_BOOLEAN,
	};
	struct nxt_input_values v = { .port = port };
	struct timespec settle = { 0, 100 * 1000 * 1000 };
	int i;

	if (xioctl(NXT_IOC_SET_INPUT_MODE, &m, "SET_INPUT_MODE"))
		return 1;
	/* The brick needs a moment after SetInputMode before the value is valid. */
	for (i = 0; i < 20 && !v.valid; i++) {
		nanosleep(&settle, NULL);
		if (xioctl(NXT_IOC_GET_INPUT_VALUES, &v, "GET_INPUT_VALUES"))
			return 1;
	}
	if (!v.valid) {
		fprintf(stderr, "port %d: no valid value after 2 s\n", port + 1);
		return 1;
	}
	printf("touch %d %s (raw %u)\n", port + 1,
	       v.scaled ? "pressed" : "released", v.raw);
	return 0;
}

static int cmd_motor(int port, int power, unsigned int degrees)
{
	struct nxt_motor_position reset = { .port = port, .relative = 0 };
	struct nxt_output_state s = {
		.port = port, .power = power,
		.mode = NXT_MODE_MOTORON | NXT_MODE_BRAKE,
		.regulation_mode = NXT_REGULATION_IDLE,
		.run_state = NXT_RUN_STATE_RUNNING,
		.tacho_limit = degrees,
	};
	struct timespec poll = { 0, 50 * 1000 * 1000 };
	int i;

	if (xioctl(NXT_IOC_RESET_MOTOR_POSITION, &reset, "RESET_MOTOR_POSITION") ||
	    xioctl(NXT_IOC_SET_OUTPUT_STATE, &s, "SET_OUTPUT_STATE"))
		return 1;
	/* The brick stops the motor at the tacho limit: wait for that (10 s at most). */
	for (i = 0; i < 200; i++) {
		nanosleep(&poll, NULL);
		memset(&s, 0, sizeof(s));
		s.port = port;
		if (xioctl(NXT_IOC_GET_OUTPUT_STATE, &s, "GET_OUTPUT_STATE"))
			return 1;
		if (s.run_state == NXT_RUN_STATE_IDLE)
			break;
	}
	printf("motor %c %s at %d degrees\n", 'A' + port,
	       s.run_state == NXT_RUN_STATE_IDLE ? "stopped" : "still running",
	       s.rotation_count);
	/* Let it float again. */
	memset(&s, 0, sizeof(s));
	s.port = port;
	if (xioctl(NXT_IOC_SET_OUTPUT_STATE, &s, "SET_OUTPUT_STATE"))
		return 1;
	return 0;
}

static void print_usage(FILE *f, const char *argv0)
{
	fprintf(f, "usage: %s [-d DEVICE] battery\n"
		"       %s [-d DEVICE] tone HZ MS\n"
		"       %s [-d DEVICE] touch PORT         (1-4)\n"
		"       %s [-d DEVICE] motor PORT POWER DEGREES  (A-C, -100..100)\n",
		argv0, argv0, argv0, argv0);
}

int main(int argc, char **argv)
{
	const char *device = "/dev/nxt0";
	int opt, ret = 2;
	char **arg;
	int n;

	while ((opt = getopt(argc, argv, "d:h")) != -1) {
		switch (opt) {
		case 'd':
			device = optarg;
			break;
		case 'h':
			print_usage(stdout, argv[0]);
			return 0;
		default:
			print_usage(stderr, argv[0]);
			return 2;
		}
	}
	arg = argv + optind;
	n = argc - optind;
	if (n < 1) {
		print_usage(stderr, argv[0]);
		return 2;
	}

	fd = open(device, O_RDWR | O_CLOEXEC);
	if (fd < 0) {
		fprintf(stderr, "%s: %s\n", device, strerror(errno));
		return 1;
	}
	if (!strcmp(arg[0], "battery") && n == 1)
		ret = cmd_battery();
	else if (!strcmp(arg[0], "tone") && n == 3)
		ret = cmd_tone(atoi(arg[1]), atoi(arg[2]));
	else if (!strcmp(arg[0], "touch") && n == 2 &&
		 atoi(arg[1]) >= 1 && atoi(arg[1]) <= NXT_INPUT_PORTS)
		ret = cmd_touch(atoi(arg[1]) - 1);
	else if (!strcmp(arg[0], "motor") && n == 4 &&
		 arg[1][0] >= 'A' && arg[1][0] < 'A' + NXT_OUTPUT_PORTS && !arg[1][1])
		ret = cmd_motor(arg[1][0] - 'A', atoi(arg[2]), strtoul(arg[3], NULL, 0));
	else
		print_usage(stderr, argv[0]);
	close(fd);
	return ret;
}
