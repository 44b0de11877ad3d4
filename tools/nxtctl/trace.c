// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl trace: the telegrams between the driver and the bricks, live,
 * from the lego_nxt_usb trace events in tracefs (see
 * Documentation/lego/tracing.rst), one line each, decoded.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nxtctl.h"
#include "tracefs.h"

#define SYSTEM	"lego_nxt_usb"

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

/* One event of trace_pipe, decoded, to the FILE @arg. */
static void trace_line(const char *ts, const char *ev, const char *f,
		       void *arg)
{
	char dev[64], a[64], b[64], c[64], d[64], e[8], o[80];
	FILE *out = arg;

	fprintf(out, "%s %-8s ", ts, tracefs_field(f, "dev", dev, sizeof(dev)));
	tracefs_field(f, "opcode", a, sizeof(a));
	if (!strcmp(ev, "nxt_usb_tx")) {
		unsigned long type = strtoul(tracefs_field(f, "type", b, sizeof(b)), NULL, 16);

		fprintf(out, "-> %s (%s%s, %s bytes)", opname(a, o, sizeof(o)),
			type & 1 ? "system" : "direct", type & 0x80 ? ", no reply" : "",
			tracefs_field(f, "len", c, sizeof(c)));
		tracefs_field(f, "ret", d, sizeof(d));
		fprintf(out, strcmp(d, "0") ? ": not sent, %s\n" : "\n", d);
	} else if (!strcmp(ev, "nxt_usb_rx")) {
		tracefs_field(f, "status", b, sizeof(b));
		fprintf(out, "<- %s reply, %s bytes", opname(a, o, sizeof(o)),
			tracefs_field(f, "len", c, sizeof(c)));
		if (strtoul(b, NULL, 16))
			fprintf(out, ", status %s: %s\n", b, status_name(strtoul(b, NULL, 16)));
		else
			fprintf(out, "\n");
	} else if (!strcmp(ev, "nxt_usb_done")) {
		int err = atoi(tracefs_field(f, "err", b, sizeof(b)));

		if (err)
			fprintf(out, "== %s failed: %s\n", opname(a, o, sizeof(o)), strerror(-err));
		else
			fprintf(out, "== %s done\n", opname(a, o, sizeof(o)));
	} else if (!strcmp(ev, "nxt_usb_timeout")) {
		fprintf(out, "== %s timed out: %s\n", opname(a, o, sizeof(o)),
			tracefs_field(f, "what", b, sizeof(b)));
	} else if (!strcmp(ev, "nxt_usb_stall")) {
		fprintf(out, "== %s endpoint stalled (%s IN stalls in a row)\n",
			tracefs_field(f, "endpoint", b, sizeof(b)),
			tracefs_field(f, "stalls", c, sizeof(c)));
	} else if (!strcmp(ev, "nxt_usb_reset")) {
		fprintf(out, "== %s\n", tracefs_field(f, "event", b, sizeof(b)));
	} else if (!strcmp(ev, "nxt_usb_drain")) {
		fprintf(out, "== draining stale replies for up to %s ms",
			tracefs_field(f, "ms", b, sizeof(b)));
		if (!strcmp(tracefs_field(f, "orphan", c, sizeof(c)), "1"))
			fprintf(out, ", until the late reply to %s",
				opname(tracefs_field(f, "orphan_op", d, sizeof(d)), o, sizeof(o)));
		fprintf(out, "\n");
	} else if (!strcmp(ev, "nxt_usb_drop")) {
		fprintf(out, "<- dropped (%s): type %s %s, %s bytes%s\n",
			tracefs_field(f, "why", b, sizeof(b)),
			tracefs_field(f, "type", c, sizeof(c)), opname(a, o, sizeof(o)),
			tracefs_field(f, "len", d, sizeof(d)),
			!strcmp(tracefs_field(f, "drain_end", e, sizeof(e)), "1") ?
			", the drain is over" : "");
	} else {
		fprintf(out, "%s %s\n", ev, f);
	}
}

int cmd_trace(int argc, char **argv)
{
	char filter[128], *pos[1];
	struct tracefs t;
	int npos, ret;

	ret = parse_opts("trace", argc, argv, NULL, pos, &npos, 0, 1);
	if (ret)
		return ret;
	if (tracefs_find(&t, SYSTEM)) {
		fprintf(stderr, "nxtctl: trace: no " SYSTEM " events in tracefs: is the driver\n"
			"loaded, and tracefs mounted (mount -t tracefs nodev /sys/kernel/tracing)?\n");
		return EXIT_DEVICE;
	}
	if (npos)
		snprintf(filter, sizeof(filter), "dev == \"%s\"", pos[0]);
	ret = tracefs_enable(&t, npos ? filter : NULL);
	if (ret) {
		tracefs_disable(&t);
		return sys_error("trace: enabling the events (root needed)", -ret);
	}
	/* The signals end the read, which lets the events be disabled. */
	ret = tracefs_read(&t, "nxt_usb_", trace_line, stdout);
	tracefs_disable(&t);
	if (ret)
		return sys_error("trace: reading trace_pipe", -ret);
	return EXIT_OK;
}
