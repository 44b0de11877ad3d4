// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT telegrams: what may be sent, which packet answers
 * which telegram, and what the brick's replies say about the brick.
 *
 * How the brick's firmware (LEGO 1.05 to 1.29) treats USB data shapes all of
 * this:
 *
 *  - one OUT packet is one command, and its length is never checked: a short
 *    command is completed with stale bytes of earlier ones, a long transfer
 *    runs as several commands. Telegrams are therefore checked here before
 *    anything is sent, and never longer than one 64-byte packet;
 *  - only types 0x00 and 0x01 are answered; the reply is one IN packet,
 *    "02 opcode status payload", with no sequence number, so a reply is
 *    matched to its command by the echoed opcode and its length;
 *  - replies have a fixed length per command, even on error (the payload is
 *    then zero), except that an unknown opcode and a bad port for
 *    LSGetStatus or LSRead give three bytes, and an unknown system opcode
 *    gives the request's length plus two bytes of stale data.
 *
 * The driver builds no command and decodes no reply for its users (that is
 * liblegonxt's job, in userspace): it only knows each command's shape well
 * enough to refuse a telegram the firmware would complete with stale bytes,
 * and to tell the reply to a telegram from a late reply to another.
 */
#include <linux/bug.h>
#include <linux/build_bug.h>
#include <linux/errno.h>
#include <linux/export.h>
#include <linux/kernel.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "nxt_proto.h"

/* The replies whose values the driver keeps (struct nxt_brick_info). */

struct nxt_reply_hdr {
	u8 type;
	u8 opcode;
	u8 status;
} __packed;

struct nxt_reply_battery {
	struct nxt_reply_hdr h;
	__le16 millivolts;
} __packed;

struct nxt_reply_versions {
	struct nxt_reply_hdr h;
	u8 protocol_minor;
	u8 protocol_major;
	u8 firmware_minor;
	u8 firmware_major;
} __packed;

struct nxt_reply_device_info {
	struct nxt_reply_hdr h;
	char name[15];
	u8 bt_address[7];	/* six bytes and a zero */
	__le32 link_quality;	/* always 0 on LEGO's firmware */
	__le32 free_flash;
} __packed;

/* The firmware's reply lengths, as the documentation and the source give them. */
static_assert(sizeof(struct nxt_reply_battery) == 5);
static_assert(sizeof(struct nxt_reply_versions) == 7);
static_assert(sizeof(struct nxt_reply_device_info) == 33);

/*
 * Reply length of each direct command, whole telegram; 0 where the firmware
 * does not know the opcode (it then answers "02 op BE"). 0x19 to 0x21 came
 * with firmware 1.28.
 */
static const u8 nxt_direct_reply_len[] = {
	[NXT_START_PROGRAM]		= NXT_REPLY_MIN,
	[NXT_STOP_PROGRAM]		= NXT_REPLY_MIN,
	[NXT_PLAY_SOUND_FILE]		= NXT_REPLY_MIN,
	[NXT_PLAY_TONE]			= NXT_REPLY_MIN,
	[NXT_SET_OUTPUT_STATE]		= NXT_REPLY_MIN,
	[NXT_SET_INPUT_MODE]		= NXT_REPLY_MIN,
	[NXT_GET_OUTPUT_STATE]		= 25,	/* port ... 4 counters */
	[NXT_GET_INPUT_VALUES]		= 16,	/* port ... 4 values */
	[NXT_RESET_INPUT_SCALED_VALUE]	= NXT_REPLY_MIN,
	[NXT_MESSAGE_WRITE]		= NXT_REPLY_MIN,
	[NXT_RESET_MOTOR_POSITION]	= NXT_REPLY_MIN,
	[NXT_GET_BATTERY_LEVEL]		= sizeof(struct nxt_reply_battery),
	[NXT_STOP_SOUND_PLAYBACK]	= NXT_REPLY_MIN,
	[NXT_KEEP_ALIVE]		= 7,	/* the sleep limit, a u32 */
	[NXT_LS_GET_STATUS]		= 4,	/* bytes ready */
	[NXT_LS_WRITE]			= NXT_REPLY_MIN,
	[NXT_LS_READ]			= 20,	/* length, 16 bytes */
	[NXT_GET_CURRENT_PROGRAM_NAME]	= 23,	/* name[20] */
	[NXT_MESSAGE_READ]		= 64,	/* inbox, size, 59 bytes */
	[0x19]	= 64,	/* DatalogRead */
	[0x1a]	= 3,	/* DatalogSetTimes */
	[0x1b]	= 4,	/* BTGetContactCount */
	[0x1c]	= 21,	/* BTGetContactName */
	[0x1d]	= 4,	/* BTGetConnCount */
	[0x1e]	= 21,	/* BTGetConnName */
	[0x1f]	= 3,	/* SetProperty */
	[0x20]	= 4,	/* GetProperty: 7 for property 2, see below */
	[0x21]	= 3,	/* UpdateResetCount */
};

/* Reply length of each system command (opcode - 0x80), whole telegram. */
static const u8 nxt_system_reply_len[] = {
	[0x00] = 8,	/* OpenRead */
	[0x01] = 4,	/* OpenWrite */
	[0x02] = 6,	/* Read: plus the data, see below */
	[0x03] = 6,	/* Write */
	[0x04] = 4,	/* Close */
	[0x05] = 23,	/* Delete */
	[0x06] = 28,	/* FindFirst */
	[0x07] = 28,	/* FindNext */
	[0x08] = 7,	/* GetVersions */
	[0x09] = 4,	/* OpenWriteLinear */
	[0x0b] = 4,	/* OpenWriteData */
	[0x0c] = 8,	/* OpenAppendData */
	[0x0d] = 4,	/* CropDataFile */
	[0x10] = 34,	/* FindFirstModule */
	[0x11] = 34,	/* FindNextModule */
	[0x12] = 4,	/* CloseModuleHandle */
	[0x14] = 9,	/* ReadIOMap: plus the data, see below */
	[0x15] = 9,	/* WriteIOMap */
	[0x17] = 7,	/* BootCommand */
	[0x18] = 3,	/* SetBrickName */
	[0x1a] = 10,	/* GetBTAddress */
	[0x1b] = 33,	/* GetDeviceInfo */
	[0x20] = 3,	/* DeleteUserFlash */
	[0x21] = 5,	/* PollCommandLength */
	[0x22] = 5,	/* PollCommand: plus the data, see below */
	[0x24] = 3,	/* BTFactoryReset */
};

/*
 * What the firmware reads of a command's arguments: the whole telegram's
 * length up to the last argument it reads at a fixed offset, and where a
 * NUL-terminated string starts, if the command has one at its end (a file
 * or brick name, BootCommand's password). The firmware takes the bytes it
 * reads from its 64-byte receive buffer whatever the packet's length, so a
 * shorter telegram would run with the bytes that earlier telegrams, of any
 * process, left there (nxt_request_complete()).
 */
struct nxt_request_shape {
	u8 len;
	u8 string_at;
	u8 string_max;	/* the string ends there without a NUL too; 0: no limit */
};

/* Direct commands; { 0, 0 } for opcodes the firmware does not know. */
static const struct nxt_request_shape nxt_direct_req[] = {
	[NXT_START_PROGRAM]		= { .len = 3, .string_at = 2 },	/* name */
	[NXT_STOP_PROGRAM]		= { .len = 2 },
	[NXT_PLAY_SOUND_FILE]		= { .len = 4, .string_at = 3 },	/* loop, name */
	[NXT_PLAY_TONE]			= { .len = 6 },
	[NXT_SET_OUTPUT_STATE]		= { .len = 12 },	/* the BDK says 13 */
	[NXT_SET_INPUT_MODE]		= { .len = 5 },
	[NXT_GET_OUTPUT_STATE]		= { .len = 3 },
	[NXT_GET_INPUT_VALUES]		= { .len = 3 },
	[NXT_RESET_INPUT_SCALED_VALUE]	= { .len = 3 },
	[NXT_MESSAGE_WRITE]		= { .len = 4 },	/* and the message */
	[NXT_RESET_MOTOR_POSITION]	= { .len = 4 },
	[NXT_GET_BATTERY_LEVEL]		= { .len = 2 },
	[NXT_STOP_SOUND_PLAYBACK]	= { .len = 2 },
	[NXT_KEEP_ALIVE]		= { .len = 2 },
	[NXT_LS_GET_STATUS]		= { .len = 3 },
	[NXT_LS_WRITE]			= { .len = 5 },	/* and the bytes to send */
	[NXT_LS_READ]			= { .len = 3 },
	[NXT_GET_CURRENT_PROGRAM_NAME]	= { .len = 2 },
	[NXT_MESSAGE_READ]		= { .len = 5 },
	[0x19]	= { .len = 3 },	/* DatalogRead */
	[0x1a]	= { .len = 6 },	/* DatalogSetTimes */
	[0x1b]	= { .len = 2 },	/* BTGetContactCount */
	[0x1c]	= { .len = 3 },	/* BTGetContactName */
	[0x1d]	= { .len = 2 },	/* BTGetConnCount */
	[0x1e]	= { .len = 3 },	/* BTGetConnName */
	[0x1f]	= { .len = 4 },	/* SetProperty: 7 for property 2 */
	[0x20]	= { .len = 3 },	/* GetProperty */
	[0x21]	= { .len = 3 },	/* UpdateResetCount */
};

/* System commands (opcode - 0x80); { 0, 0 } for unknown ones. */
static const struct nxt_request_shape nxt_system_req[] = {
	[0x00] = { .len = 3, .string_at = 2 },	/* OpenRead: name */
	[0x01] = { .len = 26 },	/* OpenWrite: name[20], size */
	[0x02] = { .len = 5 },		/* Read */
	[0x03] = { .len = 3 },		/* Write: the data is the rest */
	[0x04] = { .len = 3 },		/* Close */
	[0x05] = { .len = 3, .string_at = 2 },	/* Delete: name */
	[0x06] = { .len = 3, .string_at = 2 },	/* FindFirst: pattern */
	[0x07] = { .len = 3 },		/* FindNext */
	[0x08] = { .len = 2 },		/* GetVersions */
	[0x09] = { .len = 26 },	/* OpenWriteLinear */
	[0x0b] = { .len = 26 },	/* OpenWriteData */
	[0x0c] = { .len = 3, .string_at = 2 },	/* OpenAppendData: name */
	[0x0d] = { .len = 3 },		/* CropDataFile */
	[0x10] = { .len = 3, .string_at = 2 },	/* FindFirstModule: pattern */
	[0x11] = { .len = 3 },		/* FindNextModule */
	[0x12] = { .len = 3 },		/* CloseModuleHandle */
	[0x14] = { .len = 10 },	/* ReadIOMap */
	[0x15] = { .len = 10 },	/* WriteIOMap: and the data */
	[0x17] = { .len = 3, .string_at = 2 },	/* BootCommand: "Let's dance: SAMBA" */
	/* SetBrickName: the firmware takes 15 characters at most. */
	[0x18] = { .len = 3, .string_at = 2, .string_max = 15 },
	[0x1a] = { .len = 2 },		/* GetBTAddress */
	[0x1b] = { .len = 2 },		/* GetDeviceInfo */
	[0x20] = { .len = 2 },		/* DeleteUserFlash */
	[0x21] = { .len = 3 },		/* PollCommandLength */
	[0x22] = { .len = 4 },		/* PollCommand */
	[0x24] = { .len = 2 },		/* BTFactoryReset */
};

/**
 * nxt_request_complete() - whether a telegram holds all that its command reads
 * @tg: a telegram of a command type (direct or system, reply or not)
 * @len: its length, 2 or more
 *
 * Quirk: the firmware never checks a command's length. It reads each
 * argument at its offset in a 64-byte receive buffer that is not cleared
 * between packets, so the arguments a short telegram lacks are bytes of
 * earlier telegrams, another process's perhaps: a short SetOutputState
 * drives a motor with them. A telegram must therefore hold every argument
 * of its command, the data that a count in it announces (MessageWrite,
 * LSWrite, WriteIOMap), and the NUL of a string at its end (or, for a brick
 * name, its 15 characters: nxt-python sends them without a NUL). Opcodes the
 * firmware does not know are not checked: it answers them with an error.
 *
 * Return: true if the telegram may be sent.
 */
bool nxt_request_complete(const u8 *tg, size_t len)
{
	const struct nxt_request_shape *shape = NULL;
	size_t need;
	u8 op = tg[1];

	if ((tg[0] & ~0x80) == NXT_DIRECT_CMD && op < ARRAY_SIZE(nxt_direct_req))
		shape = &nxt_direct_req[op];
	else if ((tg[0] & ~0x80) == NXT_SYSTEM_CMD && op >= 0x80 &&
		 op - 0x80 < ARRAY_SIZE(nxt_system_req))
		shape = &nxt_system_req[op - 0x80];
	if (!shape || !shape->len)
		return true;
	if (len < shape->len)
		return false;
	if (shape->string_at)
		return memchr(tg + shape->string_at, 0, len - shape->string_at) ||
		       (shape->string_max && len >= shape->string_at + shape->string_max);

	need = shape->len;
	if ((tg[0] & ~0x80) == NXT_DIRECT_CMD) {
		if (op == NXT_MESSAGE_WRITE || op == NXT_LS_WRITE)
			need += tg[3];		/* size, tx_length */
		else if (op == 0x1f && tg[2] == 2)
			need = 7;		/* the sleep time, a u32 */
	} else if (op == 0x95) {
		need += get_unaligned_le16(tg + 8);	/* WriteIOMap's count */
	}
	return len >= need;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_request_complete);

/* Data bytes that fit a USB reply after the fixed part of these commands. */
#define NXT_READ_DATA_MAX	58
#define NXT_IOMAP_DATA_MAX	55
#define NXT_POLL_DATA_MAX	59

/**
 * nxt_telegram_check() - validate a telegram before it is sent to the brick
 * @tg: the telegram, starting with its type byte
 * @len: its length in bytes
 *
 * Return: 1 if the brick will reply to it, 0 if it will not, -%EMSGSIZE if it
 * does not fit one USB packet, -%EINVAL if it is too short, shorter than its
 * command (nxt_request_complete()) or its type byte is not a command.
 */
int nxt_telegram_check(const u8 *tg, size_t len)
{
	int want;

	if (len > NXT_TELEGRAM_MAX)
		return -EMSGSIZE;
	if (len < NXT_TELEGRAM_MIN)
		return -EINVAL;

	switch (tg[0]) {
	case NXT_DIRECT_CMD:
	case NXT_SYSTEM_CMD:
		want = 1;
		break;
	case NXT_DIRECT_CMD_NOREPLY:
	case NXT_SYSTEM_CMD_NOREPLY:
		want = 0;
		break;
	default:
		return -EINVAL;
	}
	return nxt_request_complete(tg, len) ? want : -EINVAL;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_telegram_check);

/* A little-endian count at @at, or -1 if the telegram is too short for it. */
static int nxt_count_at(const u8 *tg, size_t len, size_t at, size_t size)
{
	if (len < at + size)
		return -1;	/* the firmware would read stale bytes */
	return size == 1 ? tg[at] : get_unaligned_le16(tg + at);
}

/**
 * nxt_reply_length() - the length of the reply the brick sends to a telegram
 * @tg: a telegram that passed nxt_telegram_check()
 * @len: its length
 *
 * Return: the whole reply's length in bytes, or 0 when the firmware does not
 * know the command, when its reply length depends on bytes the telegram is
 * too short to hold, or when the telegram asks for no reply.
 */
unsigned int nxt_reply_length(const u8 *tg, size_t len)
{
	u8 op = tg[1];
	unsigned int n;
	int count, cap;

	switch (tg[0]) {
	case NXT_DIRECT_CMD:
		if (op >= ARRAY_SIZE(nxt_direct_reply_len))
			return 0;
		/* GetProperty: property 2, the sleep time, is a u32. */
		if (op == 0x20)
			return len > 2 && tg[2] == 2 ? 7 : 4;
		return nxt_direct_reply_len[op];
	case NXT_SYSTEM_CMD:
		if (op < 0x80 || op - 0x80 >= ARRAY_SIZE(nxt_system_reply_len))
			return 0;
		n = nxt_system_reply_len[op - 0x80];
		/* Data-carrying replies: the data is capped to fit 64 bytes. */
		switch (op) {
		case 0x82:	/* Read: handle, count u16 */
			count = nxt_count_at(tg, len, 3, 2);
			cap = NXT_READ_DATA_MAX;
			break;
		case 0x94:	/* ReadIOMap: id u32, offset u16, count u16 */
			count = nxt_count_at(tg, len, 8, 2);
			cap = NXT_IOMAP_DATA_MAX;
			break;
		case 0xa2:	/* PollCommand: buffer, count */
			count = nxt_count_at(tg, len, 3, 1);
			cap = NXT_POLL_DATA_MAX;
			break;
		default:
			return n;
		}
		return count < 0 ? 0 : n + min(count, cap);
	default:
		return 0;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_reply_length);

/*
 * Whether a successful reply echoes what @tg asked for, where it echoes
 * anything: the port of GetOutputState and GetInputValues, the local inbox
 * of MessageRead. An error reply has zeros there (the firmware clears the
 * payload), so only successful replies are checked.
 */
static bool nxt_reply_echoes(const u8 *tg, size_t tg_len, const u8 *reply)
{
	if (tg[0] != NXT_DIRECT_CMD)
		return true;
	switch (tg[1]) {
	case NXT_GET_OUTPUT_STATE:
	case NXT_GET_INPUT_VALUES:
		/* Request: port at 2; reply: port at 3. */
		return tg_len < 3 || reply[3] == tg[2];
	case NXT_MESSAGE_READ:
		/* Request: remote inbox, local inbox; reply: local inbox at 3. */
		return tg_len < 4 || reply[3] == tg[3];
	default:
		return true;
	}
}

/**
 * nxt_reply_check() - check that a packet from the brick answers a telegram
 * @tg: the telegram sent, which asked for a reply
 * @tg_len: its length
 * @reply: the packet received
 * @len: its length in bytes
 *
 * A reply must be a reply telegram echoing @tg's opcode, and as long as the
 * firmware makes that command's replies. An error reply may be shorter (the
 * firmware sends three bytes for an unknown opcode or a bad low-speed port).
 * A successful reply to GetOutputState or GetInputValues must echo @tg's
 * port, one to MessageRead its local inbox: a stale reply to the same
 * command for another port or inbox is not this reply.
 *
 * Return: the brick's status byte (0 for success) if @reply answers @tg;
 * -%ENOMSG if it is not a reply to @tg (a stale reply, or garbage); -%EPROTO
 * if it is a reply to @tg's opcode, but its length is wrong for the command.
 */
int nxt_reply_check(const u8 *tg, size_t tg_len, const u8 *reply, size_t len)
{
	unsigned int want;
	u8 status;

	if (len < 2 || reply[0] != NXT_REPLY || reply[1] != tg[1])
		return -ENOMSG;
	if (len < NXT_REPLY_MIN || len > NXT_TELEGRAM_MAX)
		return -EPROTO;

	status = reply[2];
	want = nxt_reply_length(tg, tg_len);
	if (want && len != want && (status == NXT_STATUS_SUCCESS || len > want))
		return -EPROTO;
	if (status == NXT_STATUS_SUCCESS && !nxt_reply_echoes(tg, tg_len, reply))
		return -ENOMSG;
	return status;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_reply_check);

/**
 * nxt_reply_late_ms() - how late a reply to a telegram may still come
 * @tg: a telegram that passed nxt_telegram_check() and was sent
 * @len: its length
 *
 * After a transaction ends without its reply (a timeout, a signal), the
 * reply may still be on its way: the next telegram waits this long for it,
 * and goes as soon as it has come and been dropped.
 *
 * Quirk: DeleteUserFlash erases the whole user flash before it answers,
 * which takes long enough that NBC waits 3 s for it instead of 1 s; every
 * other command is answered within a few milliseconds of its arrival.
 *
 * Return: the time in milliseconds, NXT_LATE_REPLY_MS or more.
 */
unsigned int nxt_reply_late_ms(const u8 *tg, size_t len)
{
	if (len >= 2 && tg[0] == NXT_SYSTEM_CMD && tg[1] == NXT_DELETE_USER_FLASH)
		return NXT_SLOW_REPLY_MS;
	return NXT_LATE_REPLY_MS;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_reply_late_ms);

/**
 * nxt_stall_backoff_ms() - how long to wait before clearing a stall again
 * @stalls: stalls of the IN endpoint in a row, with no packet in between
 *
 * A first stall is cleared at once: a telegram may be waiting for it. An
 * endpoint that stalls again as soon as it is cleared would otherwise keep
 * a CPU in a loop of control transfers, so each further stall doubles the
 * wait, from NXT_STALL_BACKOFF_MIN_MS to NXT_STALL_BACKOFF_MAX_MS.
 *
 * Return: the wait in milliseconds.
 */
unsigned int nxt_stall_backoff_ms(unsigned int stalls)
{
	unsigned int ms;

	if (stalls <= 1)
		return 0;
	ms = NXT_STALL_BACKOFF_MIN_MS << min(stalls - 2, 7U);
	return min(ms, NXT_STALL_BACKOFF_MAX_MS);
}
EXPORT_SYMBOL_GPL(nxt_stall_backoff_ms);

/**
 * nxt_time_left() - time left until a point on a 64-bit clock, capped
 * @now: the clock now (get_jiffies_64(), say)
 * @until: the point
 * @max: the cap: @until is never further than this ahead
 *
 * Pure arithmetic on a clock that does not wrap: a point long past stays
 * past, however long ago it was, unlike with time_before() on a 32-bit
 * jiffies, which wraps after 2^31 ticks (24.9 days at HZ=1000).
 *
 * Return: @until - @now, at most @max; 0 once @until has come.
 */
u64 nxt_time_left(u64 now, u64 until, u64 max)
{
	if (until <= now)
		return 0;
	return min(until - now, max);
}
EXPORT_SYMBOL_IF_KUNIT(nxt_time_left);

/**
 * nxt_decode_versions() - decode a reply to GetVersions
 * @reply: a reply that passed nxt_reply_check() with status success
 * @len: its length
 * @protocol: the protocol version: major, minor
 * @firmware: the firmware version: major, minor
 *
 * Return: 0, or -%EPROTO if @reply is not a whole successful reply.
 */
int nxt_decode_versions(const u8 *reply, size_t len, u8 protocol[2],
			u8 firmware[2])
{
	const struct nxt_reply_versions *r = (const void *)reply;

	if (len != sizeof(*r) || r->h.opcode != NXT_GET_VERSIONS ||
	    r->h.status != NXT_STATUS_SUCCESS)
		return -EPROTO;
	protocol[0] = r->protocol_major;
	protocol[1] = r->protocol_minor;
	firmware[0] = r->firmware_major;
	firmware[1] = r->firmware_minor;
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_decode_versions);

/**
 * nxt_decode_device_info() - decode a reply to GetDeviceInfo
 * @reply: a reply that passed nxt_reply_check() with status success
 * @len: its length
 * @info: the decoded information
 *
 * Return: 0, or -%EPROTO if @reply is not a whole successful reply.
 */
int nxt_decode_device_info(const u8 *reply, size_t len,
			   struct nxt_device_info *info)
{
	const struct nxt_reply_device_info *r = (const void *)reply;
	size_t i, n;

	if (len != sizeof(*r) || r->h.opcode != NXT_GET_DEVICE_INFO ||
	    r->h.status != NXT_STATUS_SUCCESS)
		return -EPROTO;

	memset(info, 0, sizeof(*info));
	n = strnlen(r->name, sizeof(r->name));
	for (i = 0; i < n; i++)
		info->name[i] = r->name[i] >= 0x20 && r->name[i] <= 0x7e ? r->name[i] : '?';
	memcpy(info->bt_address, r->bt_address, sizeof(info->bt_address));
	info->free_flash = le32_to_cpu(r->free_flash);
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_decode_device_info);

/**
 * nxt_info_note_sent() - note a telegram sent to the brick
 * @info: what the brick last said about itself
 * @tg: the telegram, which passed nxt_telegram_check()
 * @len: its length
 *
 * A system command that may change the brick's name or its free flash
 * (SetBrickName, file writes and deletions, DeleteUserFlash) makes the
 * GetDeviceInfo values unknown until the next reply to GetDeviceInfo.
 */
void nxt_info_note_sent(struct nxt_brick_info *info, const u8 *tg, size_t len)
{
	if (len < NXT_TELEGRAM_MIN || (tg[0] & ~0x80) != NXT_SYSTEM_CMD)
		return;
	switch (tg[1]) {
	case 0x81:	/* OpenWrite */
	case 0x83:	/* Write */
	case 0x85:	/* Delete */
	case 0x89:	/* OpenWriteLinear */
	case 0x8b:	/* OpenWriteData */
	case 0x8c:	/* OpenAppendData */
	case 0x8d:	/* CropDataFile */
	case 0x98:	/* SetBrickName */
	case 0xa0:	/* DeleteUserFlash */
	case 0xa4:	/* BTFactoryReset */
		info->have_device = false;
		break;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_info_note_sent);

/**
 * nxt_info_note_reply() - learn from a reply what the brick says about itself
 * @info: what the brick last said about itself
 * @tg: the telegram that was answered
 * @tg_len: its length
 * @reply: its reply, which passed nxt_reply_check() for it
 * @len: the reply's length
 *
 * Successful replies to GetVersions, GetDeviceInfo and GetBatteryLevel
 * replace the values they carry; every other reply changes nothing.
 */
void nxt_info_note_reply(struct nxt_brick_info *info, const u8 *tg,
			 size_t tg_len, const u8 *reply, size_t len)
{
	const struct nxt_reply_battery *battery = (const void *)reply;

	if (tg_len < NXT_TELEGRAM_MIN || len < NXT_REPLY_MIN ||
	    reply[0] != NXT_REPLY || reply[1] != tg[1] ||
	    reply[2] != NXT_STATUS_SUCCESS)
		return;
	if (tg[0] == NXT_SYSTEM_CMD && tg[1] == NXT_GET_VERSIONS) {
		if (!nxt_decode_versions(reply, len, info->protocol, info->firmware))
			info->have_versions = true;
	} else if (tg[0] == NXT_SYSTEM_CMD && tg[1] == NXT_GET_DEVICE_INFO) {
		if (!nxt_decode_device_info(reply, len, &info->device))
			info->have_device = true;
	} else if (tg[0] == NXT_DIRECT_CMD && tg[1] == NXT_GET_BATTERY_LEVEL &&
		   len == sizeof(*battery)) {
		info->battery_mv = le16_to_cpu(battery->millivolts);
		info->have_battery = true;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_info_note_reply);

/*
 * Bluetooth framing.
 *
 * A byte stream has no packet boundaries, and the length prefix comes from
 * the brick like any other byte: it may be 0, longer than any reply, or
 * followed by fewer or more bytes than it says (a link that dropped bytes,
 * a brick that reset, garbage on a serial line). The reader trusts a
 * prefix only if it gives a reply's length (3 to 64) and the byte after it
 * is a reply's type (0x02); otherwise it drops the first byte it holds and
 * looks again at the next, so that it finds the frames again after any
 * garbage. A frame whose prefix promised more bytes than came is completed
 * by the next frame's bytes and fails the engine's reply check; the
 * transport resets the reader before it sends each telegram, since
 * nothing that came before then can answer it.
 */

/**
 * nxt_bt_rx_reset() - forget the frame being read
 * @rx: the reader
 */
void nxt_bt_rx_reset(struct nxt_bt_rx *rx)
{
	rx->dropped += rx->have;
	rx->have = 0;
}
EXPORT_SYMBOL_GPL(nxt_bt_rx_reset);

/* The held bytes can still start a frame. */
static bool nxt_bt_rx_plausible(const struct nxt_bt_rx *rx)
{
	unsigned int len;

	if (rx->have < NXT_BT_PREFIX)
		return true;
	len = get_unaligned_le16(rx->buf);
	if (len < NXT_REPLY_MIN || len > NXT_TELEGRAM_MAX)
		return false;
	return rx->have == NXT_BT_PREFIX || rx->buf[NXT_BT_PREFIX] == NXT_REPLY;
}

/**
 * nxt_bt_rx_feed() - read the brick's bytes until a reply is complete
 * @rx: the reader
 * @data: bytes from the link
 * @len: their number
 * @reply: set to the reply when one is complete (in @rx, valid until the
 *	next call), NULL otherwise
 * @reply_len: set to its length (3 to %NXT_TELEGRAM_MAX), 0 if none
 *
 * Never holds more than one frame: when a reply is complete it stops, and
 * the caller feeds the rest of @data after it has taken the reply.
 *
 * Return: the bytes of @data consumed.
 */
size_t nxt_bt_rx_feed(struct nxt_bt_rx *rx, const u8 *data, size_t len,
		      const u8 **reply, unsigned int *reply_len)
{
	size_t used = 0;

	*reply = NULL;
	*reply_len = 0;
	while (used < len) {
		rx->buf[rx->have++] = data[used++];
		/* At most three bytes are held while a frame is not trusted. */
		while (!nxt_bt_rx_plausible(rx)) {
			memmove(rx->buf, rx->buf + 1, --rx->have);
			rx->dropped++;
		}
		if (rx->have > NXT_BT_PREFIX &&
		    rx->have == NXT_BT_PREFIX + get_unaligned_le16(rx->buf)) {
			*reply = rx->buf + NXT_BT_PREFIX;
			*reply_len = rx->have - NXT_BT_PREFIX;
			rx->have = 0;
			break;
		}
	}
	return used;
}
EXPORT_SYMBOL_GPL(nxt_bt_rx_feed);

/**
 * nxt_bt_frame() - put a telegram in a Bluetooth frame
 * @frame: %NXT_BT_FRAME_MAX bytes
 * @tg: the telegram, already checked (nxt_telegram_check())
 * @len: its length, 2 to %NXT_TELEGRAM_MAX
 *
 * Return: the frame's length.
 */
unsigned int nxt_bt_frame(u8 *frame, const u8 *tg, size_t len)
{
	if (WARN_ON_ONCE(len > NXT_TELEGRAM_MAX))
		return 0;
	put_unaligned_le16(len, frame);
	memcpy(frame + NXT_BT_PREFIX, tg, len);
	return NXT_BT_PREFIX + len;
}
EXPORT_SYMBOL_GPL(nxt_bt_frame);

/*
 * Low-speed (I2C) sensor ports: the telegrams the I2C adapters send and
 * what their replies say (nxt_i2c.c). The replies are the brick's, so each
 * is checked for its shape before a byte of it is used.
 */

/**
 * nxt_ls_mode_tg() - SetInputMode: a port to low-speed mode with 9 V
 * @tg: the telegram, at least 5 bytes
 * @port: the input port, 0 to 3
 *
 * 9 V is what LEGO's ultrasonic sensor needs; other I2C sensors take the
 * same mode.
 *
 * Return: the telegram's length.
 */
unsigned int nxt_ls_mode_tg(u8 *tg, u8 port)
{
	tg[0] = NXT_DIRECT_CMD;
	tg[1] = NXT_SET_INPUT_MODE;
	tg[2] = port;
	tg[3] = NXT_SENSOR_LOWSPEED_9V;
	tg[4] = NXT_SENSOR_MODE_RAW;
	return 5;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_mode_tg);

/**
 * nxt_ls_write_tg() - LSWrite: one I2C transaction on a port
 * @tg: the telegram, at least NXT_LS_TG_MAX bytes
 * @port: the input port, 0 to 3
 * @addr: the device's 7-bit address
 * @buf: the bytes to write after the address
 * @len: their number, 0 to NXT_LS_WRITE_MAX
 * @rx_len: the bytes to read after them, 0 to NXT_LS_MAX
 *
 * Return: the telegram's length, or -%EINVAL for what the brick cannot do.
 */
int nxt_ls_write_tg(u8 *tg, u8 port, u16 addr, const u8 *buf, size_t len,
		    size_t rx_len)
{
	if (port >= NXT_INPUT_PORTS || addr > 0x7f || len > NXT_LS_WRITE_MAX ||
	    rx_len > NXT_LS_MAX)
		return -EINVAL;
	tg[0] = NXT_DIRECT_CMD;
	tg[1] = NXT_LS_WRITE;
	tg[2] = port;
	tg[3] = len + 1;
	tg[4] = rx_len;
	tg[5] = addr << 1;
	if (len)
		memcpy(tg + 6, buf, len);
	return 6 + len;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_write_tg);

/**
 * nxt_ls_port_tg() - LSGetStatus or LSRead of a port
 * @tg: the telegram, at least 3 bytes
 * @opcode: %NXT_LS_GET_STATUS or %NXT_LS_READ
 * @port: the input port, 0 to 3
 *
 * Return: the telegram's length.
 */
unsigned int nxt_ls_port_tg(u8 *tg, u8 opcode, u8 port)
{
	tg[0] = NXT_DIRECT_CMD;
	tg[1] = opcode;
	tg[2] = port;
	return 3;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_port_tg);

/**
 * nxt_ls_errno() - the errno of a low-speed port's status byte
 * @status: the status byte of a reply
 *
 * Return: 0 for success; -%EINPROGRESS while the port's transaction runs;
 * -%EAGAIN when the port is not ready (not in low-speed mode, settling
 * after SetInputMode, or busy); -%ENXIO for a bus error (what the brick
 * says when no device acknowledged its address); -%EINVAL for values the
 * brick refused; -%EIO for any other error.
 */
int nxt_ls_errno(u8 status)
{
	switch (status) {
	case NXT_STATUS_SUCCESS:
		return 0;
	case NXT_STATUS_PENDING:
		return -EINPROGRESS;
	case NXT_STATUS_NOT_READY:
		return -EAGAIN;
	case NXT_STATUS_BUS_ERROR:
		return -ENXIO;
	case 0xc0:	/* a value out of range */
	case 0xed:	/* an illegal size */
	case 0xff:	/* bad arguments */
		return -EINVAL;
	default:
		return -EIO;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_errno);

/**
 * nxt_ls_status() - the status byte of a reply to a low-speed telegram
 * @reply: the reply
 * @len: its length
 * @opcode: the telegram's opcode
 *
 * Return: the status byte, or -%EPROTO if @reply is not a reply to @opcode.
 */
int nxt_ls_status(const u8 *reply, size_t len, u8 opcode)
{
	if (len < NXT_REPLY_MIN || reply[0] != NXT_REPLY || reply[1] != opcode)
		return -EPROTO;
	return reply[2];
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_status);

/**
 * nxt_ls_ready() - what a reply to LSGetStatus says
 * @reply: the reply
 * @len: its length
 *
 * Return: the number of bytes read and ready (0 to NXT_LS_MAX) once the
 * port's transaction is over, -%EPROTO for a malformed reply, or the
 * status byte's nxt_ls_errno().
 */
int nxt_ls_ready(const u8 *reply, size_t len)
{
	int status = nxt_ls_status(reply, len, NXT_LS_GET_STATUS);

	if (status < 0)
		return status;
	if (status != NXT_STATUS_SUCCESS)
		return nxt_ls_errno(status);
	if (len < 4 || reply[3] > NXT_LS_MAX)
		return -EPROTO;
	return reply[3];
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_ready);

/**
 * nxt_ls_read_data() - the bytes of a reply to LSRead
 * @reply: the reply: status, count, then 16 bytes
 * @len: its length
 * @buf: where the bytes go
 * @want: how many were asked for, 1 to NXT_LS_MAX
 *
 * Return: 0 with @want bytes in @buf; -%EPROTO for a malformed reply or
 * a count other than @want; or the status byte's nxt_ls_errno().
 */
int nxt_ls_read_data(const u8 *reply, size_t len, u8 *buf, size_t want)
{
	int status = nxt_ls_status(reply, len, NXT_LS_READ);

	if (status < 0)
		return status;
	if (status != NXT_STATUS_SUCCESS)
		return nxt_ls_errno(status);
	if (len < 4 + NXT_LS_MAX || want > NXT_LS_MAX || reply[3] != want)
		return -EPROTO;
	memcpy(buf, reply + 4, want);
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_ls_read_data);
