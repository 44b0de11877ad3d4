// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT telegrams: validation of commands and replies.
 *
 * The brick's firmware takes one USB packet as one command and never checks
 * its length, so everything is checked here before it is sent, and nothing
 * the brick sends back is trusted.
 */
#include <linux/errno.h>
#include <linux/export.h>
#include <linux/module.h>

#include "lego_compat.h"
#include "nxt_proto.h"

/**
 * nxt_telegram_check() - validate a telegram before it is sent to the brick
 * @buf: the telegram, starting with its type byte
 * @len: its length in bytes
 *
 * Return: 1 if the brick will reply to it, 0 if it will not, -%EMSGSIZE if it
 * does not fit one USB packet, -%EINVAL if it is too short or its type byte
 * is not a command.
 */
int nxt_telegram_check(const u8 *buf, size_t len)
{
	if (len > NXT_TELEGRAM_MAX)
		return -EMSGSIZE;
	if (len < NXT_TELEGRAM_MIN)
		return -EINVAL;

	switch (buf[0]) {
	case NXT_DIRECT_CMD:
	case NXT_SYSTEM_CMD:
		return 1;
	case NXT_DIRECT_CMD_NOREPLY:
	case NXT_SYSTEM_CMD_NOREPLY:
		return 0;
	default:
		return -EINVAL;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_telegram_check);

/**
 * nxt_reply_check() - check that a packet from the brick answers a command
 * @reply: the packet as received
 * @len: its length in bytes
 * @opcode: the opcode of the command it should answer
 *
 * Return: the brick's status byte (0 for success) if @reply is a reply to
 * @opcode, -%EPROTO otherwise.
 */
int nxt_reply_check(const u8 *reply, size_t len, u8 opcode)
{
	if (len < NXT_REPLY_MIN || len > NXT_TELEGRAM_MAX)
		return -EPROTO;
	if (reply[0] != NXT_REPLY || reply[1] != opcode)
		return -EPROTO;
	return reply[2];
}
EXPORT_SYMBOL_IF_KUNIT(nxt_reply_check);
