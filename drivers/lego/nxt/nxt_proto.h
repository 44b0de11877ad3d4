/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT telegrams: validation of commands and replies.
 *
 * Pure functions with no USB calls, tested with KUnit and fuzzed in userspace.
 */
#ifndef _NXT_PROTO_H
#define _NXT_PROTO_H

#include <linux/types.h>
#include <linux/lego_nxt.h>

/* A reply is at least its type byte, the echoed opcode and a status byte. */
#define NXT_REPLY_MIN		3

int nxt_telegram_check(const u8 *buf, size_t len);
int nxt_reply_check(const u8 *reply, size_t len, u8 opcode);

#endif /* _NXT_PROTO_H */
