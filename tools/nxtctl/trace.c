// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl trace: the telegrams between the driver and the bricks, live,
 * from the lego_nxt_usb trace events in tracefs (see
 * Documentation/lego/tracing.rst), one line each, decoded.
 */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include "nxtctl.h"

#define SYSTEM	"lego_nxt_usb"

static char tracefs[PATH_MAX];

static const struct {
	unsigned int op;
	const char *name;
} opcodes[] = {
	{ 0x00, "StartProgram" }, { 0x01, "StopProgram" },
	{ 0x02, "PlaySoundFile" }, { 0x03, "PlayTone" },
	{ 0x04, "SetOutputState" }, { 0x05, "SetInputMode" },
	{ 0x06, "GetOutputState" }, { 0x07, "GetInputValues" },
	{ 0x08, "ResetInputScaledValue" }, { 0x09, "MessageWrite" },
	{ 0x0a, "ResetMotorPosition" }, { 0x0b, "GetBatteryLevel" },
	{ 0x0c, "StopSoundPlayback" }, { 0x0d, "KeepAlive" },
	{ 0x0e, "LSGetStatus" }, { 0x0f, "LSWrite" }, { 0x10, "LSRead" },
	{ 0x11, "GetCurrentProgramName" }, { 0x13, "MessageRead" },
	{ 0x80, "OpenRead" }, { 0x81, "OpenWrite" }, { 0x82, "Read" },
	{ 0x83, "Write" }, { 0x84, "Close" }, { 0x85, "Delete" },
	{ 0x86, "FindFirst" }, { 0x87, "FindNext" },
	{ 0x88, "GetFirmwareVersion" }, { 0x89, "OpenWriteLinear" },
	{ 0x8b, "OpenWriteData" }, { 0x8c, "OpenAppendData" },
	{ 0x90, "RequestFirstModule" }, { 0x91, "RequestNextModule" },
	{ 0x92, "CloseModuleHandle" }, { 0x94, "ReadIOMap" },
	{ 0x95, "WriteIOMap" }, { 0x97, "Boot" }, { 0x98, "SetBrickName" },
	{ 0x9b, "GetDeviceInfo" }, { 0xa0, "DeleteUserFlash" },
};

static const char *opname(const char *hex, char *buf, size_t size)
{
	unsigned long op = strtoul(hex, NULL, 16);
	size_t i;

	for (i = 0; i < ARRAY_SIZE(opcodes); i++)
		if (opcodes[i].op == op)
			return opcodes[i].name;
	snprintf(buf, size, "opcode %s", hex);
	return buf;
}

/* Write @val to the tracefs file @name. Returns 0 or -errno. */
static int trace_write(const char *name, const char *val)
{
	char path[PATH_MAX + 64];
	int fd, ret = 0;

	snprintf(path, sizeof(path), "%s/events/" SYSTEM "/%s", tracefs, name);
	fd = open(path, O_WRONLY | O_TRUNC | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	if (write(fd, val, strlen(val)) < 0)
		ret = -errno;
	close(fd);
	return ret;
}

static int find_tracefs(void)
{
	static const char *const where[] = {
		"/sys/kernel/tracing", "/sys/kernel/debug/tracing",
	};
	char path[PATH_MAX + 64];
	const char *dir;
	size_t i;

	/* $TRACEFS first, then the usual mounts. */
	for (i = 0; i <= ARRAY_SIZE(where); i++) {
		dir = i ? where[i - 1] : getenv("TRACEFS");
		if (!dir || !*dir)
			continue;
		snprintf(path, sizeof(path), "%s/events/" SYSTEM, dir);
		if (!access(path, F_OK)) {
			snprintf(tracefs, sizeof(tracefs), "%s", dir);
			return 0;
		}
	}
	return -1;
}

/* The value of @key in a trace line's fields ("a=1 b=\"x y\""); "" if none. */
static const char *field(const char *fields, const char *key, char *buf,
			 size_t size)
{
	size_t klen = strlen(key), n = 0;
	const char *p = fields;
	char end = ' ';

	buf[0] = '\0';
	while ((p = strstr(p, key))) {
		if ((p == fields || p[-1] == ' ') && p[klen] == '=')
			break;
		p += klen;
	}
	if (!p)
		return buf;
	p += klen + 1;
	if (*p == '"') {
		end = '"';
		p++;
	}
	while (*p && *p != end && n + 1 < size)
		buf[n++] = *p++;
	buf[n] = '\0';
	return buf;
}

static void trace_line(const char *line)
{
	char ev[32], ts[32], dev[64], a[64], b[64], c[64], d[64], o[80];
	const char *p = strstr(line, ": nxt_usb_"), *q, *f;
	size_t n;

	if (!p)
		return;
	for (q = p; q > line && q[-1] != ' '; q--)
		;
	n = (size_t)(p - q) < sizeof(ts) ? (size_t)(p - q) : sizeof(ts) - 1;
	memcpy(ts, q, n);
	ts[n] = '\0';
	p += 2;
	q = strchr(p, ':');
	if (!q)
		return;
	n = (size_t)(q - p) < sizeof(ev) ? (size_t)(q - p) : sizeof(ev) - 1;
	memcpy(ev, p, n);
	ev[n] = '\0';
	for (f = q + 1; *f == ' '; f++)
		;
	printf("%s %-8s ", ts, field(f, "dev", dev, sizeof(dev)));
	field(f, "opcode", a, sizeof(a));
	if (!strcmp(ev, "nxt_usb_tx")) {
		unsigned long type = strtoul(field(f, "type", b, sizeof(b)), NULL, 16);

		printf("-> %s (%s%s, %s bytes)", opname(a, o, sizeof(o)),
		       type & 1 ? "system" : "direct", type & 0x80 ? ", no reply" : "",
		       field(f, "len", c, sizeof(c)));
		field(f, "ret", d, sizeof(d));
		printf(strcmp(d, "0") ? ": not sent, %s\n" : "\n", d);
	} else if (!strcmp(ev, "nxt_usb_rx")) {
		field(f, "status", b, sizeof(b));
		printf("<- %s reply, %s bytes", opname(a, o, sizeof(o)),
		       field(f, "len", c, sizeof(c)));
		if (strtoul(b, NULL, 16))
			printf(", status %s: %s\n", b, status_name(strtoul(b, NULL, 16)));
		else
			printf("\n");
	} else if (!strcmp(ev, "nxt_usb_done")) {
		int err = atoi(field(f, "err", b, sizeof(b)));

		if (err)
			printf("== %s failed: %s\n", opname(a, o, sizeof(o)), strerror(-err));
		else
			printf("== %s done\n", opname(a, o, sizeof(o)));
	} else if (!strcmp(ev, "nxt_usb_timeout")) {
		printf("== %s timed out: %s\n", opname(a, o, sizeof(o)),
		       field(f, "what", b, sizeof(b)));
	} else if (!strcmp(ev, "nxt_usb_stall")) {
		printf("== %s endpoint stalled (%s IN stalls in a row)\n",
		       field(f, "endpoint", b, sizeof(b)), field(f, "stalls", c, sizeof(c)));
	} else if (!strcmp(ev, "nxt_usb_reset")) {
		printf("== %s\n", field(f, "event", b, sizeof(b)));
	} else if (!strcmp(ev, "nxt_usb_drain")) {
		printf("== draining stale replies for up to %s ms",
		       field(f, "ms", b, sizeof(b)));
		if (!strcmp(field(f, "orphan", c, sizeof(c)), "1"))
			printf(", until the late reply to %s",
			       opname(field(f, "orphan_op", d, sizeof(d)), o, sizeof(o)));
		printf("\n");
	} else if (!strcmp(ev, "nxt_usb_drop")) {
		printf("<- dropped (%s): type %s %s, %s bytes%s\n",
		       field(f, "why", b, sizeof(b)), field(f, "type", c, sizeof(c)),
		       opname(a, o, sizeof(o)), field(f, "len", d, sizeof(d)),
		       !strcmp(field(f, "drain_end", ev, sizeof(ev)), "1") ?
		       ", the drain is over" : "");
	} else {
		printf("%s %s\n", ev, f);
	}
}

/* Reads trace_pipe until SIGINT or SIGTERM (through a signalfd). */
static int trace_loop(void)
{
	char path[PATH_MAX + 64], buf[8192], *nl, *start;
	struct pollfd pfd[2];
	size_t len = 0;
	sigset_t set;
	ssize_t n;

	sigemptyset(&set);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGTERM);
	sigprocmask(SIG_BLOCK, &set, NULL);
	snprintf(path, sizeof(path), "%s/trace_pipe", tracefs);
	pfd[0].fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
	pfd[1].fd = signalfd(-1, &set, SFD_CLOEXEC);
	if (pfd[0].fd < 0 || pfd[1].fd < 0)
		return sys_error(path, errno);
	pfd[0].events = POLLIN;
	pfd[1].events = POLLIN;
	setvbuf(stdout, NULL, _IOLBF, 0);
	for (;;) {
		if (poll(pfd, 2, -1) < 0 && errno != EINTR)
			break;
		if (pfd[1].revents)
			break;
		if (!pfd[0].revents)
			continue;
		n = read(pfd[0].fd, buf + len, sizeof(buf) - 1 - len);
		if (n < 0 && (errno == EAGAIN || errno == EINTR))
			continue;
		if (n <= 0)
			break;
		len += n;
		buf[len] = '\0';
		for (start = buf; (nl = strchr(start, '\n')); start = nl + 1) {
			*nl = '\0';
			trace_line(start);
		}
		len -= start - buf;
		memmove(buf, start, len);
		if (len == sizeof(buf) - 1) {
			trace_line(buf);
			len = 0;
		}
	}
	close(pfd[0].fd);
	close(pfd[1].fd);
	return EXIT_OK;
}

int cmd_trace(int argc, char **argv)
{
	char filter[128], *pos[1];
	int npos, ret;

	ret = parse_opts("trace", argc, argv, NULL, pos, &npos, 0, 1);
	if (ret)
		return ret;
	if (find_tracefs()) {
		fprintf(stderr, "nxtctl: trace: no " SYSTEM " events in tracefs: is the driver\n"
			"loaded, and tracefs mounted (mount -t tracefs nodev /sys/kernel/tracing)?\n");
		return EXIT_DEVICE;
	}
	if (npos)
		snprintf(filter, sizeof(filter), "dev == \"%s\"", pos[0]);
	ret = trace_write("filter", npos ? filter : "0");
	if (!ret)
		ret = trace_write("enable", "1");
	if (ret)
		return sys_error("trace: enabling the events (root needed)", -ret);
	ret = trace_loop();
	trace_write("enable", "0");
	trace_write("filter", "0");
	return ret;
}
