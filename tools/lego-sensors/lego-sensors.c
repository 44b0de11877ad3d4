// SPDX-License-Identifier: GPL-2.0
/*
 * lego-sensors: list the EV3 sensors of the lego-sensor class, like
 * sensors(1) lists hardware monitors, watch them, or switch their mode.
 *
 *   lego-sensors [--json] [--watch[=SECONDS]] [SENSOR...]
 *   lego-sensors --mode=MODE [SENSOR]
 *   lego-sensors --trace[=TTY]
 *
 * Everything comes from /sys/class/lego-sensor/sensorN (see
 * Documentation/ABI/testing/sysfs-class-lego-sensor) and from the IIO
 * device the driver registers beside each sensor: labelled with the
 * sensor's address and parented to the same tty. --trace prints the
 * protocol live from the driver's trace events, in tracefs.
 */
#define _GNU_SOURCE	/* open_memstream(), strchrnul() */
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/signalfd.h>
#include <time.h>
#include <unistd.h>

#include "tracefs.h"

#ifndef LEGO_VERSION
#define LEGO_VERSION "unknown"
#endif

#define MAX_VALUES	8	/* value0 .. value7 */
#define MAX_SELECT	32
#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))

enum {
	EXIT_OK = 0,
	EXIT_FAIL = 1,		/* no sensors, unknown sensor, mode refused... */
	EXIT_USAGE = 2,
};

struct value {
	bool ok;
	int err;		/* errno of the read when !ok */
	long long raw;		/* valueN: the number times 10^decimals */
};

struct sensor {
	int num;		/* N of sensorN */
	char name[32];
	char address[64];
	char driver[64];
	char mode[64];
	char modes[512];
	char units[32];
	char bin_format[16];
	int decimals;
	int num_values;
	struct value values[MAX_VALUES];
	char iio[32];		/* iio:deviceN, or "" */
};

static const char *prog = "lego-sensors";
static const char *sysfs = "/sys";

#define err(fmt, ...) fprintf(stderr, "%s: " fmt "\n", prog, ##__VA_ARGS__)

static void print_help(FILE *f)
{
	fprintf(f,
		"Usage: %s [OPTIONS] [SENSOR...]\n"
		"       %s --mode=MODE [SENSOR]\n"
		"       %s --trace[=TTY]\n"
		"List the LEGO EV3 sensors of /sys/class/lego-sensor: address, driver,\n"
		"mode, values with their units, and IIO device.\n"
		"SENSOR is a name (sensor0), an address (ttyAMA0:in1), its tty (ttyAMA0)\n"
		"or its port label (in1); without one, every sensor is shown.\n"
		"\n"
		"  -s, --sensor=SENSOR     show only SENSOR (may be repeated)\n"
		"  -w, --watch[=SECONDS]   redraw every SECONDS (default 1, at least 0.1)\n"
		"                          until interrupted\n"
		"  -j, --json              one JSON document (one per line with --watch)\n"
		"  -m, --mode=MODE         switch SENSOR to MODE (one of its modes), then\n"
		"                          show it; SENSOR may be left out if there is\n"
		"                          only one sensor\n"
		"  -t, --trace[=TTY]       print the protocol on TTY (every tty with the\n"
		"                          discipline if none), decoded, as it happens,\n"
		"                          until interrupted: from the lego_ev3_uart trace\n"
		"                          events (root; tracefs mounted)\n"
		"  -h, --help              this help\n"
		"  -V, --version           the version\n"
		"\n"
		"Exit status: 0 ok, 1 no sensors, no such sensor or mode switch failed,\n"
		"2 usage error.\n",
		prog, prog, prog);
}

/* ---- sysfs ------------------------------------------------------------ */

/*
 * Read attribute `name` of directory `dfd` into buf, without the trailing
 * newline. Returns 0 or a negative errno.
 */
static int read_attr(int dfd, const char *name, char *buf, size_t size)
{
	ssize_t n;
	size_t len = 0;
	int fd, e;

	fd = openat(dfd, name, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	while (len < size - 1) {
		n = read(fd, buf + len, size - 1 - len);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			e = errno;
			close(fd);
			return -e;
		}
		if (!n)
			break;
		len += n;
	}
	close(fd);
	buf[len] = '\0';
	while (len && buf[len - 1] == '\n')
		buf[--len] = '\0';
	return 0;
}

static int read_int(int dfd, const char *name, long long *v)
{
	char buf[64], *end;
	int ret;

	ret = read_attr(dfd, name, buf, sizeof(buf));
	if (ret)
		return ret;
	errno = 0;
	*v = strtoll(buf, &end, 10);
	if (errno || end == buf || *end)
		return -EINVAL;
	return 0;
}

static bool gone(int ret)
{
	return ret == -ENOENT || ret == -ENODEV;
}

/* The realpath of `dir`/`sub`, or false. */
static bool real(const char *dir, const char *sub, char *out)
{
	char p[PATH_MAX];

	if (snprintf(p, sizeof(p), "%s/%s", dir, sub) >= (int)sizeof(p))
		return false;
	return realpath(p, out);
}

/*
 * The IIO device of a sensor: the driver registers it with the tty as its
 * parent (as the sensor's) and the sensor's address as its label.
 */
static void find_iio(const char *spath, struct sensor *s)
{
	char tty[PATH_MAX], dev[PATH_MAX], base[PATH_MAX], label[64];
	struct dirent *de;
	char *slash;
	DIR *d;
	int dfd;

	s->iio[0] = '\0';
	if (!real(spath, "device", tty))
		return;
	snprintf(base, sizeof(base), "%s/bus/iio/devices", sysfs);
	d = opendir(base);
	if (!d)
		return;
	while ((de = readdir(d))) {
		if (strncmp(de->d_name, "iio:device", 10))
			continue;
		if (!real(base, de->d_name, dev))
			continue;
		slash = strrchr(dev, '/');
		if (!slash)
			continue;
		*slash = '\0';
		if (strcmp(dev, tty))
			continue;
		*slash = '/';
		dfd = open(dev, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
		if (dfd < 0)
			continue;
		/* A kernel without IIO labels: the name is the driver's. */
		if (read_attr(dfd, "label", label, sizeof(label)) &&
		    read_attr(dfd, "name", label, sizeof(label))) {
			close(dfd);
			continue;
		}
		close(dfd);
		if (strcmp(label, s->address) && strcmp(label, s->driver))
			continue;
		if (snprintf(s->iio, sizeof(s->iio), "%s", de->d_name) >=
		    (int)sizeof(s->iio))
			s->iio[0] = '\0';
		break;
	}
	closedir(d);
}

/*
 * Read one sensor. Returns 0, or a negative errno; -ENOENT or -ENODEV when
 * it went away meanwhile. The directory is read through one descriptor, so
 * a sensorN name given to the next sensor meanwhile is not mixed in.
 */
static int read_sensor(const char *cls, const char *name, struct sensor *s)
{
	char path[PATH_MAX], attr[16];
	long long v;
	int dfd, ret, i;

	memset(s, 0, sizeof(*s));
	if (snprintf(s->name, sizeof(s->name), "%s", name) >= (int)sizeof(s->name))
		return -ENAMETOOLONG;
	s->num = atoi(name + strlen("sensor"));
	if (snprintf(path, sizeof(path), "%s/%s", cls, name) >= (int)sizeof(path))
		return -ENAMETOOLONG;
	dfd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (dfd < 0)
		return -errno;

	ret = read_attr(dfd, "address", s->address, sizeof(s->address));
	if (!ret)
		ret = read_attr(dfd, "driver_name", s->driver, sizeof(s->driver));
	if (!ret)
		ret = read_attr(dfd, "mode", s->mode, sizeof(s->mode));
	if (!ret)
		ret = read_attr(dfd, "modes", s->modes, sizeof(s->modes));
	if (!ret)
		ret = read_attr(dfd, "units", s->units, sizeof(s->units));
	if (!ret && read_attr(dfd, "bin_data_format", s->bin_format,
			      sizeof(s->bin_format)))
		s->bin_format[0] = '\0';
	if (!ret) {
		ret = read_int(dfd, "decimals", &v);
		s->decimals = v < 0 || v > 18 ? 0 : (int)v;
	}
	if (!ret) {
		ret = read_int(dfd, "num_values", &v);
		s->num_values = v < 0 ? 0 : v > MAX_VALUES ? MAX_VALUES : (int)v;
	}
	for (i = 0; !ret && i < s->num_values; i++) {
		snprintf(attr, sizeof(attr), "value%d", i);
		s->values[i].err = -read_int(dfd, attr, &s->values[i].raw);
		s->values[i].ok = !s->values[i].err;
		if (gone(-s->values[i].err))
			ret = -s->values[i].err;
	}
	close(dfd);
	if (!ret)
		find_iio(path, s);
	return ret;
}

static int by_number(const void *a, const void *b)
{
	const struct sensor *x = a, *y = b;

	return (x->num > y->num) - (x->num < y->num);
}

/*
 * Every sensor, sorted by number. Returns the count, or -1 if the class
 * does not exist (the module is not loaded).
 */
static int read_sensors(struct sensor **out)
{
	struct sensor *list = NULL, *bigger;
	char cls[PATH_MAX];
	struct dirent *de;
	int n = 0, cap = 0;
	DIR *d;

	snprintf(cls, sizeof(cls), "%s/class/lego-sensor", sysfs);
	d = opendir(cls);
	if (!d) {
		*out = NULL;
		return -1;
	}
	while ((de = readdir(d))) {
		if (strncmp(de->d_name, "sensor", 6) || !isdigit(de->d_name[6]))
			continue;
		if (n == cap) {
			cap = cap ? 2 * cap : 8;
			bigger = realloc(list, cap * sizeof(*list));
			if (!bigger)
				break;
			list = bigger;
		}
		/* A sensor that went away meanwhile is left out. */
		if (!read_sensor(cls, de->d_name, &list[n]))
			n++;
	}
	closedir(d);
	qsort(list, n, sizeof(*list), by_number);
	*out = list;
	return n;
}

/* ---- selection -------------------------------------------------------- */

/* SENSOR: sensorN, the address, its tty or its port label. */
static bool matches(const struct sensor *s, const char *sel)
{
	const char *colon = strchr(s->address, ':');
	size_t ttylen = colon ? (size_t)(colon - s->address) : strlen(s->address);

	if (!strcmp(sel, s->name) || !strcmp(sel, s->address))
		return true;
	if (strlen(sel) == ttylen && !strncmp(sel, s->address, ttylen))
		return true;
	return colon && !strcmp(sel, colon + 1);
}

static bool selected(const struct sensor *s, char **sel, int nsel)
{
	int i;

	if (!nsel)
		return true;
	for (i = 0; i < nsel; i++)
		if (matches(s, sel[i]))
			return true;
	return false;
}

static void list_names(FILE *f, const struct sensor *list, int n)
{
	int i;

	for (i = 0; i < n; i++)
		fprintf(f, "%s%s (%s)", i ? ", " : "", list[i].name, list[i].address);
}

/*
 * Check that each selector names exactly one sensor. Returns an exit
 * status.
 */
static int check_selection(const struct sensor *list, int n, char **sel, int nsel)
{
	int i, j, hits;

	for (i = 0; i < nsel; i++) {
		for (hits = 0, j = 0; j < n; j++)
			hits += matches(&list[j], sel[i]);
		if (hits == 1)
			continue;
		fprintf(stderr, "%s: %s \"%s\"; sensors: ", prog,
			hits ? "more than one sensor matches" : "no sensor", sel[i]);
		list_names(stderr, list, n);
		fputc('\n', stderr);
		return EXIT_FAIL;
	}
	return EXIT_OK;
}

/* ---- output ----------------------------------------------------------- */

/* raw / 10^dec, exactly, e.g. 263 and 1 give "26.3", -5 and 2 "-0.05". */
static void scaled(char *buf, size_t size, long long raw, int dec)
{
	unsigned long long a = raw < 0 ? -(unsigned long long)raw : (unsigned long long)raw;
	unsigned long long p = 1;
	int i;

	if (!dec) {
		snprintf(buf, size, "%lld", raw);
		return;
	}
	for (i = 0; i < dec; i++)
		p *= 10;
	snprintf(buf, size, "%s%llu.%0*llu", raw < 0 ? "-" : "", a / p, dec, a % p);
}

static void print_text(FILE *f, const struct sensor *s)
{
	char num[48];
	int i;

	fprintf(f, "%s\n", s->name);
	fprintf(f, "%-9s%s\n", "Address:", s->address);
	fprintf(f, "%-9s%s\n", "Driver:", s->driver);
	fprintf(f, "%-9s%s\n", "Mode:", s->mode);
	fprintf(f, "%-9s%s\n", "Modes:", s->modes);
	fprintf(f, "%-9s%s\n", "IIO:", s->iio[0] ? s->iio : "none");
	for (i = 0; i < s->num_values; i++) {
		fprintf(f, "value%d:  ", i);
		if (!s->values[i].ok) {
			fprintf(f, "unreadable (%s)\n", strerror(s->values[i].err));
			continue;
		}
		scaled(num, sizeof(num), s->values[i].raw, s->decimals);
		fprintf(f, "%s%s%s\n", num, s->units[0] ? " " : "", s->units);
	}
}

static void json_str(FILE *f, const char *str)
{
	const unsigned char *p;

	fputc('"', f);
	for (p = (const unsigned char *)str; *p; p++) {
		switch (*p) {
		case '"':
			fputs("\\\"", f);
			break;
		case '\\':
			fputs("\\\\", f);
			break;
		case '\n':
			fputs("\\n", f);
			break;
		case '\t':
			fputs("\\t", f);
			break;
		default:
			/* Control characters, and any byte that is not ASCII
			 * (sysfs strings should have none): always valid JSON.
			 */
			if (*p < 0x20 || *p >= 0x7f)
				fprintf(f, "\\u%04x", *p);
			else
				fputc(*p, f);
		}
	}
	fputc('"', f);
}

/* nl: newline and indentation, or "" for one line. */
static void print_json(FILE *f, const struct sensor *s, bool pretty)
{
	const char *nl = pretty ? "\n    " : "", *sp = pretty ? " " : "";
	const char *p, *end;
	char num[48];
	int i;

	fprintf(f, "{%s\"name\":%s", nl, sp);
	json_str(f, s->name);
	fprintf(f, ",%s\"address\":%s", nl, sp);
	json_str(f, s->address);
	fprintf(f, ",%s\"driver\":%s", nl, sp);
	json_str(f, s->driver);
	fprintf(f, ",%s\"mode\":%s", nl, sp);
	json_str(f, s->mode);
	fprintf(f, ",%s\"modes\":%s[", nl, sp);
	for (i = 0, p = s->modes; *p; i++) {
		char name[sizeof(s->modes)];

		end = strchrnul(p, ' ');
		snprintf(name, sizeof(name), "%.*s", (int)(end - p), p);
		fprintf(f, "%s%s", i ? "," : "", i ? sp : "");
		json_str(f, name);
		p = *end ? end + 1 : end;
	}
	fprintf(f, "],%s\"num_values\":%s%d", nl, sp, s->num_values);
	fprintf(f, ",%s\"decimals\":%s%d", nl, sp, s->decimals);
	fprintf(f, ",%s\"units\":%s", nl, sp);
	json_str(f, s->units);
	fprintf(f, ",%s\"values\":%s[", nl, sp);
	for (i = 0; i < s->num_values; i++) {
		fprintf(f, "%s%s", i ? "," : "", i ? sp : "");
		if (s->values[i].ok) {
			scaled(num, sizeof(num), s->values[i].raw, s->decimals);
			fputs(num, f);
		} else {
			fputs("null", f);
		}
	}
	fprintf(f, "],%s\"raw_values\":%s[", nl, sp);
	for (i = 0; i < s->num_values; i++) {
		fprintf(f, "%s%s", i ? "," : "", i ? sp : "");
		if (s->values[i].ok)
			fprintf(f, "%lld", s->values[i].raw);
		else
			fputs("null", f);
	}
	fprintf(f, "],%s\"bin_data_format\":%s", nl, sp);
	json_str(f, s->bin_format);
	fprintf(f, ",%s\"iio_device\":%s", nl, sp);
	if (s->iio[0])
		json_str(f, s->iio);
	else
		fputs("null", f);
	fprintf(f, "%s}", pretty ? "\n  " : "");
}

/*
 * One listing of the selected sensors. In JSON an empty list is a valid
 * answer; in text it is a line saying so.
 */
static void print_all(FILE *f, const struct sensor *list, int n, char **sel,
		      int nsel, bool json, bool pretty)
{
	int i, shown = 0;

	if (json)
		fprintf(f, "{%s\"sensors\":%s[", pretty ? "\n  " : "", pretty ? " " : "");
	for (i = 0; i < n; i++) {
		if (!selected(&list[i], sel, nsel))
			continue;
		if (json) {
			fputs(shown ? (pretty ? ", " : ",") : "", f);
			print_json(f, &list[i], pretty);
		} else {
			fputs(shown ? "\n" : "", f);
			print_text(f, &list[i]);
		}
		shown++;
	}
	if (json)
		fprintf(f, "]%s}\n", pretty ? "\n" : "");
	else if (!shown)
		fprintf(f, "No EV3 sensors found.\n");
}

/* Why there is nothing to show, and what to do. */
static void no_sensors(FILE *f, bool no_class)
{
	fprintf(f, "%s: no EV3 sensors: ", prog);
	if (no_class)
		fprintf(f, "the lego-sensor class does not exist (%s)\n",
			"is the lego_ev3_uart module loaded? modprobe lego_ev3_uart");
	else
		fprintf(f, "none found (%s)\n",
			"is a sensor wired and its tty attached? see lego-ev3-attach(8)");
}

/* ---- mode ------------------------------------------------------------- */

static int set_mode(const struct sensor *s, const char *mode)
{
	char path[PATH_MAX];
	size_t len = strlen(mode);
	ssize_t n;
	int fd, e;

	snprintf(path, sizeof(path), "%s/class/lego-sensor/%s/mode", sysfs, s->name);
	fd = open(path, O_WRONLY | O_CLOEXEC);
	if (fd < 0) {
		e = errno;
		err("%s: cannot open %s: %s%s", s->name, path, strerror(e),
		    e == EACCES ? " (run as root or as a member of the group lego)" : "");
		return EXIT_FAIL;
	}
	/* Returns once the sensor confirmed the mode (up to about 1.5 s). */
	do {
		n = write(fd, mode, len);
	} while (n < 0 && errno == EINTR);
	e = errno;
	close(fd);
	if (n == (ssize_t)len)
		return EXIT_OK;
	switch (e) {
	case EINVAL:
		err("%s: no mode \"%s\"; modes: %s", s->name, mode, s->modes);
		break;
	case EBUSY:
		err("%s: cannot switch to %s: %s (%s)", s->name, mode, strerror(e),
		    "an IIO buffer of the sensor is enabled on another mode");
		break;
	case ETIMEDOUT:
		err("%s: cannot switch to %s: %s (the sensor did not confirm the mode)",
		    s->name, mode, strerror(e));
		break;
	case ENODEV:
	case ENOENT:
		err("%s: cannot switch to %s: %s (the sensor is gone)", s->name, mode,
		    strerror(e));
		break;
	default:
		err("%s: cannot switch to %s: %s", s->name, mode,
		    n >= 0 ? "short write" : strerror(e));
	}
	return EXIT_FAIL;
}

/* ---- watch ------------------------------------------------------------ */

/*
 * Wait `secs` for one of the blocked signals in `set`. Returns true if one
 * came: time to stop.
 */
static bool wait_signal(const sigset_t *set, double secs)
{
	struct timespec ts, t0, t1;
	double left = secs;

	clock_gettime(CLOCK_MONOTONIC, &t0);
	for (;;) {
		ts.tv_sec = (time_t)left;
		ts.tv_nsec = (long)((left - (double)ts.tv_sec) * 1e9);
		if (sigtimedwait(set, NULL, &ts) >= 0)
			return true;
		if (errno != EINTR)
			return false;
		/* Another signal (SIGWINCH, SIGCONT): sleep on. */
		clock_gettime(CLOCK_MONOTONIC, &t1);
		left = secs - (double)(t1.tv_sec - t0.tv_sec) -
		       (double)(t1.tv_nsec - t0.tv_nsec) / 1e9;
		if (left <= 0)
			return false;
	}
}

static int watch(char **sel, int nsel, bool json, double interval)
{
	bool tty = isatty(STDOUT_FILENO);
	struct sensor *list;
	sigset_t set;
	char *frame, stamp[64];
	size_t size;
	time_t now;
	FILE *f;
	int n;

	/* SIGINT and SIGTERM end the watch, read by sigtimedwait(). */
	sigemptyset(&set);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGTERM);
	sigprocmask(SIG_BLOCK, &set, NULL);

	for (;;) {
		f = open_memstream(&frame, &size);
		if (!f) {
			err("out of memory");
			return EXIT_FAIL;
		}
		n = read_sensors(&list);
		if (json) {
			print_all(f, list, n < 0 ? 0 : n, sel, nsel, true, false);
		} else {
			now = time(NULL);
			strftime(stamp, sizeof(stamp), "%Y-%m-%d %H:%M:%S",
				 localtime(&now));
			/* Like watch(1): what, how often, and when. */
			if (tty)
				fputs("\033[H\033[2J", f);
			fprintf(f, "Every %.1fs: lego-sensors%*s%s\n\n", interval,
				20, "", stamp);
			if (n < 0)
				no_sensors(f, true);
			else
				print_all(f, list, n, sel, nsel, false, false);
			if (!tty)
				fputc('\n', f);
		}
		free(list);
		fclose(f);
		if (fwrite(frame, 1, size, stdout) != size || fflush(stdout)) {
			err("write error: %s", strerror(errno));
			free(frame);
			return EXIT_FAIL;
		}
		free(frame);
		if (wait_signal(&set, interval))
			return EXIT_OK;
	}
}

/* ---- main ------------------------------------------------------------- */

/* ---- --trace ------------------------------------------------------------ */

/*
 * The protocol, live: the lego_ev3_uart trace events (see
 * Documentation/lego/tracing.rst) read from tracefs's trace_pipe and
 * printed one message a line. The events are enabled for the run and
 * disabled again when it is interrupted (tools/lib/tracefs.c).
 */

/* A CMD message's name, from its header. */
static const char *cmd_name(unsigned int cmd)
{
	static const char *const names[] = {
		"TYPE", "MODES", "SPEED", "SELECT", "WRITE", "CMD5", "EXT_MODE", "VERSION",
	};

	return names[cmd & 7];
}

/* What the ev3_uart_rx event's accept field says, for a DATA message. */
static const char *accept_note(const char *accept)
{
	if (!strcmp(accept, "rgb-raw-quirk"))
		return ", checksum not checked (RGB-RAW quirk)";
	if (!strcmp(accept, "us-dc-in-quirk"))
		return ", tagged mode 5 (US-DC-IN quirk)";
	return "";
}

static const char *info_name(unsigned int info)
{
	switch (info & ~0x20U) {
	case 0x00: return "NAME";
	case 0x01: return "RAW";
	case 0x02: return "PCT";
	case 0x03: return "SI";
	case 0x04: return "UNITS";
	case 0x80: return "FORMAT";
	default: return "INFO";
	}
}

/* One event of trace_pipe, decoded, to the FILE @arg. */
static void trace_line(const char *ts, const char *ev, const char *fields,
		       void *arg)
{
	char tty[64], a[64], b[64], c[64], d[64];
	FILE *f = arg;

	tracefs_field(fields, "tty", tty, sizeof(tty));
	fprintf(f, "%s %-8s ", ts, tty);

	if (!strcmp(ev, "ev3_uart_rx")) {
		unsigned int hdr = strtoul(tracefs_field(fields, "hdr", a, sizeof(a)), NULL, 16);
		unsigned int info = strtoul(tracefs_field(fields, "info", b, sizeof(b)), NULL, 16);

		tracefs_field(fields, "msg", a, sizeof(a));
		tracefs_field(fields, "arg", b, sizeof(b));
		tracefs_field(fields, "len", c, sizeof(c));
		if (!strcmp(a, "TYPE"))
			fprintf(f, "<- TYPE %s\n", b);
		else if (!strcmp(a, "CMD"))
			fprintf(f, "<- %s (%s bytes)\n", cmd_name(hdr), c);
		else if (!strcmp(a, "INFO"))
			fprintf(f, "<- INFO mode %u %s (%s bytes)\n",
				(hdr & 7) + (info & 0x20 ? 8 : 0), info_name(info), c);
		else if (!strcmp(a, "ACK"))
			fprintf(f, "<- ACK: handshake complete, %s modes\n", b);
		else
			fprintf(f, "<- %s mode %s, %s bytes%s%s\n", a, b, c,
				!strcmp(tracefs_field(fields, "mode_changed", d, sizeof(d)), "1") ?
				", mode switched" : "",
				accept_note(tracefs_field(fields, "accept", d, sizeof(d))));
	} else if (!strcmp(ev, "ev3_uart_tx")) {
		tracefs_field(fields, "msg", a, sizeof(a));
		tracefs_field(fields, "arg", b, sizeof(b));
		tracefs_field(fields, "len", c, sizeof(c));
		tracefs_field(fields, "ret", d, sizeof(d));
		if (!strcmp(a, "SELECT"))
			fprintf(f, "-> SELECT mode %s", b);
		else if (!strcmp(a, "WRITE"))
			fprintf(f, "-> WRITE %s bytes", c);
		else if (!strcmp(a, "SPEED"))
			fprintf(f, "-> SPEED 115200 (fast sync probe)");
		else
			fprintf(f, "-> %s", a);
		fprintf(f, strcmp(d, "0") ? " (not sent: %s)\n" : "\n", d);
	} else if (!strcmp(ev, "ev3_uart_handshake")) {
		fprintf(f, "== sensor type %s: %s modes (%s shown), %s baud\n",
			tracefs_field(fields, "type", a, sizeof(a)),
			tracefs_field(fields, "modes", b, sizeof(b)),
			tracefs_field(fields, "view_modes", c, sizeof(c)),
			tracefs_field(fields, "speed", d, sizeof(d)));
	} else if (!strcmp(ev, "ev3_uart_speed")) {
		tracefs_field(fields, "ret", b, sizeof(b));
		fprintf(f, "== %s baud%s\n", tracefs_field(fields, "speed", a, sizeof(a)),
			strcmp(b, "0") ? " (not supported by the tty)" : "");
	} else if (!strcmp(ev, "ev3_uart_state")) {
		fprintf(f, "== %s -> %s", tracefs_field(fields, "from", a, sizeof(a)),
			tracefs_field(fields, "to", b, sizeof(b)));
		tracefs_field(fields, "reason", c, sizeof(c));
		fprintf(f, *c ? ": %s\n" : "\n", c);
	} else if (!strcmp(ev, "ev3_uart_sensor")) {
		tracefs_field(fields, "dev", c, sizeof(c));
		fprintf(f, "== sensor %s: %s%s%s\n", tracefs_field(fields, "event", a, sizeof(a)),
			tracefs_field(fields, "driver", b, sizeof(b)), *c ? " as " : "", c);
	} else {
		fprintf(f, "%s %s\n", ev, fields);
	}
}

/* --trace[=TTY]: until interrupted (SIGINT, SIGTERM) or the end of input. */
static int trace(const char *tty)
{
	struct tracefs t;
	char filter[128];
	int ret;

	if (tracefs_find(&t, "lego_ev3_uart")) {
		err("no lego_ev3_uart events in tracefs: is lego_ev3_uart loaded, and tracefs\n"
		    "mounted (mount -t tracefs nodev /sys/kernel/tracing)?");
		return EXIT_FAIL;
	}
	if (tty && *tty)
		snprintf(filter, sizeof(filter), "tty == \"%s\"", tty);
	ret = tracefs_enable(&t, tty && *tty ? filter : NULL);
	if (ret) {
		tracefs_disable(&t);
		err("cannot enable the events in %s: %s (root needed)", t.dir, strerror(-ret));
		return EXIT_FAIL;
	}
	/* The signals end the read, which lets the events be disabled. */
	ret = tracefs_read(&t, "ev3_uart_", trace_line, stdout);
	tracefs_disable(&t);
	if (ret) {
		err("%s/trace_pipe: %s", t.dir, strerror(-ret));
		return EXIT_FAIL;
	}
	return EXIT_OK;
}

static bool parse_interval(const char *arg, double *out)
{
	char *end;
	double v;

	errno = 0;
	v = strtod(arg, &end);
	if (errno || end == arg || *end || !isfinite(v) || v < 0.1 || v > 86400)
		return false;
	*out = v;
	return true;
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {
		{ "sensor", required_argument, NULL, 's' },
		{ "watch", optional_argument, NULL, 'w' },
		{ "json", no_argument, NULL, 'j' },
		{ "mode", required_argument, NULL, 'm' },
		{ "trace", optional_argument, NULL, 't' },
		{ "help", no_argument, NULL, 'h' },
		{ "version", no_argument, NULL, 'V' },
		{ NULL, 0, NULL, 0 }
	};
	char *sel[MAX_SELECT], addr[64];
	const char *mode = NULL, *env;
	bool json = false, do_watch = false;
	double interval = 1.0;
	struct sensor *list;
	int c, i, n, nsel = 0, ret, target = -1;

	env = getenv("SYSFS_PATH");
	if (env && *env)
		sysfs = env;
	while ((c = getopt_long(argc, argv, "s:w::jm:t::hV", opts, NULL)) != -1) {
		switch (c) {
		case 's':
			if (nsel == MAX_SELECT) {
				err("at most %d sensors can be selected", MAX_SELECT);
				return EXIT_USAGE;
			}
			sel[nsel++] = optarg;
			break;
		case 'w':
			do_watch = true;
			if (optarg && !parse_interval(optarg, &interval)) {
				err("bad interval \"%s\": seconds from 0.1 to 86400", optarg);
				return EXIT_USAGE;
			}
			break;
		case 'j':
			json = true;
			break;
		case 'm':
			if (!*optarg) {
				err("--mode needs a mode name");
				return EXIT_USAGE;
			}
			mode = optarg;
			break;
		case 't':
			return trace(optarg);
		case 'h':
			print_help(stdout);
			return EXIT_OK;
		case 'V':
			printf("%s %s\n", prog, LEGO_VERSION);
			return EXIT_OK;
		default:
			fprintf(stderr, "Try '%s --help' for more information.\n", prog);
			return EXIT_USAGE;
		}
	}
	for (i = optind; i < argc; i++) {
		if (nsel == MAX_SELECT) {
			err("at most %d sensors can be selected", MAX_SELECT);
			return EXIT_USAGE;
		}
		sel[nsel++] = argv[i];
	}
	if (mode && nsel > 1) {
		err("--mode switches one sensor: %d given", nsel);
		return EXIT_USAGE;
	}

	n = read_sensors(&list);
	if (n <= 0 && !do_watch) {
		no_sensors(stderr, n < 0);
		free(list);
		return EXIT_FAIL;
	}
	ret = check_selection(list, n < 0 ? 0 : n, sel, nsel);
	if (ret && !(do_watch && n <= 0)) {
		free(list);
		return ret;
	}

	if (mode) {
		if (n <= 0) {
			no_sensors(stderr, n < 0);
			free(list);
			return EXIT_FAIL;
		}
		if (!nsel && n > 1) {
			fprintf(stderr, "%s: %d sensors: name the one to switch: ", prog, n);
			list_names(stderr, list, n);
			fputc('\n', stderr);
			free(list);
			return EXIT_USAGE;
		}
		for (i = 0; i < n; i++)
			if (selected(&list[i], sel, nsel))
				target = i;
		ret = set_mode(&list[target], mode);
		if (ret) {
			free(list);
			return ret;
		}
		/* From now on show the switched sensor, by its address (its
		 * sensorN would name another one after a reconnect).
		 */
		snprintf(addr, sizeof(addr), "%s", list[target].address);
		sel[0] = addr;
		nsel = 1;
		free(list);
		n = read_sensors(&list);
	}

	if (do_watch) {
		free(list);
		return watch(sel, nsel, json, interval);
	}
	print_all(stdout, list, n < 0 ? 0 : n, sel, nsel, json, true);
	free(list);
	if (fflush(stdout) || ferror(stdout)) {
		err("write error: %s", strerror(errno));
		return EXIT_FAIL;
	}
	return EXIT_OK;
}
