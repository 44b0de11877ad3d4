/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT telegrams: validation, encoding and decoding.
 *
 * Pure functions with no USB calls, tested with KUnit and fuzzed in
 * userspace. Nothing here trusts a byte that came from the brick.
 */
#ifndef _NXT_PROTO_H
#define _NXT_PROTO_H

#include <linux/types.h>
#include <linux/lego_nxt.h>

/* A reply is at least its type byte, the echoed opcode and a status byte. */
#define NXT_REPLY_MIN		3

/**
 * struct nxt_command - a direct command with a typed ioctl
 * @ioctl: its ioctl number; _IOC_SIZE() of it is the size of its argument
 * @opcode: its opcode
 * @status_offset: offset of the status byte in the ioctl's argument
 * @encode: checks the argument and writes the telegram to its second
 *	parameter (NXT_TELEGRAM_MAX bytes); returns the telegram's length or
 *	-EINVAL
 * @decode: reads a reply (a whole telegram, zero-padded to
 *	NXT_TELEGRAM_MAX bytes) into the argument's output members; returns
 *	0 or -EPROTO; NULL when the reply carries nothing but the status
 */
struct nxt_command {
	unsigned int ioctl;
	u8 opcode;
	u8 status_offset;
	int (*encode)(const void *arg, u8 *tg);
	int (*decode)(const u8 *reply, void *arg);
};

/**
 * struct nxt_device_info - the reply to GetDeviceInfo (system command 0x9b)
 * @name: the brick's name, NUL-terminated; bytes that are not printable
 *	ASCII read as '?'
 * @bt_address: its Bluetooth address, most significant byte first
 * @free_flash: free user flash, in bytes
 */
struct nxt_device_info {
	char name[16];
	u8 bt_address[6];
	u32 free_flash;
};

/* System commands the driver sends itself, for the sysfs attributes. */
#define NXT_GET_VERSIONS	0x88
#define NXT_GET_DEVICE_INFO	0x9b

int nxt_telegram_check(const u8 *tg, size_t len);
unsigned int nxt_reply_length(const u8 *tg, size_t len);
int nxt_reply_check(const u8 *tg, size_t tg_len, const u8 *reply, size_t len);
int nxt_status_to_errno(u8 status);

const struct nxt_command *nxt_command_find(unsigned int ioctl);
int nxt_command_encode(const struct nxt_command *cmd, const void *arg, u8 *tg);
int nxt_command_decode(const struct nxt_command *cmd, const u8 *reply,
		       size_t len, void *arg);
int nxt_decode_versions(const u8 *reply, size_t len, u8 protocol[2],
			u8 firmware[2]);
int nxt_decode_device_info(const u8 *reply, size_t len,
			   struct nxt_device_info *info);

#endif /* _NXT_PROTO_H */
