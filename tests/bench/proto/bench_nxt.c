// SPDX-License-Identifier: GPL-2.0
/*
 * The NXT reply path over a recorded mix of telegrams and replies, for
 * callgrind, in two parts that run.sh counts apart:
 *
 *  - the driver's: each reply matched to its telegram (nxt_reply_check())
 *    and noted for the sysfs attributes (nxt_info_note_reply(), which
 *    decodes GetVersions, GetDeviceInfo and GetBatteryLevel), as
 *    nxt_usb.c does with every reply;
 *  - the program's: what a C program does with the reply NXT_IOC_TRANSACT
 *    gave it, liblegonxt's lnxt_reply_check() and the parser of the
 *    command's reply (lnxt_parse_*()), for the replies with status 0.
 *
 * Record format: kind, telegram length, telegram, reply length, reply. The
 * kind byte is read and not used (make-streams.py still writes it: 0 for a
 * raw telegram, else the number of the typed ioctl that decoded the reply
 * in releases that had them).
 *
 * Usage: bench_nxt RECORDS
 * Prints: replies, reply bytes, replies accepted (by the driver), bad (a
 * reply the driver did not note, or that liblegonxt rejected or could not
 * parse).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <linux/kernel.h>

#include "nxt_proto.h"
#include "legonxt.h"

/* liblegonxt's parser for @m's reply; 0 when it parsed, or had none to run. */
static int lib_parse(const struct lnxt_msg *m, const u8 *reply, size_t len)
{
	struct lnxt_device_info info;
	struct lnxt_versions versions;
	struct lnxt_output output;
	struct lnxt_input input;
	struct lnxt_data data;
	uint32_t sleep_ms;
	uint16_t mv;
	uint8_t ready;

	switch (m->buf[1]) {
	case LNXT_GET_OUTPUT_STATE:
		return lnxt_parse_output_state(reply, len, &output);
	case LNXT_GET_INPUT_VALUES:
		return lnxt_parse_input_values(reply, len, &input);
	case LNXT_GET_BATTERY_LEVEL:
		return lnxt_parse_battery_level(reply, len, &mv);
	case LNXT_KEEP_ALIVE:
		return lnxt_parse_keep_alive(reply, len, &sleep_ms);
	case LNXT_LS_GET_STATUS:
		return lnxt_parse_ls_get_status(reply, len, &ready);
	case LNXT_LS_READ:
		return lnxt_parse_ls_read(reply, len, &data);
	case LNXT_MESSAGE_READ:
		return lnxt_parse_message_read(reply, len, &data);
	case LNXT_GET_VERSIONS:
		return lnxt_parse_versions(reply, len, &versions);
	case LNXT_GET_DEVICE_INFO:
		return lnxt_parse_device_info(reply, len, &info);
	}
	return 0;	/* a reply with nothing but its status */
}

/* Whether nxt_info_note_reply() took what a successful reply carries. */
static int noted(struct nxt_brick_info *info, const u8 *tg)
{
	int ok = 1;

	if (tg[0] == NXT_SYSTEM_CMD && tg[1] == NXT_GET_VERSIONS)
		ok = info->have_versions;
	else if (tg[0] == NXT_SYSTEM_CMD && tg[1] == NXT_GET_DEVICE_INFO)
		ok = info->have_device;
	else if (tg[0] == NXT_DIRECT_CMD && tg[1] == NXT_GET_BATTERY_LEVEL)
		ok = info->have_battery;
	memset(info, 0, sizeof(*info));
	return ok;
}

int main(int argc, char **argv)
{
	unsigned long replies = 0, bytes = 0, accepted = 0, bad = 0;
	u8 rec[2 + 2 * NXT_TELEGRAM_MAX + 1];
	struct nxt_brick_info info;
	struct lnxt_msg m;
	int kind, tg_len, len, status;
	FILE *f;

	if (argc != 2) {
		fprintf(stderr, "usage: %s RECORDS\n", argv[0]);
		return 2;
	}
	f = fopen(argv[1], "rb");
	if (!f) {
		perror(argv[1]);
		return 1;
	}
	memset(&info, 0, sizeof(info));
	for (;;) {
		kind = getc(f);
		if (kind == EOF)
			break;
		tg_len = getc(f);
		if (tg_len < NXT_TELEGRAM_MIN || tg_len > NXT_TELEGRAM_MAX ||
		    fread(rec, 1, tg_len, f) != (size_t)tg_len)
			len = -1;
		else
			len = getc(f);
		if (len < 0 || len > NXT_TELEGRAM_MAX ||
		    fread(rec + tg_len, 1, len, f) != (size_t)len) {
			fprintf(stderr, "%s: bad record %lu\n", argv[1], replies);
			return 1;
		}
		replies++;
		bytes += len;

		/* The driver's part. */
		status = nxt_reply_check(rec, tg_len, rec + tg_len, len);
		if (status < 0) {
			bad++;
			continue;
		}
		accepted++;
		nxt_info_note_reply(&info, rec, tg_len, rec + tg_len, len);
		if (!noted(&info, rec) && status == NXT_STATUS_SUCCESS)
			bad++;

		/* The program's part: liblegonxt on what NXT_IOC_TRANSACT returned. */
		m.len = tg_len;
		memcpy(m.buf, rec, tg_len);
		status = lnxt_reply_check(&m, rec + tg_len, len);
		if (status < 0 || (!status && lib_parse(&m, rec + tg_len, len)))
			bad++;
	}
	fclose(f);
	printf("replies %lu bytes %lu accepted %lu bad %lu\n", replies, bytes,
	       accepted, bad);
	return 0;
}
