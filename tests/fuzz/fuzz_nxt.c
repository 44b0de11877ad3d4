// SPDX-License-Identifier: GPL-2.0
/*
 * libFuzzer target: the NXT telegram core (nxt_proto.c) as nxt_usb.c,
 * nxt_cdev.c and nxt_sysfs.c use it: a reply packet from the brick is
 * matched to the telegram sent (nxt_reply_check) and decoded.
 *
 * Input: a selector byte, then
 *  - selector even (NXT_IOC_TRANSACT and the driver's own commands): the
 *    telegram's length - 2 (mod 64), the telegram, then the reply (the
 *    rest of the input);
 *  - selector odd (the typed ioctls, command number selector / 2): the
 *    reply's length (mod 81), the reply, then the ioctl argument as
 *    userspace passes it (_IOC_SIZE bytes, zero-padded), which is encoded
 *    into a telegram.
 * Replies of up to 80 bytes (USB gives at most 64) are in buffers of exactly
 * their size, so ASan sees any read past them.
 */
#include <errno.h>
#include <string.h>
#include <linux/ioctl.h>

#include <linux/kernel.h>

#include "nxt_proto.h"
#include "nxt_ioctls.h"
#include "fuzz_check.h"

#define REPLY_MAX	80

/* nxt_reply_check() and what its result promises. */
static int check_reply(const u8 *tg, size_t tg_len, const u8 *reply, size_t len)
{
	unsigned int want = nxt_reply_length(tg, tg_len);
	int ret = nxt_reply_check(tg, tg_len, reply, len);
	int err;

	CHECK(want == 0 || (want >= NXT_REPLY_MIN && want <= NXT_TELEGRAM_MAX));
	CHECK(ret == -ENOMSG || ret == -EPROTO || (ret >= 0 && ret <= 0xff));
	if (ret < 0)
		return ret;
	CHECK(len >= NXT_REPLY_MIN && len <= NXT_TELEGRAM_MAX);
	CHECK(reply[0] == NXT_REPLY && reply[1] == tg[1] && reply[2] == ret);
	if (want && ret == NXT_STATUS_SUCCESS)
		CHECK(len == want);
	if (want)
		CHECK(len <= want);
	err = nxt_status_to_errno(ret);
	CHECK(err <= 0 && err > -4096);
	CHECK((err == 0) == (ret == NXT_STATUS_SUCCESS));
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
		CHECK(reply[1] == NXT_GET_VERSIONS && len == 7);

	memset(&info, 0xa5, sizeof(info));
	ret = nxt_decode_device_info(reply, len, &info);
	CHECK(ret == 0 || ret == -EPROTO);
	if (ret)
		return;
	CHECK(reply[1] == NXT_GET_DEVICE_INFO && len == 33);
	n = strnlen(info.name, sizeof(info.name));
	CHECK(n < sizeof(info.name));
	for (i = 0; i < n; i++)
		CHECK(info.name[i] >= 0x20 && info.name[i] <= 0x7e);
}

static void raw(const u8 *data, size_t size)
{
	u8 tg[NXT_TELEGRAM_MAX + 1] = { };
	size_t tg_len, len;
	u8 *reply;
	int ret;

	if (size < 1)
		return;
	/* One byte too many is refused before anything is sent. */
	tg_len = NXT_TELEGRAM_MIN + data[0] % NXT_TELEGRAM_MAX;
	data++;
	size--;
	len = tg_len < size ? tg_len : size;
	memcpy(tg, data, len);
	data += len;
	size -= len;

	ret = nxt_telegram_check(tg, tg_len);
	if (tg_len > NXT_TELEGRAM_MAX)
		CHECK(ret == -EMSGSIZE);
	else
		CHECK(ret == 0 || ret == 1 || ret == -EINVAL);
	if (ret != 1)
		return;
	len = size < REPLY_MAX ? size : REPLY_MAX;
	reply = malloc(len ? len : 1);
	CHECK(reply);
	memcpy(reply, data, len);
	if (check_reply(tg, tg_len, reply, len) >= 0)
		decode_sysfs(reply, len);
	free(reply);
}

static void typed(unsigned int sel, const u8 *data, size_t size)
{
	const struct nxt_command *cmd;
	u8 tg[NXT_TELEGRAM_MAX], status;
	size_t arg_size, len, i;
	u8 *arg, *reply;
	int tg_len, ret;

	cmd = nxt_command_find(nxt_test_ioctls[sel % ARRAY_SIZE(nxt_test_ioctls)]);
	CHECK(cmd);
	arg_size = _IOC_SIZE(cmd->ioctl);
	CHECK(arg_size <= NXT_TELEGRAM_MAX && cmd->status_offset < arg_size);
	if (size < 1)
		return;
	len = data[0] % (REPLY_MAX + 1);
	data++;
	size--;
	len = len < size ? len : size;
	reply = malloc(len ? len : 1);
	CHECK(reply);
	memcpy(reply, data, len);
	data += len;
	size -= len;
	arg = calloc(1, arg_size);
	CHECK(arg);
	memcpy(arg, data, arg_size < size ? arg_size : size);

	memset(tg, 0xa5, sizeof(tg));
	tg_len = nxt_command_encode(cmd, arg, tg);
	if (tg_len < 0) {
		CHECK(tg_len == -EINVAL);
		CHECK(!memchr_inv(tg, 0, sizeof(tg)));
		goto out;
	}
	CHECK(tg_len >= NXT_TELEGRAM_MIN && tg_len <= NXT_TELEGRAM_MAX);
	CHECK(tg[0] == NXT_DIRECT_CMD && tg[1] == cmd->opcode);
	CHECK(!memchr_inv(tg + tg_len, 0, sizeof(tg) - tg_len));
	CHECK(nxt_telegram_check(tg, tg_len) == 1);
	CHECK(nxt_reply_length(tg, tg_len) >= NXT_REPLY_MIN);

	if (check_reply(tg, tg_len, reply, len) < 0)
		goto out;
	status = reply[2];
	ret = nxt_command_decode(cmd, reply, len, arg);
	CHECK(ret == 0 || ret == -EPROTO);
	CHECK(arg[cmd->status_offset] == status);
	if (!ret && status == NXT_STATUS_SUCCESS) {
		/* Counts the caller trusts to index its buffers. */
		switch (cmd->opcode) {
		case NXT_LS_GET_STATUS:
			CHECK(((struct nxt_ls_status *)arg)->bytes_ready <= NXT_LS_DATA_MAX);
			break;
		case NXT_LS_READ:
			CHECK(((struct nxt_ls_read *)arg)->length <= NXT_LS_DATA_MAX);
			break;
		case NXT_MESSAGE_READ:
			CHECK(((struct nxt_message *)arg)->size <= NXT_MESSAGE_MAX);
			break;
		case NXT_GET_CURRENT_PROGRAM_NAME:
			i = strnlen(((struct nxt_program *)arg)->name, NXT_NAME_LEN);
			CHECK(i < NXT_NAME_LEN);
			break;
		}
	}
out:
	free(arg);
	free(reply);
}

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size)
{
	if (size < 1)
		return 0;
	if (data[0] & 1)
		typed(data[0] >> 1, data + 1, size - 1);
	else
		raw(data + 1, size - 1);
	return 0;
}
