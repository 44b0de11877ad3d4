// SPDX-License-Identifier: GPL-2.0
/*
 * The NXT reply decoder over a recorded mix of telegrams and replies, for
 * callgrind: each reply is matched to its telegram (nxt_reply_check, as
 * nxt_usb.c does) and decoded as the typed ioctls (nxt_command_decode) or
 * the sysfs attributes (nxt_decode_versions, nxt_decode_device_info) do.
 *
 * Record format: kind (0: raw, else 1 + the typed command's number in the
 * table below), telegram length, telegram, reply length, reply.
 *
 * Usage: bench_nxt RECORDS
 * Prints: replies, reply bytes, replies accepted, decode errors.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <linux/ioctl.h>
#include <linux/kernel.h>

#include "nxt_proto.h"
#include "nxt_ioctls.h"

int main(int argc, char **argv)
{
	unsigned long replies = 0, bytes = 0, accepted = 0, bad = 0;
	u8 rec[2 + 2 * NXT_TELEGRAM_MAX + 1], arg[NXT_TELEGRAM_MAX];
	const struct nxt_command *cmd;
	struct nxt_device_info info;
	u8 proto[2], fw[2];
	int kind, tg_len, len;
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
		    fread(rec + tg_len, 1, len, f) != (size_t)len ||
		    kind > (int)ARRAY_SIZE(nxt_test_ioctls)) {
			fprintf(stderr, "%s: bad record %lu\n", argv[1], replies);
			return 1;
		}
		replies++;
		bytes += len;
		if (nxt_reply_check(rec, tg_len, rec + tg_len, len) < 0) {
			bad++;
			continue;
		}
		accepted++;
		if (kind) {
			cmd = nxt_command_find(nxt_test_ioctls[kind - 1]);
			if (!cmd || nxt_command_decode(cmd, rec + tg_len, len, arg))
				bad++;
		} else if (rec[1] == NXT_GET_VERSIONS) {
			bad += !!nxt_decode_versions(rec + tg_len, len, proto, fw);
		} else if (rec[1] == NXT_GET_DEVICE_INFO) {
			bad += !!nxt_decode_device_info(rec + tg_len, len, &info);
		}
	}
	fclose(f);
	printf("replies %lu bytes %lu accepted %lu bad %lu\n", replies, bytes,
	       accepted, bad);
	return 0;
}
