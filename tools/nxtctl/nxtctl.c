// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl: drive a LEGO MINDSTORMS NXT brick through /dev/nxtN.
 *
 * Every command is a telegram that liblegonxt (tools/liblegonxt) builds and
 * whose reply it checks and decodes, sent with NXT_IOC_TRANSACT of the
 * uapi header <linux/lego_nxt.h>. See Documentation/lego/nxtctl.rst.
 */
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <glob.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#include "nxtctl.h"

#define DEFAULT_TIMEOUT_MS	1000
#define DEFAULT_WAIT_MS		60000	/* motor --wait */
#define WAIT_POLL_MS		50

int nxt_fd = -1;
static unsigned int timeout_ms = DEFAULT_TIMEOUT_MS;
const char *dev_path;		/* -d */
static long dev_timeout;	/* -t, 0 for the driver's */

#ifndef LEGO_VERSION
#define LEGO_VERSION "unknown"
#endif

static int open_device(const char *dev, long timeout);
static double now_ms(void);
static void sleep_ms(unsigned int ms);
static const char *run_state_name(unsigned int s);

/* The device is opened on first use, after the arguments were checked. */
static int ensure_device(void)
{
	if (nxt_fd >= 0)
		return EXIT_OK;
	return open_device(dev_path, dev_timeout);
}

/* ---- errors ---- */

const char *status_name(unsigned int status)
{
	const char *name = lnxt_status_name(status);

	return name ? name : "unknown status";
}

int brick_error(const char *what, unsigned int status)
{
	progress_end();
	fprintf(stderr, "nxtctl: %s: %s (status 0x%02x)\n", what,
		status_name(status), status);
	return EXIT_BRICK;
}

int sys_error(const char *what, int err)
{
	progress_end();
	if (err == ETIMEDOUT)
		fprintf(stderr, "nxtctl: %s: %s: the brick did not answer within %u ms\n",
			what, strerror(err), timeout_ms);
	else if (err == ENODEV)
		fprintf(stderr, "nxtctl: %s: %s: the brick is gone (unplugged?)\n",
			what, strerror(err));
	else
		fprintf(stderr, "nxtctl: %s: %s\n", what, strerror(err));
	return EXIT_DEVICE;
}

static const struct command *find_command(const char *name);
static void print_usage(FILE *f, const struct command *c);
static void print_help(const struct command *c);

int usage_error(const char *cmd, const char *fmt, ...)
{
	va_list ap;

	fputs("nxtctl: ", stderr);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
	if (cmd && find_command(cmd))
		print_usage(stderr, find_command(cmd));
	else
		fputs("Try 'nxtctl --help'.\n", stderr);
	return EXIT_USAGE;
}

/* ---- transport ---- */

/* @t, zeroed, with the telegram @m to send. */
void load_telegram(struct nxt_transaction *t, const struct lnxt_msg *m)
{
	memset(t, 0, sizeof(*t));
	memcpy(t->telegram, m->buf, m->len);
	t->length = m->len;
}

int transact(struct nxt_transaction *t, const char *what)
{
	if (ensure_device())
		return EXIT_DEVICE;
	if (ioctl(nxt_fd, NXT_IOC_TRANSACT, t) < 0)
		return sys_error(what, errno);
	return EXIT_OK;
}

/*
 * Send @m and check that its reply answers it (lnxt_reply_check()): the
 * reply in @t and the brick's status byte in @status. Returns EXIT_DEVICE
 * after a transport error or a reply that does not answer @m.
 */
int exchange(const struct lnxt_msg *m, struct nxt_transaction *t, int *status,
	     const char *what)
{
	load_telegram(t, m);
	if (transact(t, what))
		return EXIT_DEVICE;
	*status = lnxt_reply_check(m, t->reply, t->reply_length);
	if (*status < 0) {
		progress_end();
		fprintf(stderr, "nxtctl: %s: the brick's reply does not answer it (%u bytes)\n",
			what, t->reply_length);
		return EXIT_DEVICE;
	}
	return EXIT_OK;
}

/* exchange(), and the brick's error status reported (EXIT_BRICK). */
int command(const struct lnxt_msg *m, struct nxt_transaction *t, const char *what)
{
	int ret, status;

	ret = exchange(m, t, &status, what);
	if (ret)
		return ret;
	return status ? brick_error(what, status) : EXIT_OK;
}

/* command() for a command whose reply has nothing but the status. */
static int simple(const struct lnxt_msg *m, const char *what)
{
	struct nxt_transaction t;

	return command(m, &t, what);
}

/* A reply that command() accepted and its parser refused. */
int bad_reply(const char *what)
{
	progress_end();
	fprintf(stderr, "nxtctl: %s: malformed reply\n", what);
	return EXIT_DEVICE;
}

/* ---- argument parsing ---- */

/* The options every command takes, after the command's own. */
#define OPT_DEVICE	'd'
#define OPT_TIMEOUT	't'
#define OPT_HELP	'h'
#define OPT_CMD		256	/* + the index in the command's table */

static int set_timeout_opt(const char *cmd, const char *s);

/* A negative number is a value ("motor A -50"), not an option. */
static int is_number(const char *s)
{
	return s[0] == '-' && s[1] >= '0' && s[1] <= '9';
}

/*
 * Parse the arguments of @cmd (argv[0] is its first argument) with
 * getopt_long: the options in @opts ("--name", "--name=VALUE" or "--name
 * VALUE"), -d/--device and -t/--timeout, and at least @min, at most @max
 * positional arguments into @pos. Options and positional arguments may
 * come in any order; "--" ends the options.
 */
int parse_opts(const char *cmd, int argc, char **argv, struct opt *opts,
	       char **pos, int *npos, int min, int max)
{
	int i, n = 0, nopts, c, idx, ret = EXIT_OK;
	struct option *lo;
	char **av, *arg;

	for (nopts = 0; opts && opts[nopts].name; nopts++)
		;
	lo = calloc(nopts + 4, sizeof(*lo));
	av = calloc(argc + 2, sizeof(*av));
	if (!lo || !av) {
		free(lo);
		free(av);
		fprintf(stderr, "nxtctl: %s\n", strerror(ENOMEM));
		return EXIT_DEVICE;
	}
	for (i = 0; i < nopts; i++) {
		lo[i].name = opts[i].name;
		lo[i].has_arg = opts[i].has_arg ? required_argument : no_argument;
		lo[i].val = OPT_CMD + i;
	}
	lo[i++] = (struct option){ "device", required_argument, NULL, OPT_DEVICE };
	lo[i++] = (struct option){ "timeout", required_argument, NULL, OPT_TIMEOUT };
	lo[i++] = (struct option){ "help", no_argument, NULL, OPT_HELP };
	av[0] = (char *)cmd;
	if (argc)
		memcpy(av + 1, argv, argc * sizeof(*av));
	argc++;

	opterr = 0;
	optind = 0;		/* a fresh scan (glibc and musl) */
	for (;;) {
		if (optind > 0 && optind < argc && is_number(av[optind])) {
			arg = av[optind++];
			goto positional;
		}
		idx = optind ? optind : 1;
		/* No -h here: main() takes "-h" alone, "-hello" is no help. */
		c = getopt_long(argc, av, "+:d:t:", lo, NULL);
		if (c == -1) {
			if (optind >= argc && !(optind == idx + 1 && !strcmp(av[idx], "--")))
				break;
			if (optind == idx + 1 && !strcmp(av[idx], "--")) {
				/* Everything after "--" is an argument. */
				while (optind < argc) {
					if (n >= max) {
						ret = usage_error(cmd, "%s: too many arguments",
								  cmd);
						goto out;
					}
					pos[n++] = av[optind++];
				}
				break;
			}
			arg = av[optind++];
positional:
			if (n >= max) {
				ret = usage_error(cmd, "%s: too many arguments", cmd);
				goto out;
			}
			pos[n++] = arg;
			continue;
		}
		switch (c) {
		case OPT_DEVICE:
			dev_path = optarg;
			break;
		case OPT_TIMEOUT:
			ret = set_timeout_opt(cmd, optarg);
			if (ret)
				goto out;
			break;
		case OPT_HELP:	/* main() sees most; "--he" comes here */
			print_help(find_command(cmd));
			ret = EXIT_HELP;
			goto out;
		case ':':
			ret = usage_error(cmd, "%s: option '%s' needs a value", cmd,
					  av[optind - 1]);
			goto out;
		case '?':
			arg = av[optind - 1];
			if (strncmp(arg, "--", 2))
				ret = usage_error(cmd, "%s: unknown option '-%c'", cmd, optopt);
			else if (optopt)
				ret = usage_error(cmd, "%s: option '%.*s' takes no value", cmd,
						  (int)strcspn(arg, "="), arg);
			else
				ret = usage_error(cmd, "%s: unknown option '%s'", cmd, arg);
			goto out;
		default:
			opts[c - OPT_CMD].set = 1;
			opts[c - OPT_CMD].arg = optarg;
			break;
		}
	}
	if (n < min) {
		ret = usage_error(cmd, "%s: missing arguments", cmd);
		goto out;
	}
	*npos = n;
out:
	free(lo);
	free(av);
	return ret;
}

static int parse_long(const char *s, long min, long max, long *val)
{
	char *end;
	long v;

	errno = 0;
	v = strtol(s, &end, 0);
	if (errno || end == s || *end || v < min || v > max)
		return -1;
	*val = v;
	return 0;
}

static int set_timeout_opt(const char *cmd, const char *s)
{
	if (parse_long(s, 1, 60000, &dev_timeout))
		return usage_error(cmd, "%s%s-t: the timeout is 1 to 60000 ms, not '%s'",
				   cmd ? cmd : "", cmd ? ": " : "", s);
	return EXIT_OK;
}

static int num_arg(const char *cmd, const char *what, const char *s, long min,
		   long max, long *val)
{
	if (parse_long(s, min, max, val))
		return usage_error(cmd, "%s: %s must be a number from %ld to %ld, not '%s'",
				   cmd, what, min, max, s);
	return EXIT_OK;
}

/* Motor ports: A, B, C (0 to 2), "all" where @all allows it. */
static int motor_port(const char *cmd, const char *s, int all, __u8 *port)
{
	if (all && !strcasecmp(s, "all")) {
		*port = LNXT_PORT_ALL;
		return EXIT_OK;
	}
	if (strlen(s) == 1 && toupper((unsigned char)s[0]) >= 'A' &&
	    toupper((unsigned char)s[0]) <= 'C') {
		*port = toupper((unsigned char)s[0]) - 'A';
		return EXIT_OK;
	}
	return usage_error(cmd, "%s: motor port must be A, B or C%s, not '%s'",
			   cmd, all ? " (or all)" : "", s);
}

/* Sensor ports: 1 to 4 (0 to 3 on the wire). */
static int sensor_port(const char *cmd, const char *s, __u8 *port)
{
	if (strlen(s) == 1 && s[0] >= '1' && s[0] <= '4') {
		*port = s[0] - '1';
		return EXIT_OK;
	}
	return usage_error(cmd, "%s: sensor port must be 1, 2, 3 or 4, not '%s'",
			   cmd, s);
}

int check_name(const char *cmd, const char *name)
{
	size_t i, len = strlen(name);

	if (len < 1 || len > LNXT_NAME_MAX)
		return usage_error(cmd, "%s: a file name on the brick has 1 to %d characters: '%s'",
				   cmd, LNXT_NAME_MAX, name);
	for (i = 0; i < len; i++)
		if (name[i] < 0x20 || name[i] > 0x7e)
			return usage_error(cmd, "%s: file names are printable ASCII: '%s'",
					   cmd, name);
	return EXIT_OK;
}

/* ---- device ---- */

static const char *find_device(void)
{
	static char path[64];
	glob_t g;

	if (glob("/dev/nxt[0-9]*", 0, NULL, &g))
		return NULL;
	snprintf(path, sizeof(path), "%s", g.gl_pathv[0]);
	globfree(&g);
	return path;
}

static int open_device(const char *dev, long timeout)
{
	__u32 t;
	int fd;

	if (!dev)
		dev = getenv("NXT_DEVICE");
	if (!dev || !*dev) {
		dev = find_device();
		if (!dev) {
			fprintf(stderr, "nxtctl: no NXT brick found (no /dev/nxt* device)\n");
			return EXIT_DEVICE;
		}
	}
	fd = open(dev, O_RDWR | O_CLOEXEC);
	if (fd < 0) {
		fprintf(stderr, "nxtctl: cannot open %s: %s\n", dev, strerror(errno));
		return EXIT_DEVICE;
	}
	nxt_fd = fd;
	if (timeout > 0) {
		t = timeout;
		if (ioctl(nxt_fd, NXT_IOC_SET_TIMEOUT, &t) < 0) {
			fprintf(stderr, "nxtctl: %s: cannot set the timeout: %s\n",
				dev, strerror(errno));
			return EXIT_DEVICE;
		}
		timeout_ms = t;
	} else if (ioctl(nxt_fd, NXT_IOC_GET_TIMEOUT, &t) == 0) {
		timeout_ms = t;
	} else {
		fprintf(stderr, "nxtctl: %s: not an NXT brick: %s\n", dev, strerror(errno));
		return EXIT_DEVICE;
	}
	return EXIT_OK;
}

/* ---- commands ---- */

static int read_attr(const char *node, const char *attr, char *buf, size_t size)
{
	char path[256];
	FILE *f;
	size_t n;

	snprintf(path, sizeof(path), "/sys/class/lego-nxt/%s/%s", node, attr);
	f = fopen(path, "r");
	if (!f)
		goto fail;
	n = fread(buf, 1, size - 1, f);
	if (ferror(f)) {
		fclose(f);
		goto fail;
	}
	fclose(f);
	buf[n] = 0;
	while (n && (buf[n - 1] == '\n' || buf[n - 1] == ' '))
		buf[--n] = 0;
	return 0;
fail:
	snprintf(buf, size, "?");
	return -1;
}

/*
 * Asks the brick behind @dev for its name and versions. The driver's
 * attributes show only what replies to its users' telegrams said, and
 * ENODATA before: this fills them. Does nothing if @dev cannot be opened
 * for writing.
 */
static void ask_brick_info(const char *dev)
{
	struct nxt_transaction t;
	struct lnxt_msg m[2];
	size_t i;
	int fd;

	fd = open(dev, O_RDWR | O_CLOEXEC);
	if (fd < 0)
		return;
	lnxt_get_device_info(&m[0]);
	lnxt_get_versions(&m[1]);
	for (i = 0; i < ARRAY_SIZE(m); i++) {
		load_telegram(&t, &m[i]);
		if (ioctl(fd, NXT_IOC_TRANSACT, &t) < 0)
			break;
	}
	close(fd);
}

/* The brick's name, address and firmware version; 0 if all were read. */
static int read_list_attrs(const char *node, char *name, char *addr, char *fw)
{
	int ret = 0;

	ret |= read_attr(node, "brick_name", name, 64);
	ret |= read_attr(node, "bt_address", addr, 64);
	ret |= read_attr(node, "firmware_version", fw, 32);
	return ret;
}

static int cmd_list(int argc, char **argv)
{
	char *pos[1], name[64], addr[64], fw[32];
	const char *node;
	int npos, ret;
	size_t i;
	glob_t g;

	ret = parse_opts("list", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	if (glob("/dev/nxt[0-9]*", 0, NULL, &g))
		return EXIT_OK;
	for (i = 0; i < g.gl_pathc; i++) {
		node = strrchr(g.gl_pathv[i], '/') + 1;
		if (read_list_attrs(node, name, addr, fw)) {
			ask_brick_info(g.gl_pathv[i]);
			read_list_attrs(node, name, addr, fw);
		}
		printf("%s\t%s\t%s\t%s\n", g.gl_pathv[i], name, addr, fw);
	}
	globfree(&g);
	return EXIT_OK;
}

static int battery_level(__u16 *mv)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	int ret;

	lnxt_get_battery_level(&m);
	ret = command(&m, &t, "GetBatteryLevel");
	if (ret)
		return ret;
	if (lnxt_parse_battery_level(t.reply, t.reply_length, mv))
		return bad_reply("GetBatteryLevel");
	return EXIT_OK;
}

static int cmd_info(int argc, char **argv)
{
	struct lnxt_device_info info;
	struct lnxt_versions v;
	struct nxt_transaction t;
	struct lnxt_msg m;
	const __u8 *a;
	int npos, ret;
	char *pos[1];
	__u16 mv;

	ret = parse_opts("info", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	lnxt_get_device_info(&m);
	ret = command(&m, &t, "GetDeviceInfo");
	if (ret)
		return ret;
	if (lnxt_parse_device_info(t.reply, t.reply_length, &info))
		return bad_reply("GetDeviceInfo");
	lnxt_get_versions(&m);
	ret = command(&m, &t, "GetVersions");
	if (ret)
		return ret;
	if (lnxt_parse_versions(t.reply, t.reply_length, &v))
		return bad_reply("GetVersions");
	ret = battery_level(&mv);
	if (ret)
		return ret;
	a = info.bt_address;
	printf("name: %s\n", info.name);
	printf("bt_address: %02x:%02x:%02x:%02x:%02x:%02x\n", a[0], a[1], a[2], a[3], a[4], a[5]);
	printf("firmware: %u.%02u\n", v.firmware_major, v.firmware_minor);
	printf("protocol: %u.%u\n", v.protocol_major, v.protocol_minor);
	printf("battery_mv: %u\n", mv);
	printf("free_flash: %u\n", info.free_flash);
	return EXIT_OK;
}

static int cmd_battery(int argc, char **argv)
{
	int npos, ret;
	char *pos[1];
	__u16 mv;

	ret = parse_opts("battery", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	ret = battery_level(&mv);
	if (ret)
		return ret;
	printf("%u\n", mv);
	return EXIT_OK;
}

static int cmd_keep_alive(int argc, char **argv)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];
	__u32 ms;

	ret = parse_opts("keep-alive", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	lnxt_keep_alive(&m);
	ret = command(&m, &t, "KeepAlive");
	if (ret)
		return ret;
	if (lnxt_parse_keep_alive(t.reply, t.reply_length, &ms))
		return bad_reply("KeepAlive");
	printf("%u\n", ms);
	return EXIT_OK;
}

static int cmd_tone(int argc, char **argv)
{
	struct lnxt_msg m;
	long freq, dur;
	int npos, ret;
	char *pos[2];

	ret = parse_opts("tone", argc, argv, NULL, pos, &npos, 2, 2);
	if (ret)
		return ret;
	ret = num_arg("tone", "FREQ_HZ", pos[0], TONE_MIN_HZ, TONE_MAX_HZ, &freq);
	if (ret)
		return ret;
	ret = num_arg("tone", "DURATION_MS", pos[1], 0, 65535, &dur);
	if (ret)
		return ret;
	lnxt_play_tone(&m, freq, dur);
	return simple(&m, "PlayTone");
}

static int cmd_play(int argc, char **argv)
{
	struct opt opts[] = { { .name = "loop" }, {} };
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("play", argc, argv, opts, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = check_name("play", pos[0]);
	if (ret)
		return ret;
	if (lnxt_play_sound_file(&m, opts[0].set, pos[0]))	/* checked */
		return EXIT_USAGE;
	return simple(&m, "PlaySoundFile");
}

static int cmd_stop_sound(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("stop-sound", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	lnxt_stop_sound_playback(&m);
	return simple(&m, "StopSoundPlayback");
}

/* GetOutputState of @port into @o. */
static int output_state(__u8 port, struct lnxt_output *o)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	int ret;

	if (lnxt_get_output_state(&m, port))
		return EXIT_USAGE;	/* checked */
	ret = command(&m, &t, "GetOutputState");
	if (ret)
		return ret;
	if (lnxt_parse_output_state(t.reply, t.reply_length, o))
		return bad_reply("GetOutputState");
	return EXIT_OK;
}

/* SetOutputState as @o says. */
static int set_output_state(const struct lnxt_output *o)
{
	struct lnxt_msg m;

	if (lnxt_set_output_state(&m, o))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "SetOutputState");
}

/*
 * --wait: poll GetOutputState until the motor on @port (each of the three
 * for LNXT_PORT_ALL) is back in run state idle, as the firmware puts it
 * when it reaches its tacho limit; give up after @wait_ms.
 */
static int wait_motors(__u8 port, long wait_ms)
{
	struct lnxt_output o, last = { 0 };
	double deadline = now_ms() + wait_ms;
	unsigned int busy = port == LNXT_PORT_ALL ? 7 : 1u << port;
	__u8 p;
	int ret;

	for (;;) {
		for (p = 0; p < 3; p++) {
			if (!(busy & 1u << p))
				continue;
			ret = output_state(p, &o);
			if (ret)
				return ret;
			if (o.run_state == LNXT_RUN_IDLE)
				busy &= ~(1u << p);
			else
				last = o;
		}
		if (!busy)
			return EXIT_OK;
		if (now_ms() > deadline) {
			fprintf(stderr, "nxtctl: motor %c: %s: ",
				'A' + last.port, strerror(ETIMEDOUT));
			fprintf(stderr, "still %s after %ld ms (tacho_count %d of %u)\n",
				run_state_name(last.run_state), wait_ms,
				last.tacho_count, last.tacho_limit);
			return EXIT_DEVICE;
		}
		sleep_ms(WAIT_POLL_MS);
	}
}

static int cmd_motor(int argc, char **argv)
{
	struct opt opts[] = {
		{ .name = "tacho-limit", .has_arg = 1 },
		{ .name = "brake" },
		{ .name = "regulated" },
		{ .name = "sync" },
		{ .name = "turn-ratio", .has_arg = 1 },
		{ .name = "wait" },
		{ .name = "wait-timeout", .has_arg = 1 },
		{}
	};
	struct lnxt_output o = { 0 };
	long power, limit = 0, turn = 0, wait_ms = DEFAULT_WAIT_MS;
	int npos, ret;
	char *pos[2];

	ret = parse_opts("motor", argc, argv, opts, pos, &npos, 2, 2);
	if (ret)
		return ret;
	ret = motor_port("motor", pos[0], 1, &o.port);
	if (ret)
		return ret;
	if (opts[6].set) {
		ret = num_arg("motor", "--wait-timeout", opts[6].arg, 1, 3600000, &wait_ms);
		if (ret)
			return ret;
	}
	if (!strcmp(pos[1], "stop") || !strcmp(pos[1], "coast") ||
	    !strcmp(pos[1], "brake")) {
		if (opts[5].set)
			return usage_error("motor",
					   "motor: --wait is for a move with --tacho-limit");
	}
	if (!strcmp(pos[1], "stop") || !strcmp(pos[1], "coast")) {
		/* Power off, the motor coasts to a stop. */
		o.run_state = LNXT_RUN_IDLE;
		return set_output_state(&o);
	}
	if (!strcmp(pos[1], "brake")) {
		/* Power 0 with the brake and speed regulation: hold still. */
		o.mode = LNXT_MODE_MOTORON | LNXT_MODE_BRAKE | LNXT_MODE_REGULATED;
		o.regulation = LNXT_REGULATION_SPEED;
		o.run_state = LNXT_RUN_RUNNING;
		return set_output_state(&o);
	}
	ret = num_arg("motor", "POWER", pos[1], -POWER_MAX, POWER_MAX, &power);
	if (ret)
		return ret;
	if (opts[0].set) {
		ret = num_arg("motor", "--tacho-limit", opts[0].arg, 0, 0x7fffffff, &limit);
		if (ret)
			return ret;
	}
	if (opts[4].set) {
		ret = num_arg("motor", "--turn-ratio", opts[4].arg, -POWER_MAX, POWER_MAX, &turn);
		if (ret)
			return ret;
	}
	if (opts[2].set && opts[3].set)
		return usage_error("motor", "motor: --regulated and --sync exclude each other");
	if (opts[5].set && (!limit || !power))
		return usage_error("motor",
				   "motor: --wait needs a non-zero POWER and a --tacho-limit");
	o.power = power;
	o.mode = LNXT_MODE_MOTORON;
	if (opts[1].set)
		o.mode |= LNXT_MODE_BRAKE;
	if (opts[2].set || opts[3].set)
		o.mode |= LNXT_MODE_REGULATED;
	o.regulation = opts[3].set ? LNXT_REGULATION_SYNC :
		       opts[2].set ? LNXT_REGULATION_SPEED : LNXT_REGULATION_IDLE;
	o.turn = turn;
	o.run_state = LNXT_RUN_RUNNING;
	o.tacho_limit = limit;
	ret = set_output_state(&o);
	if (ret || !opts[5].set)
		return ret;
	return wait_motors(o.port, wait_ms);
}

static const char *run_state_name(unsigned int s)
{
	switch (s) {
	case LNXT_RUN_IDLE:
		return "idle";
	case LNXT_RUN_RAMPUP:
		return "ramp-up";
	case LNXT_RUN_RUNNING:
		return "running";
	case LNXT_RUN_RAMPDOWN:
		return "ramp-down";
	}
	return "unknown";
}

static const char *const regulation_names[] = { "idle", "speed", "sync" };

static int cmd_motor_state(int argc, char **argv)
{
	struct lnxt_output o;
	int npos, ret;
	char *pos[1];
	__u8 port = 0;

	ret = parse_opts("motor-state", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = motor_port("motor-state", pos[0], 0, &port);
	if (ret)
		return ret;
	ret = output_state(port, &o);
	if (ret)
		return ret;
	printf("port: %c\n", 'A' + o.port);
	printf("power: %d\n", o.power);
	printf("mode:%s%s%s%s\n", o.mode & LNXT_MODE_MOTORON ? " on" : "",
	       o.mode & LNXT_MODE_BRAKE ? " brake" : "",
	       o.mode & LNXT_MODE_REGULATED ? " regulated" : "",
	       o.mode ? "" : " off");
	printf("regulation: %s\n", o.regulation < 3 ? regulation_names[o.regulation] : "unknown");
	printf("turn_ratio: %d\n", o.turn);
	printf("run_state: %s\n", run_state_name(o.run_state));
	printf("tacho_limit: %u\n", o.tacho_limit);
	printf("tacho_count: %d\n", o.tacho_count);
	printf("block_tacho_count: %d\n", o.block_tacho_count);
	printf("rotation_count: %d\n", o.rotation_count);
	return EXIT_OK;
}

static int cmd_reset_motor(int argc, char **argv)
{
	struct opt opts[] = { { .name = "relative" }, {} };
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];
	__u8 port = 0;

	ret = parse_opts("reset-motor", argc, argv, opts, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = motor_port("reset-motor", pos[0], 0, &port);
	if (ret)
		return ret;
	if (lnxt_reset_motor_position(&m, port, opts[0].set))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "ResetMotorPosition");
}

static const char *const sensor_types[LNXT_SENSOR_TYPES] = {
	[LNXT_SENSOR_NONE] = "none",
	[LNXT_SENSOR_SWITCH] = "touch",
	[LNXT_SENSOR_TEMPERATURE] = "temperature",
	[LNXT_SENSOR_REFLECTION] = "reflection",
	[LNXT_SENSOR_ANGLE] = "angle",
	[LNXT_SENSOR_LIGHT_ACTIVE] = "light-active",
	[LNXT_SENSOR_LIGHT_INACTIVE] = "light-inactive",
	[LNXT_SENSOR_SOUND_DB] = "sound-db",
	[LNXT_SENSOR_SOUND_DBA] = "sound-dba",
	[LNXT_SENSOR_CUSTOM] = "custom",
	[LNXT_SENSOR_LOWSPEED] = "lowspeed",
	[LNXT_SENSOR_LOWSPEED_9V] = "lowspeed-9v",
};

static const char *const sensor_modes[8] = {
	"raw", "bool", "transitions", "periods", "percent", "celsius",
	"fahrenheit", "angle-steps",
};

static int cmd_sensor_type(int argc, char **argv)
{
	struct opt opts[] = { { .name = "slope", .has_arg = 1 }, {} };
	int npos, ret, type = -1, mode = 0;
	struct lnxt_msg m;
	__u8 port = 0;
	long slope = 0;
	char *pos[3];
	int i;

	ret = parse_opts("sensor-type", argc, argv, opts, pos, &npos, 2, 3);
	if (ret)
		return ret;
	ret = sensor_port("sensor-type", pos[0], &port);
	if (ret)
		return ret;
	for (i = 0; i < LNXT_SENSOR_TYPES; i++)
		if (!strcasecmp(pos[1], sensor_types[i]))
			type = i;
	if (!strcasecmp(pos[1], "switch"))
		type = LNXT_SENSOR_SWITCH;
	if (!strcasecmp(pos[1], "ultrasonic"))
		type = LNXT_SENSOR_LOWSPEED_9V;
	if (type < 0)
		return usage_error("sensor-type", "sensor-type: unknown sensor type '%s'",
				   pos[1]);
	if (npos > 2) {
		mode = -1;
		for (i = 0; i < 8; i++)
			if (!strcasecmp(pos[2], sensor_modes[i]))
				mode = i;
		if (!strcasecmp(pos[2], "boolean"))
			mode = 1;
		if (mode < 0)
			return usage_error("sensor-type", "sensor-type: unknown sensor mode '%s'",
					   pos[2]);
	}
	if (opts[0].set) {
		ret = num_arg("sensor-type", "--slope", opts[0].arg, 0, 31, &slope);
		if (ret)
			return ret;
	}
	if (lnxt_set_input_mode(&m, port, type, mode << 5 | slope))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "SetInputMode");
}

/* GetInputValues of @port into @v. */
static int input_values(__u8 port, struct lnxt_input *v)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	int ret;

	if (lnxt_get_input_values(&m, port))
		return EXIT_USAGE;	/* checked */
	ret = command(&m, &t, "GetInputValues");
	if (ret)
		return ret;
	if (lnxt_parse_input_values(t.reply, t.reply_length, v))
		return bad_reply("GetInputValues");
	return EXIT_OK;
}

static int cmd_sensor(int argc, char **argv)
{
	struct lnxt_input v;
	int npos, ret;
	char *pos[1];
	__u8 port = 0;

	ret = parse_opts("sensor", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = sensor_port("sensor", pos[0], &port);
	if (ret)
		return ret;
	ret = input_values(port, &v);
	if (ret)
		return ret;
	printf("port: %u\n", v.port + 1);
	printf("type: %s\n", v.type < LNXT_SENSOR_TYPES ? sensor_types[v.type] : "unknown");
	printf("mode: %s\n", sensor_modes[v.mode >> 5]);
	printf("slope: %u\n", v.mode & 0x1f);
	printf("valid: %u\n", v.valid);
	printf("calibrated: %u\n", v.calibrated);
	printf("raw: %u\n", v.raw);
	printf("normalized: %u\n", v.normalized);
	printf("scaled: %d\n", v.scaled);
	printf("calibrated_value: %d\n", v.calibrated_value);
	return EXIT_OK;
}

static int cmd_reset_sensor(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];
	__u8 port = 0;

	ret = parse_opts("reset-sensor", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = sensor_port("reset-sensor", pos[0], &port);
	if (ret)
		return ret;
	if (lnxt_reset_input_scaled_value(&m, port))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "ResetInputScaledValue");
}

static double now_ms(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1000.0 + ts.tv_nsec / 1e6;
}

static void sleep_ms(unsigned int ms)
{
	struct timespec ts = { ms / 1000, (ms % 1000) * 1000000L };

	nanosleep(&ts, NULL);
}

/*
 * @m until the brick stops answering @busy (an I2C port not ready yet, a
 * transaction still running) or @deadline passes: EXIT_OK with the reply
 * in @t, or the error.
 */
static int retry_busy(const struct lnxt_msg *m, struct nxt_transaction *t, int busy,
		      double deadline, const char *what)
{
	int ret, status;

	for (;;) {
		ret = exchange(m, t, &status, what);
		if (ret)
			return ret;
		if (status != busy)
			return status ? brick_error(what, status) : EXIT_OK;
		if (now_ms() > deadline)
			return sys_error(what, ETIMEDOUT);
		sleep_ms(busy == LNXT_STATUS_PENDING ? 5 : 20);
	}
}

/* The LEGO ultrasonic sensor: I2C address 0x02, register 0x42 (cm). */
static int cmd_ultrasonic(int argc, char **argv)
{
	static const __u8 distance[] = { 0x02, 0x42 };
	struct nxt_transaction t;
	struct lnxt_input v;
	struct lnxt_data d;
	struct lnxt_msg m;
	double deadline;
	__u8 port = 0, ready;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("ultrasonic", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = sensor_port("ultrasonic", pos[0], &port);
	if (ret)
		return ret;
	ret = input_values(port, &v);
	if (ret)
		return ret;
	if (v.type != LNXT_SENSOR_LOWSPEED_9V) {
		lnxt_set_input_mode(&m, port, LNXT_SENSOR_LOWSPEED_9V, LNXT_SENSOR_MODE_RAW);
		ret = simple(&m, "SetInputMode");
		if (ret)
			return ret;
	}
	/* The port may need a moment after SetInputMode: retry while busy. */
	deadline = now_ms() + timeout_ms;
	lnxt_ls_write(&m, port, distance, sizeof(distance), 1);
	ret = retry_busy(&m, &t, LNXT_STATUS_CHANNEL_BUSY, deadline, "LSWrite");
	if (ret)
		return ret;
	lnxt_ls_get_status(&m, port);
	do {
		ret = retry_busy(&m, &t, LNXT_STATUS_PENDING, deadline, "LSGetStatus");
		if (ret)
			return ret;
		if (lnxt_parse_ls_get_status(t.reply, t.reply_length, &ready))
			return bad_reply("LSGetStatus");
		if (!ready && now_ms() > deadline)
			return sys_error("LSGetStatus (waiting for the sensor)", ETIMEDOUT);
		if (!ready)
			sleep_ms(5);
	} while (!ready);
	lnxt_ls_read(&m, port);
	ret = command(&m, &t, "LSRead");
	if (ret)
		return ret;
	if (lnxt_parse_ls_read(t.reply, t.reply_length, &d))
		return bad_reply("LSRead");
	if (d.len < 1) {
		fprintf(stderr, "nxtctl: LSRead: the sensor sent no data\n");
		return EXIT_DEVICE;
	}
	printf("%u\n", d.data[0]);
	return EXIT_OK;
}

static int mailbox(const char *cmd, const char *s, long max, __u8 *box)
{
	long v;
	int ret;

	ret = num_arg(cmd, "BOX", s, 0, max, &v);
	if (!ret)
		*box = v;
	return ret;
}

static int cmd_mailbox_send(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[2];
	size_t len;
	__u8 box;

	ret = parse_opts("mailbox-send", argc, argv, NULL, pos, &npos, 2, 2);
	if (ret)
		return ret;
	ret = mailbox("mailbox-send", pos[0], INBOXES - 1, &box);
	if (ret)
		return ret;
	len = strlen(pos[1]);
	if (len > LNXT_MESSAGE_MAX)
		return usage_error("mailbox-send", "mailbox-send: a message has at most %d bytes",
				   LNXT_MESSAGE_MAX);
	if (lnxt_message_write(&m, box, pos[1], len))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "MessageWrite");
}

static int cmd_mailbox_read(int argc, char **argv)
{
	struct opt opts[] = { { .name = "remove" }, {} };
	struct nxt_transaction t;
	struct lnxt_data d;
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];
	__u8 box;

	ret = parse_opts("mailbox-read", argc, argv, opts, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = mailbox("mailbox-read", pos[0], REMOTE_INBOXES - 1, &box);
	if (ret)
		return ret;
	/* The brick's remote inbox @box, into local inbox 0. */
	if (lnxt_message_read(&m, box, 0, opts[0].set))
		return EXIT_USAGE;	/* checked */
	ret = command(&m, &t, "MessageRead");
	if (ret)
		return ret;
	if (lnxt_parse_message_read(t.reply, t.reply_length, &d))
		return bad_reply("MessageRead");
	/* Up to the message's NUL. */
	printf("%.*s\n", (int)strnlen((char *)d.data, d.len), (char *)d.data);
	return EXIT_OK;
}

static int cmd_start(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("start", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	ret = check_name("start", pos[0]);
	if (ret)
		return ret;
	if (lnxt_start_program(&m, pos[0]))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "StartProgram");
}

static int cmd_stop(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("stop", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	lnxt_stop_program(&m);
	return simple(&m, "StopProgram");
}

static int cmd_current(int argc, char **argv)
{
	char name[LNXT_NAME_MAX + 1];
	struct nxt_transaction t;
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];

	ret = parse_opts("current", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	lnxt_get_current_program_name(&m);
	ret = command(&m, &t, "GetCurrentProgramName");
	if (ret)
		return ret;
	if (lnxt_parse_program_name(t.reply, t.reply_length, name))
		return bad_reply("GetCurrentProgramName");
	printf("%s\n", name);
	return EXIT_OK;
}

static int cmd_name(int argc, char **argv)
{
	struct lnxt_msg m;
	int npos, ret;
	char *pos[1];
	size_t i, len;

	ret = parse_opts("name", argc, argv, NULL, pos, &npos, 1, 1);
	if (ret)
		return ret;
	len = strlen(pos[0]);
	if (len < 1 || len > 15)
		return usage_error("name", "name: a brick name has 1 to 15 characters");
	for (i = 0; i < len; i++)
		if (pos[0][i] < 0x20 || pos[0][i] > 0x7e)
			return usage_error("name", "name: a brick name is printable ASCII");
	if (lnxt_set_brick_name(&m, pos[0]))
		return EXIT_USAGE;	/* checked */
	return simple(&m, "SetBrickName");
}

static int hex_digit(int c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	c = tolower(c);
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	return -1;
}

static int cmd_raw(int argc, char **argv)
{
	struct nxt_transaction t = {};
	const char *s;
	int i, hi, lo;
	__u32 k;

	if (argc < 1)
		return usage_error("raw", "raw: missing arguments");
	for (i = 0; i < argc; i++) {
		s = argv[i];
		if (!strncmp(s, "0x", 2) || !strncmp(s, "0X", 2))
			s += 2;
		if (!*s || strlen(s) % 2)
			return usage_error("raw", "raw: '%s' is not whole bytes in hex", argv[i]);
		for (; *s; s += 2) {
			hi = hex_digit((unsigned char)s[0]);
			lo = hex_digit((unsigned char)s[1]);
			if (hi < 0 || lo < 0)
				return usage_error("raw", "raw: '%s' is not hex", argv[i]);
			if (t.length >= NXT_TELEGRAM_MAX)
				return usage_error("raw", "raw: a telegram has at most %d bytes",
						   NXT_TELEGRAM_MAX);
			t.telegram[t.length++] = hi << 4 | lo;
		}
	}
	if (t.length < NXT_TELEGRAM_MIN)
		return usage_error("raw", "raw: a telegram has at least %d bytes",
				   NXT_TELEGRAM_MIN);
	if (transact(&t, "raw telegram"))
		return EXIT_DEVICE;
	for (k = 0; k < t.reply_length; k++)
		printf("%s%02x", k ? " " : "", t.reply[k]);
	if (t.reply_length)
		printf("\n");
	if (t.reply_length >= 3 && t.reply[2])
		return brick_error("raw telegram", t.reply[2]);
	return EXIT_OK;
}

/* ---- the command table and help ---- */

struct command {
	const char *name;
	int (*fn)(int argc, char **argv);
	const char *args;
	const char *help;
};

static int cmd_help(int argc, char **argv);

static const struct command commands[] = {
	{ "list", cmd_list, "",
	  "List the bricks present: device, name, Bluetooth address and firmware\n"
	  "version (from sysfs), one brick a line, separated by tabs.\n" },
	{ "info", cmd_info, "",
	  "Print the brick's name, Bluetooth address, firmware and protocol\n"
	  "versions, battery voltage (mV) and free flash (bytes).\n" },
	{ "battery", cmd_battery, "",
	  "Print the battery voltage in millivolts.\n" },
	{ "keep-alive", cmd_keep_alive, "",
	  "Reset the brick's sleep timer; print its sleep limit in milliseconds\n"
	  "(0: never sleeps).\n" },
	{ "tone", cmd_tone, "FREQ_HZ DURATION_MS",
	  "Play a tone of 200 to 14000 Hz for 0 to 65535 ms (returns at once).\n" },
	{ "play", cmd_play, "FILE.rso [--loop]",
	  "Play a sound file stored on the brick, once or (--loop) until\n"
	  "stop-sound.\n" },
	{ "stop-sound", cmd_stop_sound, "",
	  "Stop playing sound.\n" },
	{ "motor", cmd_motor,
	  "PORT POWER [--tacho-limit=DEG] [--wait] [--wait-timeout=MS] [--brake] [--regulated|--sync] [--turn-ratio=N]\n"
	  "       nxtctl motor PORT stop|brake",
	  "Run the motor on PORT (A, B, C or all) at POWER (-100 to 100), for\n"
	  "DEG degrees with --tacho-limit (0: no limit). --brake brakes between\n"
	  "the PWM pulses, --regulated turns on speed regulation, --sync\n"
	  "synchronises two motors (with --turn-ratio -100 to 100).\n"
	  "--wait waits until the move with --tacho-limit is over (the brick\n"
	  "reports run state idle), at most --wait-timeout ms (default 60000);\n"
	  "for 'all', until all three motors are.\n"
	  "'stop' turns the power off (the motor coasts), 'brake' holds the\n"
	  "motor still (power 0, brake and regulation on).\n" },
	{ "motor-state", cmd_motor_state, "PORT",
	  "Print the state of the motor on PORT (A, B or C): power, mode,\n"
	  "regulation, run state, tacho limit and the three counters.\n" },
	{ "reset-motor", cmd_reset_motor, "PORT [--relative]",
	  "Reset the motor's rotation count, or with --relative its block\n"
	  "tacho count (relative to the last movement).\n" },
	{ "sensor-type", cmd_sensor_type, "PORT TYPE [MODE] [--slope N]",
	  "Set the type and mode of sensor PORT (1 to 4). TYPE: none, touch,\n"
	  "temperature, reflection, angle, light-active, light-inactive,\n"
	  "sound-db, sound-dba, custom, lowspeed, lowspeed-9v (alias\n"
	  "ultrasonic). MODE (default raw): raw, bool, transitions, periods,\n"
	  "percent, celsius, fahrenheit, angle-steps; --slope 0 to 31.\n" },
	{ "sensor", cmd_sensor, "PORT",
	  "Read sensor PORT (1 to 4): type, mode, valid, raw, normalized,\n"
	  "scaled and calibrated values.\n" },
	{ "reset-sensor", cmd_reset_sensor, "PORT",
	  "Reset the scaled value (counters) of sensor PORT.\n" },
	{ "ultrasonic", cmd_ultrasonic, "PORT",
	  "Print the distance in cm measured by a LEGO ultrasonic sensor on\n"
	  "PORT (1 to 4), through LSWrite/LSGetStatus/LSRead (I2C address\n"
	  "0x02, register 0x42). Sets the port to lowspeed-9v first if needed.\n" },
	{ "mailbox-send", cmd_mailbox_send, "BOX TEXT",
	  "Put TEXT (at most 58 bytes) in inbox BOX (0 to 9) of the running\n"
	  "program.\n" },
	{ "mailbox-read", cmd_mailbox_read, "BOX [--remove]",
	  "Print the oldest message of the running program's mailbox BOX\n"
	  "(0 to 19; 10 to 19 are the outboxes the program writes to), and\n"
	  "with --remove take it out of the queue.\n" },
	{ "start", cmd_start, "PROGRAM.rxe",
	  "Start a program stored on the brick.\n" },
	{ "stop", cmd_stop, "",
	  "Stop the running program.\n" },
	{ "current", cmd_current, "",
	  "Print the name of the running program.\n" },
	{ "name", cmd_name, "NEWNAME",
	  "Rename the brick (1 to 15 printable ASCII characters).\n" },
	{ "raw", cmd_raw, "HEX...",
	  "Send one telegram, given as hex bytes (\"01 88\", \"0188\" or 0x01 0x88),\n"
	  "and print the reply in hex (nothing for the no-reply types 0x80 and\n"
	  "0x81). A reply with a non-zero status byte exits with 1.\n" },
	{ "upload", cmd_upload, "LOCAL [REMOTE] [--force]",
	  "Copy the file LOCAL to the brick as REMOTE (default: the base name\n"
	  "of LOCAL). --force deletes an existing REMOTE first.\n" },
	{ "download", cmd_download, "REMOTE [LOCAL]",
	  "Copy the file REMOTE from the brick to LOCAL (default: REMOTE in\n"
	  "the current directory; '-' for standard output).\n" },
	{ "ls", cmd_ls, "[PATTERN]",
	  "List the files on the brick matching PATTERN (default *.*; also\n"
	  "NAME.*, *.EXT or a full name): size in bytes and name.\n" },
	{ "rm", cmd_rm, "NAME",
	  "Delete the file NAME from the brick.\n" },
	{ "release", cmd_release, "[--serial=SERIAL]",
	  "Hand the brick to libusb programs (nxt-python's usb backend, NBC/NXC,\n"
	  "NeXTTool, leJOS): unbind lego_nxt_usb from it, so /dev/nxtN goes\n"
	  "away. -d takes /dev/nxtN or the brick's /dev/bus/usb/BBB/DDD;\n"
	  "--serial picks the brick by its USB serial number. Needs write\n"
	  "access to /dev/bus/usb/BBB/DDD only. Prints the serial and that node.\n" },
	{ "claim", cmd_claim, "[--serial=SERIAL]",
	  "Take a released brick back: lego_nxt_usb binds to it again and\n"
	  "/dev/nxtN comes back (printed). The brick is -d /dev/bus/usb/BBB/DDD,\n"
	  "--serial SERIAL, or the only released NXT.\n" },
	{ "connect", cmd_connect, "BDADDR [--channel=N] [--foreground]",
	  "Connect to the paired brick BDADDR (AA:BB:CC:DD:EE:FF) over Bluetooth\n"
	  "(RFCOMM channel 1, or N), attach it, and print its /dev/nxtN. A daemon\n"
	  "holds the link until nxtctl disconnect, or until the link is lost;\n"
	  "--foreground holds it in nxtctl itself (for a service). Root.\n" },
	{ "attach", cmd_attach, "TTY [--foreground]",
	  "Attach the brick on the serial line TTY (an RFCOMM tty bound with\n"
	  "rfcomm, or any tty that carries the brick's Bluetooth framing) and\n"
	  "print its /dev/nxtN; held as with connect. Root.\n" },
	{ "disconnect", cmd_disconnect, "",
	  "Let go of the brick -d /dev/nxtN that connect or attach made: the\n"
	  "node goes, and so does the Bluetooth link of connect. Prints the tty.\n" },
	{ "trace", cmd_trace, "[USBDEV]",
	  "Print the telegrams between the driver and the bricks (or the brick\n"
	  "USBDEV, e.g. 1-1), replies, timeouts, stalls, resets and drains of\n"
	  "stale replies, decoded, as they happen, until interrupted: from the\n"
	  "lego_nxt_usb trace events in tracefs (root).\n" },
	{ "help", cmd_help, "[COMMAND]",
	  "Print the help of COMMAND, or the list of commands.\n" },
};

#define NCOMMANDS	ARRAY_SIZE(commands)

static const struct command *find_command(const char *name)
{
	size_t i;

	for (i = 0; i < NCOMMANDS; i++)
		if (!strcmp(commands[i].name, name))
			return &commands[i];
	return NULL;
}

static void print_usage(FILE *f, const struct command *c)
{
	fprintf(f, "usage: nxtctl [-d DEVICE] [-t TIMEOUT_MS] %s%s%s\n", c->name,
		*c->args ? " " : "", c->args);
}

static void print_help(const struct command *c)
{
	print_usage(stdout, c);
	printf("\n%s", c->help);
}

static void print_main_help(FILE *f)
{
	size_t i;

	fputs("usage: nxtctl [-d DEVICE] [-t TIMEOUT_MS] COMMAND [ARGS...]\n"
	      "       nxtctl help COMMAND | nxtctl COMMAND --help | nxtctl --version\n"
	      "\n"
	      "Drive a LEGO MINDSTORMS NXT brick through /dev/nxtN.\n"
	      "\n"
	      "  -d, --device=DEVICE       the brick's device (default: $NXT_DEVICE,\n"
	      "                            else the first /dev/nxt*)\n"
	      "  -t, --timeout=TIMEOUT_MS  how long to wait for each reply, 1 to 60000\n"
	      "                            (default: the driver's, 1000)\n"
	      "  -h, --help                this help\n"
	      "  -V, --version             print the version\n"
	      "\n"
	      "Commands:\n", f);
	for (i = 0; i < NCOMMANDS; i++)
		fprintf(f, "  %s%s%.*s\n", commands[i].name,
			*commands[i].args ? " " : "",
			(int)strcspn(commands[i].args, "\n"), commands[i].args);
	fputs("\n"
	      "Options take their value as --opt=VALUE or --opt VALUE and may come\n"
	      "after the command: nxtctl motor A 50 --tacho-limit=360 --wait\n"
	      "\n"
	      "Exit status: 0 success, 1 the brick answered with an error status,\n"
	      "2 usage error, 3 device, transport or local I/O error.\n"
	      "See nxtctl(1).\n", f);
}

static int cmd_help(int argc, char **argv)
{
	const struct command *c;

	if (argc == 0) {
		print_main_help(stdout);
		return EXIT_OK;
	}
	if (argc > 1)
		return usage_error("help", "help: too many arguments");
	c = find_command(argv[0]);
	if (!c)
		return usage_error(NULL, "unknown command '%s'", argv[0]);
	print_help(c);
	return EXIT_OK;
}

int main(int argc, char **argv)
{
	static const struct option lo[] = {
		{ "device", required_argument, NULL, 'd' },
		{ "timeout", required_argument, NULL, 't' },
		{ "help", no_argument, NULL, 'h' },
		{ "version", no_argument, NULL, 'V' },
		{}
	};
	const struct command *c;
	int i, ret, opt;

	opterr = 0;
	while ((opt = getopt_long(argc, argv, "+:d:t:hV", lo, NULL)) != -1) {
		switch (opt) {
		case 'd':
			dev_path = optarg;
			break;
		case 't':
			ret = set_timeout_opt(NULL, optarg);
			if (ret)
				return ret;
			break;
		case 'h':
			print_main_help(stdout);
			return EXIT_OK;
		case 'V':
			printf("nxtctl %s\n", LEGO_VERSION);
			return EXIT_OK;
		case ':':
			return usage_error(NULL, "option '%s' needs a value", argv[optind - 1]);
		default:
			if (strncmp(argv[optind - 1], "--", 2))
				return usage_error(NULL, "unknown option '-%c'", optopt);
			return usage_error(NULL, "unknown option '%s'", argv[optind - 1]);
		}
	}
	if (optind >= argc)
		return usage_error(NULL, "no command given");
	c = find_command(argv[optind]);
	if (!c)
		return usage_error(NULL, "unknown command '%s'", argv[optind]);
	argc -= optind + 1;
	argv += optind + 1;
	for (i = 0; i < argc; i++) {
		if (!strcmp(argv[i], "--"))
			break;
		if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
			print_help(c);
			return EXIT_OK;
		}
	}
	ret = c->fn(argc, argv);
	if (ret == EXIT_HELP)
		ret = EXIT_OK;
	if (nxt_fd >= 0)
		close(nxt_fd);
	if (fflush(stdout) || ferror(stdout)) {
		fprintf(stderr, "nxtctl: writing the output: %s\n", strerror(errno));
		return EXIT_DEVICE;
	}
	return ret;
}
