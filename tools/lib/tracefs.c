// SPDX-License-Identifier: GPL-2.0
/*
 * The trace events of one system in tracefs: see tracefs.h and
 * Documentation/lego/tracing.rst.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include "tracefs.h"

#ifndef ARRAY_SIZE
#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))
#endif

/* Write @val to events/SYSTEM/@name. Returns 0 or -errno. */
static int tracefs_write(const struct tracefs *t, const char *name,
			 const char *val)
{
	char path[sizeof(t->dir) + 128];
	int fd, ret = 0;

	snprintf(path, sizeof(path), "%s/events/%s/%s", t->dir, t->system, name);
	fd = open(path, O_WRONLY | O_TRUNC | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	if (write(fd, val, strlen(val)) < 0)
		ret = -errno;
	close(fd);
	return ret;
}

/*
 * Where tracefs is mounted with @system's events: $TRACEFS first, then the
 * usual mounts. Returns 0, or -ENOENT if nowhere (the driver is not loaded
 * or tracefs is not mounted).
 */
int tracefs_find(struct tracefs *t, const char *system)
{
	static const char *const where[] = {
		"/sys/kernel/tracing", "/sys/kernel/debug/tracing",
	};
	char path[sizeof(t->dir) + 128];
	const char *dir;
	size_t i;

	t->system = system;
	for (i = 0; i <= ARRAY_SIZE(where); i++) {
		dir = i ? where[i - 1] : getenv("TRACEFS");
		if (!dir || !*dir || strlen(dir) >= sizeof(t->dir))
			continue;
		snprintf(path, sizeof(path), "%s/events/%s", dir, system);
		if (!access(path, F_OK)) {
			snprintf(t->dir, sizeof(t->dir), "%s", dir);
			return 0;
		}
	}
	return -ENOENT;
}

/*
 * Enable the system's events, with the event filter @filter (e.g.
 * "tty == \"ttyS1\""), or all of them if @filter is NULL. Returns 0 or
 * -errno (-EACCES: root is needed).
 */
int tracefs_enable(struct tracefs *t, const char *filter)
{
	int ret = tracefs_write(t, "filter", filter ? filter : "0");

	return ret ? ret : tracefs_write(t, "enable", "1");
}

/* Disable the events again and drop the filter. */
void tracefs_disable(struct tracefs *t)
{
	tracefs_write(t, "enable", "0");
	tracefs_write(t, "filter", "0");
}

/*
 * Split one line of trace_pipe ("  task-1  [000] .....  12.345678: ev: f")
 * at ": @prefix" and pass its timestamp, event name and fields to @line.
 * Lines of other events are left out.
 */
static void tracefs_split(const char *text, const char *prefix,
			  void (*line)(const char *, const char *,
				       const char *, void *),
			  void *arg)
{
	char pat[64], ts[32], ev[64];
	const char *p, *q;
	size_t n;

	snprintf(pat, sizeof(pat), ": %s", prefix);
	p = strstr(text, pat);
	if (!p)
		return;
	/* The timestamp ends where the event's name starts. */
	for (q = p; q > text && q[-1] != ' '; q--)
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
	for (q++; *q == ' '; q++)
		;
	line(ts, ev, q, arg);
}

/*
 * Read trace_pipe until SIGINT or SIGTERM (taken through a signalfd, so
 * the caller can disable the events afterwards) or its end, passing each
 * line of an event whose name starts with @prefix to @line. Returns 0 or
 * -errno if trace_pipe cannot be read.
 */
int tracefs_read(struct tracefs *t, const char *prefix,
		 void (*line)(const char *ts, const char *ev,
			      const char *fields, void *arg),
		 void *arg)
{
	char path[sizeof(t->dir) + 32], buf[8192], *nl, *start;
	struct pollfd pfd[2];
	size_t len = 0;
	sigset_t set;
	ssize_t n;
	int ret = 0;

	sigemptyset(&set);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGTERM);
	sigprocmask(SIG_BLOCK, &set, NULL);
	snprintf(path, sizeof(path), "%s/trace_pipe", t->dir);
	pfd[0].fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
	pfd[1].fd = signalfd(-1, &set, SFD_CLOEXEC);
	if (pfd[0].fd < 0 || pfd[1].fd < 0) {
		ret = -errno;
		goto out;
	}
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
		/* Whole lines; a line longer than the buffer is cut. */
		for (start = buf; (nl = strchr(start, '\n')); start = nl + 1) {
			*nl = '\0';
			tracefs_split(start, prefix, line, arg);
		}
		len -= start - buf;
		memmove(buf, start, len);
		if (len == sizeof(buf) - 1) {
			tracefs_split(buf, prefix, line, arg);
			len = 0;
		}
	}
out:
	if (pfd[0].fd >= 0)
		close(pfd[0].fd);
	if (pfd[1].fd >= 0)
		close(pfd[1].fd);
	return ret;
}

/*
 * The value of @key in a trace line's fields ("a=1 b=\"x y\""), into @buf;
 * "" if absent. Returns @buf.
 */
const char *tracefs_field(const char *fields, const char *key, char *buf,
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
	while (*p && *p != end && *p != '\n' && n + 1 < size)
		buf[n++] = *p++;
	buf[n] = '\0';
	return buf;
}
