// SPDX-License-Identifier: GPL-2.0
/*
 * libFuzzer target: the NXT telegram core (nxt_proto.c) as nxt_usb.c,
 * nxt_cdev.c, nxt_sysfs.c and nxt_i2c.c use it: a telegram from userspace
 * is checked (nxt_telegram_check), a reply packet from the brick is matched
 * to it (nxt_reply_check), what the reply says about the brick is noted for
 * sysfs (nxt_info_note_sent, nxt_info_note_reply), and an I2C adapter reads
 * its count and bytes (nxt_ls_ready, nxt_ls_read_data).
 *
 * Input: a flags byte, the telegram's length - 2 (mod 64), the telegram,
 * then the reply (the rest of the input). The flags say which values of the
 * brick's information are known before the telegram (bits 0 to 2: the
 * versions, the device information, the battery voltage) and how many
 * bytes an LSRead asked for, less one (bits 3 to 6); with bit 7, the rest
 * of the input is what a serial
 * link (Bluetooth) brought, read by nxt_bt_rx_feed() once a byte at a
 * time and once in batches whose sizes the flags seed; both must give the
 * same replies, each a well-formed one, and account for every byte. Replies
 * of up to 80 bytes (USB gives at most 64) are in buffers of exactly their
 * size, so ASan sees any read past them.
 */
#include <errno.h>
#include <string.h>

#include <linux/kernel.h>
#include <linux/unaligned.h>

#include "nxt_proto.h"
#include "fuzz_check.h"

#define REPLY_MAX	80

/*
 * The firmware's numbers, written out here so that the checks do not lean
 * on the driver's own names for them.
 */
#define STATUS_SUCCESS		0x00
#define OP_GET_OUTPUT_STATE	0x06	/* direct */
#define OP_GET_INPUT_VALUES	0x07	/* direct */
#define OP_GET_BATTERY_LEVEL	0x0b	/* direct */
#define OP_MESSAGE_READ		0x13	/* direct */
#define OP_LS_GET_STATUS	0x0e	/* direct */
#define OP_LS_READ		0x10	/* direct */
#define OP_GET_VERSIONS		0x88	/* system */
#define OP_GET_DEVICE_INFO	0x9b	/* system */
#define OP_DELETE_USER_FLASH	0xa0	/* system */

#define KNOWS_VERSIONS		0x01
#define KNOWS_DEVICE		0x02
#define KNOWS_BATTERY		0x04
#define BT_STREAM		0x80

/* nxt_reply_check() and what its result promises. */
static int check_reply(const u8 *tg, size_t tg_len, const u8 *reply, size_t len)
{
	unsigned int want = nxt_reply_length(tg, tg_len);
	int ret = nxt_reply_check(tg, tg_len, reply, len);

	CHECK(want == 0 || (want >= NXT_REPLY_MIN && want <= NXT_TELEGRAM_MAX));
	CHECK(ret == -ENOMSG || ret == -EPROTO || (ret >= 0 && ret <= 0xff));
	if (ret < 0)
		return ret;
	CHECK(len >= NXT_REPLY_MIN && len <= NXT_TELEGRAM_MAX);
	CHECK(reply[0] == NXT_REPLY && reply[1] == tg[1] && reply[2] == ret);
	if (want && ret == STATUS_SUCCESS)
		CHECK(len == want);
	if (want)
		CHECK(len <= want);
	/* A successful reply echoes the port or the local inbox asked for. */
	if (ret == STATUS_SUCCESS && tg[0] == NXT_DIRECT_CMD) {
		if (tg[1] == OP_GET_OUTPUT_STATE || tg[1] == OP_GET_INPUT_VALUES)
			CHECK(reply[3] == tg[2]);
		else if (tg[1] == OP_MESSAGE_READ)
			CHECK(reply[3] == tg[3]);
	}
	return ret;
}

/* The replies the driver decodes itself for sysfs. */
static void decode_sysfs(const u8 *reply, size_t len)
{
	struct nxt_device_info info;
	u8 protocol[2], firmware[2];
	size_t i, n;
	int ret;

	ret = nxt_decode_versions(reply, len, protocol, firmware);
	CHECK(ret == 0 || ret == -EPROTO);
	if (!ret)
		CHECK(reply[1] == OP_GET_VERSIONS && len == 7 &&
		      reply[2] == STATUS_SUCCESS);

	memset(&info, 0xa5, sizeof(info));
	ret = nxt_decode_device_info(reply, len, &info);
	CHECK(ret == 0 || ret == -EPROTO);
	if (ret)
		return;
	CHECK(reply[1] == OP_GET_DEVICE_INFO && len == 33 && reply[2] == STATUS_SUCCESS);
	n = strnlen(info.name, sizeof(info.name));
	CHECK(n < sizeof(info.name));
	for (i = 0; i < n; i++)
		CHECK(info.name[i] >= 0x20 && info.name[i] <= 0x7e);
	CHECK(!memchr_inv(info.name + n, 0, sizeof(info.name) - n));
	CHECK(!memcmp(info.bt_address, reply + 18, sizeof(info.bt_address)));
	CHECK(info.free_flash == get_unaligned_le32(reply + 29));
}

/* The brick's information before the telegram, as the flags say. */
static void brick_info_init(struct nxt_brick_info *info, u8 flags)
{
	memset(info, 0x5a, sizeof(*info));
	info->have_versions = flags & KNOWS_VERSIONS;
	info->have_device = flags & KNOWS_DEVICE;
	info->have_battery = flags & KNOWS_BATTERY;
}

/*
 * nxt_info_note_sent(): only a system command may make the device
 * information unknown, and nothing else changes.
 */
static void check_note_sent(struct nxt_brick_info *info, const u8 *tg, size_t tg_len)
{
	struct nxt_brick_info before;

	memcpy(&before, info, sizeof(before));
	nxt_info_note_sent(info, tg, tg_len);
	CHECK(info->have_device == before.have_device || !info->have_device);
	if (info->have_device != before.have_device)
		CHECK((tg[0] & ~0x80) == NXT_SYSTEM_CMD && tg[1] != OP_GET_VERSIONS &&
		      tg[1] != OP_GET_DEVICE_INFO);
	before.have_device = info->have_device;
	CHECK(!memcmp(&before, info, sizeof(before)));
}

/*
 * nxt_info_note_reply() for a reply that nxt_reply_check() accepted: a
 * successful reply to GetVersions, GetDeviceInfo or GetBatteryLevel
 * replaces the values it carries, every other reply changes nothing.
 */
static void check_note_reply(struct nxt_brick_info *info, const u8 *tg, size_t tg_len,
			     const u8 *reply, size_t len)
{
	bool success = reply[2] == STATUS_SUCCESS;
	struct nxt_brick_info before;
	size_t n;

	memcpy(&before, info, sizeof(before));
	nxt_info_note_reply(info, tg, tg_len, reply, len);
	if (success && tg[0] == NXT_SYSTEM_CMD && tg[1] == OP_GET_VERSIONS) {
		CHECK(info->have_versions && len == 7);
		CHECK(info->protocol[0] == reply[4] && info->protocol[1] == reply[3]);
		CHECK(info->firmware[0] == reply[6] && info->firmware[1] == reply[5]);
		before.have_versions = true;
		memcpy(before.protocol, info->protocol, sizeof(before.protocol));
		memcpy(before.firmware, info->firmware, sizeof(before.firmware));
	} else if (success && tg[0] == NXT_SYSTEM_CMD && tg[1] == OP_GET_DEVICE_INFO) {
		CHECK(info->have_device && len == 33);
		n = strnlen(info->device.name, sizeof(info->device.name));
		CHECK(n < sizeof(info->device.name));
		CHECK(!memcmp(info->device.bt_address, reply + 18,
			      sizeof(info->device.bt_address)));
		CHECK(info->device.free_flash == get_unaligned_le32(reply + 29));
		before.have_device = true;
		memcpy(&before.device, &info->device, sizeof(before.device));
	} else if (success && tg[0] == NXT_DIRECT_CMD && tg[1] == OP_GET_BATTERY_LEVEL) {
		CHECK(info->have_battery && len == 5);
		CHECK(info->battery_mv == get_unaligned_le16(reply + 3));
		before.have_battery = true;
		before.battery_mv = info->battery_mv;
	}
	CHECK(!memcmp(&before, info, sizeof(before)));
}

/* What nxt_telegram_check() promises, before anything is sent. */
static int check_telegram(const u8 *tg, size_t tg_len)
{
	int ret = nxt_telegram_check(tg, tg_len);
	unsigned int late;
	bool command;

	if (tg_len > NXT_TELEGRAM_MAX) {
		CHECK(ret == -EMSGSIZE);
		return ret;
	}
	CHECK(ret == 0 || ret == 1 || ret == -EINVAL);
	command = tg[0] == NXT_DIRECT_CMD || tg[0] == NXT_SYSTEM_CMD ||
		  tg[0] == NXT_DIRECT_CMD_NOREPLY || tg[0] == NXT_SYSTEM_CMD_NOREPLY;
	/* Refused only for its type byte or for bytes its command reads. */
	if (!command)
		CHECK(ret == -EINVAL);
	else
		CHECK((ret == -EINVAL) == !nxt_request_complete(tg, tg_len));
	if (ret < 0)
		return ret;
	CHECK(ret == (tg[0] == NXT_DIRECT_CMD || tg[0] == NXT_SYSTEM_CMD));
	if (!ret)
		CHECK(nxt_reply_length(tg, tg_len) == 0);
	late = nxt_reply_late_ms(tg, tg_len);
	if (tg[0] == NXT_SYSTEM_CMD && tg[1] == OP_DELETE_USER_FLASH)
		CHECK(late == NXT_SLOW_REPLY_MS);
	else
		CHECK(late == NXT_LATE_REPLY_MS);
	return ret;
}

/* A reply out of the stream: well formed, then as a USB packet would be. */
static void bt_reply(struct nxt_brick_info *info, const u8 *tg, size_t tg_len,
		     const u8 *reply, unsigned int len)
{
	u8 *copy;

	CHECK(len >= NXT_REPLY_MIN && len <= NXT_TELEGRAM_MAX);
	CHECK(reply[0] == NXT_REPLY);
	copy = malloc(len);
	CHECK(copy);
	memcpy(copy, reply, len);
	if (check_reply(tg, tg_len, copy, len) >= 0) {
		decode_sysfs(copy, len);
		check_note_reply(info, tg, tg_len, copy, len);
	}
	free(copy);
}

/*
 * The stream read a byte at a time, then in batches of 1 to 64 bytes: the
 * same replies in the same order, and every byte is in a reply's frame,
 * dropped, or held.
 */
static void bt_stream(struct nxt_brick_info *info, const u8 *tg, size_t tg_len,
		      const u8 *data, size_t size, u8 seed)
{
	static u8 replies[64 * 1024];
	static u8 lens[64 * 1024 / (NXT_BT_PREFIX + NXT_REPLY_MIN) + 1];
	struct nxt_bt_rx one = { }, batch = { };
	size_t at = 0, framed = 0, n = 0, m = 0, i;
	unsigned int rand = seed | 1;

	CHECK(size <= sizeof(replies));
	for (i = 0; i < size; i++) {
		const u8 *reply;
		unsigned int len;

		CHECK(nxt_bt_rx_feed(&one, data + i, 1, &reply, &len) == 1);
		CHECK(one.have <= NXT_BT_FRAME_MAX);
		if (!reply) {
			CHECK(len == 0);
			continue;
		}
		bt_reply(info, tg, tg_len, reply, len);
		memcpy(replies + framed, reply, len);
		framed += len;
		lens[n++] = len;
	}
	CHECK(framed + NXT_BT_PREFIX * n + one.dropped + one.have == size);

	framed = 0;
	while (at < size) {
		size_t step, used;
		const u8 *reply;
		unsigned int len;

		rand = rand * 1103515245 + 12345;
		step = 1 + (rand >> 16) % 64;
		if (step > size - at)
			step = size - at;
		while (step) {
			used = nxt_bt_rx_feed(&batch, data + at, step, &reply, &len);
			CHECK(used >= 1 && used <= step);
			at += used;
			step -= used;
			if (!reply)
				continue;
			CHECK(m < n && lens[m++] == len);
			CHECK(!memcmp(replies + framed, reply, len));
			framed += len;
		}
	}
	CHECK(m == n);
	CHECK(framed + NXT_BT_PREFIX * n + batch.dropped + batch.have == size);
	CHECK(batch.have == one.have && batch.dropped == one.dropped);
	CHECK(!memcmp(batch.buf, one.buf, one.have));
	nxt_bt_rx_reset(&batch);
	CHECK(batch.have == 0 && batch.dropped == one.dropped + one.have);
}

/*
 * What the I2C adapters (nxt_i2c.c) read out of a reply to LSGetStatus or
 * LSRead, for any packet: a count within what one LSWrite can read, or an
 * errno; the bytes of a read only from a whole reply whose count is the one
 * asked for, and never a byte past them.
 */
static void check_ls(const u8 *reply, size_t len, size_t want)
{
	u8 buf[NXT_LS_MAX + 1];
	int ret;

	ret = nxt_ls_ready(reply, len);
	CHECK((ret >= 0 && ret <= NXT_LS_MAX) || ret == -EPROTO || ret == -EINPROGRESS ||
	      ret == -EAGAIN || ret == -ENXIO || ret == -EINVAL || ret == -EIO);
	if (ret >= 0)
		CHECK(len >= 4 && reply[0] == NXT_REPLY && reply[1] == OP_LS_GET_STATUS &&
		      reply[2] == STATUS_SUCCESS && reply[3] == ret);
	if (ret != -EPROTO)
		CHECK(len >= NXT_REPLY_MIN && reply[1] == OP_LS_GET_STATUS);

	memset(buf, 0xa5, sizeof(buf));
	ret = nxt_ls_read_data(reply, len, buf, want);
	CHECK(ret == 0 || ret == -EPROTO || ret == -EINPROGRESS || ret == -EAGAIN ||
	      ret == -ENXIO || ret == -EINVAL || ret == -EIO);
	if (!ret) {
		CHECK(len >= 4 + NXT_LS_MAX && reply[1] == OP_LS_READ && reply[3] == want);
		CHECK(!memcmp(buf, reply + 4, want));
	} else if (ret != -EPROTO) {
		CHECK(reply[1] == OP_LS_READ && reply[2] != STATUS_SUCCESS);
	}
	CHECK(buf[want] == 0xa5);
}

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
	u8 tg[NXT_TELEGRAM_MAX + 1] = { };
	struct nxt_brick_info info;
	size_t tg_len, len;
	u8 flags, *reply;
	int ret;

	if (size < 2)
		return 0;
	flags = data[0];
	/* One byte too many is refused before anything is sent. */
	tg_len = NXT_TELEGRAM_MIN + data[1] % NXT_TELEGRAM_MAX;
	data += 2;
	size -= 2;
	len = tg_len < size ? tg_len : size;
	memcpy(tg, data, len);
	data += len;
	size -= len;

	ret = check_telegram(tg, tg_len);
	if (ret < 0)
		return 0;
	brick_info_init(&info, flags);
	check_note_sent(&info, tg, tg_len);
	if (ret != 1)
		return 0;
	if (flags & BT_STREAM) {
		if (size <= 64 * 1024)
			bt_stream(&info, tg, tg_len, data, size, flags);
		return 0;
	}
	len = size < REPLY_MAX ? size : REPLY_MAX;
	reply = malloc(len ? len : 1);
	CHECK(reply);
	memcpy(reply, data, len);
	/* Bits 3 to 6 of the flags: the bytes an LSRead asks for, less one. */
	check_ls(reply, len, 1 + ((flags >> 3) & 0x0f));
	if (check_reply(tg, tg_len, reply, len) >= 0) {
		decode_sysfs(reply, len);
		check_note_reply(&info, tg, tg_len, reply, len);
	}
	free(reply);
	return 0;
}
