// SPDX-License-Identifier: GPL-2.0
/*
 * nxt-ioctl: talk to an NXT brick through /dev/nxtN: read the battery, play
 * a tone, read a sensor port, turn a motor by a number of degrees. Each
 * command is a telegram that liblegonxt builds (<legonxt.h>), sent with
 * NXT_IOC_TRANSACT (<linux/lego_nxt.h>); liblegonxt checks that the reply
 * answers it and decodes it.
 *
 * Needs:  the lego_nxt_usb module, a brick on USB (its /dev/nxtN), read and
 *         write access to the node (the group "lego", or the logged-in
 *         user through the udev rule), the uapi header and liblegonxt: in
 *         this repository include/uapi and tools/liblegonxt (the Makefile
 *         uses them), else lego-mindstorms-dev and liblegonxt-dev
 *         (pkg-config lego-mindstorms legonxt).
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
#include <legonxt.h>

static int fd;
static struct nxt_transaction t;

/*
 * Send @m and wait for its reply, in t.reply: 0, or -1 after printing why
 * not (errno for the device, the brick's status by name).
 */
static int transact(const struct lnxt_msg *m, const char *what)
{
	int status;

	memset(&t, 0, sizeof(t));
	memcpy(t.telegram, m->buf, m->len);
	t.length = m->len;
	if (ioctl(fd, NXT_IOC_TRANSACT, &t) < 0) {
		fprintf(stderr, "%s: %s\n", what, strerror(errno));
		return -1;
	}
	status = lnxt_reply_check(m, t.reply, t.reply_length);
	if (status < 0) {
		fprintf(stderr, "%s: not a reply to it\n", what);
		return -1;
	}
	if (status) {
		const char *name = lnxt_status_name(status);

		fprintf(stderr, "%s: %s (status 0x%02x)\n", what, name ? name : "unknown status",
			status);
		return -1;
	}
	return 0;
}

static int cmd_battery(void)
{
	struct lnxt_msg m;
	uint16_t mv;

	lnxt_get_battery_level(&m);
	if (transact(&m, "GetBatteryLevel") ||
	    lnxt_parse_battery_level(t.reply, t.reply_length, &mv))
		return 1;
	printf("battery %u mV\n", mv);
	return 0;
}

static int cmd_tone(int hz, int ms)
{
	struct lnxt_msg m;

	lnxt_play_tone(&m, hz, ms);
	if (transact(&m, "PlayTone"))
		return 1;
	printf("tone %d Hz %d ms\n", hz, ms);
	return 0;
}

static int get_input(int port, struct lnxt_input *v)
{
	struct lnxt_msg m;

	lnxt_get_input_values(&m, port);
	if (transact(&m, "GetInputValues"))
		return -1;
	return lnxt_parse_input_values(t.reply, t.reply_length, v) ? -1 : 0;
}

static int cmd_touch(int port)
{
	struct timespec settle = { 0, 100 * 1000 * 1000 };
	struct lnxt_input v = { 0 };
	struct lnxt_msg m;
	int i;

	lnxt_set_input_mode(&m, port, LNXT_SENSOR_SWITCH, LNXT_SENSOR_MODE_BOOLEAN);
	if (transact(&m, "SetInputMode"))
		return 1;
	/* The brick needs a moment after SetInputMode before the value is valid. */
	for (i = 0; i < 20 && !v.valid; i++) {
		nanosleep(&settle, NULL);
		if (get_input(port, &v))
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

static int get_output(int port, struct lnxt_output *o)
{
	struct lnxt_msg m;

	lnxt_get_output_state(&m, port);
	if (transact(&m, "GetOutputState"))
		return -1;
	return lnxt_parse_output_state(t.reply, t.reply_length, o) ? -1 : 0;
}

static int cmd_motor(int port, int power, unsigned int degrees)
{
	struct lnxt_output s = {
		.port = port, .power = power,
		.mode = LNXT_MODE_MOTORON | LNXT_MODE_BRAKE,
		.regulation = LNXT_REGULATION_IDLE,
		.run_state = LNXT_RUN_RUNNING,
		.tacho_limit = degrees,
	};
	struct timespec poll = { 0, 50 * 1000 * 1000 };
	struct lnxt_msg m;
	int i;

	lnxt_reset_motor_position(&m, port, false);
	if (transact(&m, "ResetMotorPosition"))
		return 1;
	if (lnxt_set_output_state(&m, &s)) {
		fprintf(stderr, "power %d: out of -100..100\n", power);
		return 2;
	}
	if (transact(&m, "SetOutputState"))
		return 1;
	/* The brick stops the motor at the tacho limit: wait for that (10 s at most). */
	for (i = 0; i < 200; i++) {
		nanosleep(&poll, NULL);
		if (get_output(port, &s))
			return 1;
		if (s.run_state == LNXT_RUN_IDLE)
			break;
	}
	printf("motor %c %s at %d degrees\n", 'A' + port,
	       s.run_state == LNXT_RUN_IDLE ? "stopped" : "still running",
	       s.rotation_count);
	/* Let it float again. */
	memset(&s, 0, sizeof(s));
	s.port = port;
	lnxt_set_output_state(&m, &s);
	if (transact(&m, "SetOutputState"))
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
		 atoi(arg[1]) >= 1 && atoi(arg[1]) <= 4)
		ret = cmd_touch(atoi(arg[1]) - 1);
	else if (!strcmp(arg[0], "motor") && n == 4 &&
		 arg[1][0] >= 'A' && arg[1][0] <= 'C' && !arg[1][1])
		ret = cmd_motor(arg[1][0] - 'A', atoi(arg[2]), strtoul(arg[3], NULL, 0));
	else
		print_usage(stderr, argv[0]);
	close(fd);
	return ret;
}
