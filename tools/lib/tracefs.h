/* SPDX-License-Identifier: GPL-2.0 */
/*
 * The trace events of one system in tracefs, for the tools' live protocol
 * views (lego-sensors --trace, nxtctl trace): find the mount, enable the
 * events with a filter, read trace_pipe line by line until SIGINT or
 * SIGTERM, and pick the fields out of a line.
 */
#ifndef LEGO_TOOLS_TRACEFS_H
#define LEGO_TOOLS_TRACEFS_H

#include <stddef.h>

/*
 * One system's events in a tracefs mount: @dir once tracefs_find() found
 * it, @system as in events/SYSTEM.
 */
struct tracefs {
	const char *system;
	char dir[4096];
};

int tracefs_find(struct tracefs *t, const char *system);
int tracefs_enable(struct tracefs *t, const char *filter);
void tracefs_disable(struct tracefs *t);
int tracefs_read(struct tracefs *t, const char *prefix,
		 void (*line)(const char *ts, const char *ev,
			      const char *fields, void *arg),
		 void *arg);
const char *tracefs_field(const char *fields, const char *key, char *buf,
			  size_t size);

#endif
