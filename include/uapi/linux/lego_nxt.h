/* SPDX-License-Identifier: GPL-2.0 WITH Linux-syscall-note */
/*
 * LEGO MINDSTORMS NXT brick over USB: userspace interface of /dev/nxtN.
 *
 * A telegram is what the brick's firmware calls one command or reply: a
 * type byte, an opcode and the command's arguments, all in one USB packet.
 */
#ifndef _UAPI_LINUX_LEGO_NXT_H
#define _UAPI_LINUX_LEGO_NXT_H

#include <linux/types.h>

/** NXT_TELEGRAM_MIN - shortest telegram: the type byte and the opcode */
#define NXT_TELEGRAM_MIN	2
/** NXT_TELEGRAM_MAX - longest telegram: one full-speed bulk packet */
#define NXT_TELEGRAM_MAX	64

/**
 * enum nxt_telegram_type - the first byte of every telegram
 * @NXT_DIRECT_CMD: direct command, the brick replies
 * @NXT_SYSTEM_CMD: system command, the brick replies
 * @NXT_REPLY: a reply from the brick
 * @NXT_DIRECT_CMD_NOREPLY: direct command, no reply
 * @NXT_SYSTEM_CMD_NOREPLY: system command, no reply
 */
enum nxt_telegram_type {
	NXT_DIRECT_CMD		= 0x00,
	NXT_SYSTEM_CMD		= 0x01,
	NXT_REPLY		= 0x02,
	NXT_DIRECT_CMD_NOREPLY	= 0x80,
	NXT_SYSTEM_CMD_NOREPLY	= 0x81,
};

#endif /* _UAPI_LINUX_LEGO_NXT_H */
