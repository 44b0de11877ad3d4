// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT telegrams: validation, encoding and decoding.
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
 */
#include <linux/bug.h>
#include <linux/build_bug.h>
#include <linux/errno.h>
#include <linux/export.h>
#include <linux/kernel.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "nxt_proto.h"

/* Wire formats, after the type and opcode bytes or the reply's header. */

struct nxt_req_hdr {
	u8 type;
	u8 opcode;
} __packed;

struct nxt_reply_hdr {
	u8 type;
	u8 opcode;
	u8 status;
} __packed;

struct nxt_req_program {
	struct nxt_req_hdr h;
	char name[NXT_NAME_LEN];
} __packed;

struct nxt_req_sound_file {
	struct nxt_req_hdr h;
	u8 loop;
	char name[NXT_NAME_LEN];
} __packed;

struct nxt_req_tone {
	struct nxt_req_hdr h;
	__le16 frequency;
	__le16 duration;
} __packed;

struct nxt_req_output_state {
	struct nxt_req_hdr h;
	u8 port;
	s8 power;
	u8 mode;
	u8 regulation_mode;
	s8 turn_ratio;
	u8 run_state;
	__le32 tacho_limit;
} __packed;

struct nxt_req_input_mode {
	struct nxt_req_hdr h;
	u8 port;
	u8 type;
	u8 mode;
} __packed;

/* GetOutputState, GetInputValues, ResetInputScaledValue, LSGetStatus, LSRead */
struct nxt_req_port {
	struct nxt_req_hdr h;
	u8 port;
} __packed;

struct nxt_req_message_write {
	struct nxt_req_hdr h;
	u8 inbox;
	u8 size;
	u8 data[NXT_MESSAGE_MAX];
} __packed;

struct nxt_req_motor_position {
	struct nxt_req_hdr h;
	u8 port;
	u8 relative;
} __packed;

struct nxt_req_ls_write {
	struct nxt_req_hdr h;
	u8 port;
	u8 tx_length;
	u8 rx_length;
	u8 tx_data[NXT_LS_DATA_MAX];
} __packed;

struct nxt_req_message_read {
	struct nxt_req_hdr h;
	u8 remote_inbox;
	u8 local_inbox;
	u8 remove;
} __packed;

struct nxt_reply_output_state {
	struct nxt_reply_hdr h;
	u8 port;
	s8 power;
	u8 mode;
	u8 regulation_mode;
	s8 turn_ratio;
	u8 run_state;
	__le32 tacho_limit;
	__le32 tacho_count;
	__le32 block_tacho_count;
	__le32 rotation_count;
} __packed;

struct nxt_reply_input_values {
	struct nxt_reply_hdr h;
	u8 port;
	u8 valid;
	u8 calibrated;
	u8 type;
	u8 mode;
	__le16 raw;
	__le16 normalized;
	__le16 scaled;
	__le16 calibrated_value;
} __packed;

struct nxt_reply_battery {
	struct nxt_reply_hdr h;
	__le16 millivolts;
} __packed;

struct nxt_reply_keep_alive {
	struct nxt_reply_hdr h;
	__le32 sleep_limit;
} __packed;

struct nxt_reply_ls_status {
	struct nxt_reply_hdr h;
	u8 bytes_ready;
} __packed;

struct nxt_reply_ls_read {
	struct nxt_reply_hdr h;
	u8 length;
	u8 data[NXT_LS_DATA_MAX];
} __packed;

struct nxt_reply_program {
	struct nxt_reply_hdr h;
	char name[NXT_NAME_LEN];
} __packed;

struct nxt_reply_message_read {
	struct nxt_reply_hdr h;
	u8 local_inbox;
	u8 size;
	u8 data[NXT_MESSAGE_MAX];
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
static_assert(sizeof(struct nxt_reply_output_state) == 25);
static_assert(sizeof(struct nxt_reply_input_values) == 16);
static_assert(sizeof(struct nxt_reply_battery) == 5);
static_assert(sizeof(struct nxt_reply_keep_alive) == 7);
static_assert(sizeof(struct nxt_reply_ls_status) == 4);
static_assert(sizeof(struct nxt_reply_ls_read) == 20);
static_assert(sizeof(struct nxt_reply_program) == 23);
static_assert(sizeof(struct nxt_reply_message_read) == NXT_TELEGRAM_MAX);
static_assert(sizeof(struct nxt_reply_versions) == 7);
static_assert(sizeof(struct nxt_reply_device_info) == 33);
static_assert(sizeof(struct nxt_req_message_write) == 4 + NXT_MESSAGE_MAX);

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
	[NXT_GET_OUTPUT_STATE]		= sizeof(struct nxt_reply_output_state),
	[NXT_GET_INPUT_VALUES]		= sizeof(struct nxt_reply_input_values),
	[NXT_RESET_INPUT_SCALED_VALUE]	= NXT_REPLY_MIN,
	[NXT_MESSAGE_WRITE]		= NXT_REPLY_MIN,
	[NXT_RESET_MOTOR_POSITION]	= NXT_REPLY_MIN,
	[NXT_GET_BATTERY_LEVEL]		= sizeof(struct nxt_reply_battery),
	[NXT_STOP_SOUND_PLAYBACK]	= NXT_REPLY_MIN,
	[NXT_KEEP_ALIVE]		= sizeof(struct nxt_reply_keep_alive),
	[NXT_LS_GET_STATUS]		= sizeof(struct nxt_reply_ls_status),
	[NXT_LS_WRITE]			= NXT_REPLY_MIN,
	[NXT_LS_READ]			= sizeof(struct nxt_reply_ls_read),
	[NXT_GET_CURRENT_PROGRAM_NAME]	= sizeof(struct nxt_reply_program),
	[NXT_MESSAGE_READ]		= sizeof(struct nxt_reply_message_read),
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
EXPORT_SYMBOL_IF_KUNIT(nxt_stall_backoff_ms);

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
 * nxt_status_to_errno() - the errno a status byte of the brick maps to
 * @status: the status byte of a reply
 *
 * Return: 0 for %NXT_STATUS_SUCCESS, else a negative errno; -%EIO for codes
 * the firmware does not define. Documentation/lego/nxt-usb.rst has the table.
 */
int nxt_status_to_errno(u8 status)
{
	switch (status) {
	case NXT_STATUS_SUCCESS:
		return 0;
	case NXT_STATUS_PENDING:
		/* Not -EAGAIN, which means "busy, nothing sent" under O_NONBLOCK. */
		return -EINPROGRESS;
	case NXT_STATUS_MAILBOX_EMPTY:
		return -ENOMSG;
	case NXT_STATUS_NO_MORE_HANDLES:
		return -EMFILE;
	case NXT_STATUS_NO_SPACE:
	case NXT_STATUS_NO_LINEAR_SPACE:
		return -ENOSPC;
	case NXT_STATUS_NO_MORE_FILES:
	case NXT_STATUS_FILE_NOT_FOUND:
	case NXT_STATUS_MODULE_NOT_FOUND:
	case NXT_STATUS_FILE_TX_SRC_MISSING:
		return -ENOENT;
	case NXT_STATUS_END_OF_FILE:
		return -ENODATA;
	case NXT_STATUS_HANDLE_CLOSED:
	case NXT_STATUS_ILLEGAL_HANDLE:
		return -EBADF;
	case NXT_STATUS_FILE_BUSY:
	case NXT_STATUS_BT_BUSY:
	case NXT_STATUS_CHANNEL_BUSY:
		return -EBUSY;
	case NXT_STATUS_NO_WRITE_BUFFERS:
	case NXT_STATUS_BUFFER_FULL:
		return -ENOBUFS;
	case NXT_STATUS_FILE_FULL:
		return -EFBIG;
	case NXT_STATUS_FILE_EXISTS:
	case NXT_STATUS_FILE_TX_DST_EXISTS:
		return -EEXIST;
	case NXT_STATUS_OUT_OF_BOUNDS:
	case NXT_STATUS_OUT_OF_RANGE:
		return -ERANGE;
	case NXT_STATUS_NOT_LINEAR_FILE:
	case NXT_STATUS_APPEND_NOT_POSSIBLE:
	case NXT_STATUS_ILLEGAL_FILE_NAME:
	case NXT_STATUS_BAD_MAILBOX:
	case NXT_STATUS_BAD_FIELD:
	case NXT_STATUS_BAD_PORT:
	case NXT_STATUS_BAD_ARGUMENTS:
		return -EINVAL;
	case NXT_STATUS_BT_CONNECT_FAIL:
		return -ECONNREFUSED;
	case NXT_STATUS_BT_TIMEOUT:
	case NXT_STATUS_FILE_TX_TIMEOUT:
		return -ETIMEDOUT;
	case NXT_STATUS_UNKNOWN_OPCODE:
		return -EOPNOTSUPP;
	case NXT_STATUS_INSANE_PACKET:
		return -EBADMSG;
	case NXT_STATUS_BAD_CHANNEL:
		return -ENXIO;
	case NXT_STATUS_NO_PROGRAM:
		return -ESRCH;
	case NXT_STATUS_BAD_SIZE:
		return -EMSGSIZE;
	case NXT_STATUS_NO_MEMORY:
		return -ENOMEM;
	default:
		/* EOF expected, undefined error, bus error, VM fatal codes... */
		return -EIO;
	}
}
EXPORT_SYMBOL_IF_KUNIT(nxt_status_to_errno);

/* Encoders: check every argument, then build the telegram. */

static void nxt_put_hdr(u8 *tg, u8 opcode)
{
	struct nxt_req_hdr *h = (struct nxt_req_hdr *)tg;

	/* Typed commands always ask for a reply: its status is the result. */
	h->type = NXT_DIRECT_CMD;
	h->opcode = opcode;
}

static bool nxt_reserved_clear(const void *p, size_t n)
{
	return !memchr_inv(p, 0, n);
}

/* A file name: 1 to 19 printable ASCII characters and a NUL, zero-padded. */
static int nxt_put_name(char *dst, const char *name)
{
	size_t i, n = strnlen(name, NXT_NAME_LEN);

	if (n == 0 || n == NXT_NAME_LEN)
		return -EINVAL;
	for (i = 0; i < n; i++)
		if (name[i] < 0x20 || name[i] > 0x7e)
			return -EINVAL;
	memset(dst, 0, NXT_NAME_LEN);
	memcpy(dst, name, n);
	return 0;
}

static int nxt_encode_status_only(const void *arg, u8 *tg)
{
	const struct nxt_status_only *a = arg;

	if (!nxt_reserved_clear(a->reserved, sizeof(a->reserved)))
		return -EINVAL;
	return sizeof(struct nxt_req_hdr);
}

static int nxt_encode_start_program(const void *arg, u8 *tg)
{
	const struct nxt_program *a = arg;
	struct nxt_req_program *r = (void *)tg;

	if (!nxt_reserved_clear(a->reserved, sizeof(a->reserved)) ||
	    nxt_put_name(r->name, a->name))
		return -EINVAL;
	return sizeof(*r);
}

static int nxt_encode_sound_file(const void *arg, u8 *tg)
{
	const struct nxt_sound_file *a = arg;
	struct nxt_req_sound_file *r = (void *)tg;

	if (a->loop > 1 || !nxt_reserved_clear(a->reserved, sizeof(a->reserved)) ||
	    nxt_put_name(r->name, a->name))
		return -EINVAL;
	r->loop = a->loop;
	return sizeof(*r);
}

static int nxt_encode_tone(const void *arg, u8 *tg)
{
	const struct nxt_tone *a = arg;
	struct nxt_req_tone *r = (void *)tg;

	if (a->frequency < NXT_TONE_MIN_HZ || a->frequency > NXT_TONE_MAX_HZ ||
	    !nxt_reserved_clear(a->reserved, sizeof(a->reserved)))
		return -EINVAL;
	r->frequency = cpu_to_le16(a->frequency);
	r->duration = cpu_to_le16(a->duration);
	return sizeof(*r);
}

static bool nxt_run_state_valid(u8 state)
{
	return state == NXT_RUN_STATE_IDLE || state == NXT_RUN_STATE_RAMPUP ||
	       state == NXT_RUN_STATE_RUNNING || state == NXT_RUN_STATE_RAMPDOWN;
}

static int nxt_encode_set_output_state(const void *arg, u8 *tg)
{
	const struct nxt_output_state *a = arg;
	struct nxt_req_output_state *r = (void *)tg;
	const u8 mode_bits = NXT_MODE_MOTORON | NXT_MODE_BRAKE | NXT_MODE_REGULATED;

	if ((a->port >= NXT_OUTPUT_PORTS && a->port != NXT_OUTPUT_ALL) ||
	    abs(a->power) > NXT_POWER_MAX || abs(a->turn_ratio) > NXT_POWER_MAX ||
	    (a->mode & ~mode_bits) || a->regulation_mode > NXT_REGULATION_MOTOR_SYNC ||
	    !nxt_run_state_valid(a->run_state) || a->reserved)
		return -EINVAL;
	r->port = a->port;
	r->power = a->power;
	r->mode = a->mode;
	r->regulation_mode = a->regulation_mode;
	r->turn_ratio = a->turn_ratio;
	r->run_state = a->run_state;
	r->tacho_limit = cpu_to_le32(a->tacho_limit);
	return sizeof(*r);
}

static int nxt_encode_input_mode(const void *arg, u8 *tg)
{
	const struct nxt_input_mode *a = arg;
	struct nxt_req_input_mode *r = (void *)tg;

	/* Every mode byte is valid: a mode in the top bits, a slope below. */
	if (a->port >= NXT_INPUT_PORTS || a->type >= NXT_SENSOR_TYPES)
		return -EINVAL;
	r->port = a->port;
	r->type = a->type;
	r->mode = a->mode;
	return sizeof(*r);
}

static int nxt_encode_port(u8 port, unsigned int ports, u8 *tg)
{
	struct nxt_req_port *r = (void *)tg;

	if (port >= ports)
		return -EINVAL;
	r->port = port;
	return sizeof(*r);
}

static int nxt_encode_get_output_state(const void *arg, u8 *tg)
{
	const struct nxt_output_state *a = arg;

	if (a->reserved)
		return -EINVAL;
	return nxt_encode_port(a->port, NXT_OUTPUT_PORTS, tg);
}

static int nxt_encode_get_input_values(const void *arg, u8 *tg)
{
	const struct nxt_input_values *a = arg;

	if (a->reserved)
		return -EINVAL;
	return nxt_encode_port(a->port, NXT_INPUT_PORTS, tg);
}

static int nxt_encode_input_port(const void *arg, u8 *tg)
{
	const struct nxt_input_port *a = arg;

	if (!nxt_reserved_clear(a->reserved, sizeof(a->reserved)))
		return -EINVAL;
	return nxt_encode_port(a->port, NXT_INPUT_PORTS, tg);
}

static int nxt_encode_ls_status(const void *arg, u8 *tg)
{
	const struct nxt_ls_status *a = arg;

	if (a->reserved)
		return -EINVAL;
	return nxt_encode_port(a->port, NXT_INPUT_PORTS, tg);
}

static int nxt_encode_ls_read(const void *arg, u8 *tg)
{
	const struct nxt_ls_read *a = arg;

	if (a->reserved)
		return -EINVAL;
	return nxt_encode_port(a->port, NXT_INPUT_PORTS, tg);
}

static int nxt_encode_message_write(const void *arg, u8 *tg)
{
	const struct nxt_message *a = arg;
	struct nxt_req_message_write *r = (void *)tg;

	/* The firmware takes only NUL-terminated messages, NUL counted. */
	if (a->inbox >= NXT_INBOXES || a->size < 1 || a->size > NXT_MESSAGE_MAX ||
	    a->data[a->size - 1] != '\0')
		return -EINVAL;
	r->inbox = a->inbox;
	r->size = a->size;
	memcpy(r->data, a->data, a->size);
	return offsetof(struct nxt_req_message_write, data) + a->size;
}

static int nxt_encode_motor_position(const void *arg, u8 *tg)
{
	const struct nxt_motor_position *a = arg;
	struct nxt_req_motor_position *r = (void *)tg;

	if (a->port >= NXT_OUTPUT_PORTS || a->relative > 1 || a->reserved)
		return -EINVAL;
	r->port = a->port;
	r->relative = a->relative;
	return sizeof(*r);
}

static int nxt_encode_battery(const void *arg, u8 *tg)
{
	const struct nxt_battery *a = arg;

	if (a->reserved)
		return -EINVAL;
	return sizeof(struct nxt_req_hdr);
}

static int nxt_encode_keep_alive(const void *arg, u8 *tg)
{
	const struct nxt_keep_alive *a = arg;

	if (!nxt_reserved_clear(a->reserved, sizeof(a->reserved)))
		return -EINVAL;
	return sizeof(struct nxt_req_hdr);
}

static int nxt_encode_ls_write(const void *arg, u8 *tg)
{
	const struct nxt_ls_write *a = arg;
	struct nxt_req_ls_write *r = (void *)tg;

	if (a->port >= NXT_INPUT_PORTS || a->tx_length < 1 ||
	    a->tx_length > NXT_LS_DATA_MAX || a->rx_length > NXT_LS_DATA_MAX)
		return -EINVAL;
	r->port = a->port;
	r->tx_length = a->tx_length;
	r->rx_length = a->rx_length;
	memcpy(r->tx_data, a->tx_data, a->tx_length);
	return offsetof(struct nxt_req_ls_write, tx_data) + a->tx_length;
}

static int nxt_encode_program_name(const void *arg, u8 *tg)
{
	const struct nxt_program *a = arg;

	if (!nxt_reserved_clear(a->reserved, sizeof(a->reserved)))
		return -EINVAL;
	return sizeof(struct nxt_req_hdr);
}

static int nxt_encode_message_read(const void *arg, u8 *tg)
{
	const struct nxt_message *a = arg;
	struct nxt_req_message_read *r = (void *)tg;

	if (a->inbox >= NXT_REMOTE_INBOXES || a->local_inbox >= NXT_INBOXES ||
	    a->remove > 1)
		return -EINVAL;
	r->remote_inbox = a->inbox;
	r->local_inbox = a->local_inbox;
	r->remove = a->remove;
	return sizeof(*r);
}

/*
 * Decoders. The reply has been checked for type, opcode and length and is
 * zero-padded, and zero entirely past the header when its status is not
 * success, so each decoder reads a whole reply; a count it reads is still
 * checked against its field before it is used.
 */

static int nxt_decode_output_state(const u8 *reply, void *arg)
{
	const struct nxt_reply_output_state *r = (const void *)reply;
	struct nxt_output_state *a = arg;

	a->power = r->power;
	a->mode = r->mode;
	a->regulation_mode = r->regulation_mode;
	a->turn_ratio = r->turn_ratio;
	a->run_state = r->run_state;
	a->tacho_limit = le32_to_cpu(r->tacho_limit);
	a->tacho_count = (s32)le32_to_cpu(r->tacho_count);
	a->block_tacho_count = (s32)le32_to_cpu(r->block_tacho_count);
	a->rotation_count = (s32)le32_to_cpu(r->rotation_count);
	return 0;
}

static int nxt_decode_input_values(const u8 *reply, void *arg)
{
	const struct nxt_reply_input_values *r = (const void *)reply;
	struct nxt_input_values *a = arg;

	a->valid = r->valid;
	a->calibrated = r->calibrated;
	a->type = r->type;
	a->mode = r->mode;
	a->raw = le16_to_cpu(r->raw);
	a->normalized = le16_to_cpu(r->normalized);
	a->scaled = (s16)le16_to_cpu(r->scaled);
	a->calibrated_value = (s16)le16_to_cpu(r->calibrated_value);
	return 0;
}

static int nxt_decode_battery(const u8 *reply, void *arg)
{
	const struct nxt_reply_battery *r = (const void *)reply;
	struct nxt_battery *a = arg;

	a->millivolts = le16_to_cpu(r->millivolts);
	return 0;
}

static int nxt_decode_keep_alive(const u8 *reply, void *arg)
{
	const struct nxt_reply_keep_alive *r = (const void *)reply;
	struct nxt_keep_alive *a = arg;

	a->sleep_limit = le32_to_cpu(r->sleep_limit);
	return 0;
}

static int nxt_decode_ls_status(const u8 *reply, void *arg)
{
	const struct nxt_reply_ls_status *r = (const void *)reply;
	struct nxt_ls_status *a = arg;

	if (r->bytes_ready > NXT_LS_DATA_MAX)
		return -EPROTO;
	a->bytes_ready = r->bytes_ready;
	return 0;
}

static int nxt_decode_ls_read(const u8 *reply, void *arg)
{
	const struct nxt_reply_ls_read *r = (const void *)reply;
	struct nxt_ls_read *a = arg;

	if (r->length > NXT_LS_DATA_MAX)
		return -EPROTO;
	a->length = r->length;
	memset(a->data, 0, sizeof(a->data));
	memcpy(a->data, r->data, r->length);
	return 0;
}

static int nxt_decode_program_name(const u8 *reply, void *arg)
{
	const struct nxt_reply_program *r = (const void *)reply;
	struct nxt_program *a = arg;
	size_t n = strnlen(r->name, NXT_NAME_LEN);

	if (n == NXT_NAME_LEN)
		return -EPROTO;
	memset(a->name, 0, sizeof(a->name));
	memcpy(a->name, r->name, n);
	return 0;
}

static int nxt_decode_message_read(const u8 *reply, void *arg)
{
	const struct nxt_reply_message_read *r = (const void *)reply;
	struct nxt_message *a = arg;

	if (r->size > NXT_MESSAGE_MAX)
		return -EPROTO;
	/* Echoed by a reply of success only (an error's reply is cut short). */
	if (r->h.status == NXT_STATUS_SUCCESS)
		a->local_inbox = r->local_inbox;
	a->size = r->size;
	memset(a->data, 0, sizeof(a->data));
	memcpy(a->data, r->data, r->size);
	return 0;
}

/*
 * The typed ioctl NXT_IOC_<name> of direct command NXT_<name>: the size its
 * number encodes must be that of its structure @_type, which must fit
 * union nxt_command_arg, the ioctl's buffer.
 */
#define NXT_CMD(_name, _type, _enc, _dec) {				\
	.ioctl = NXT_IOC_##_name +					\
		 BUILD_BUG_ON_ZERO(_IOC_SIZE(NXT_IOC_##_name) != sizeof(_type)) + \
		 BUILD_BUG_ON_ZERO(sizeof(_type) > sizeof(union nxt_command_arg)), \
	.opcode = NXT_##_name,						\
	.status_offset = offsetof(_type, status),			\
	.encode = _enc,							\
	.decode = _dec,							\
}

static const struct nxt_command nxt_commands[] = {
	NXT_CMD(START_PROGRAM, struct nxt_program,
		nxt_encode_start_program, NULL),
	NXT_CMD(STOP_PROGRAM, struct nxt_status_only,
		nxt_encode_status_only, NULL),
	NXT_CMD(PLAY_SOUND_FILE, struct nxt_sound_file,
		nxt_encode_sound_file, NULL),
	NXT_CMD(PLAY_TONE, struct nxt_tone,
		nxt_encode_tone, NULL),
	NXT_CMD(SET_OUTPUT_STATE, struct nxt_output_state,
		nxt_encode_set_output_state, NULL),
	NXT_CMD(SET_INPUT_MODE, struct nxt_input_mode,
		nxt_encode_input_mode, NULL),
	NXT_CMD(GET_OUTPUT_STATE, struct nxt_output_state,
		nxt_encode_get_output_state, nxt_decode_output_state),
	NXT_CMD(GET_INPUT_VALUES, struct nxt_input_values,
		nxt_encode_get_input_values, nxt_decode_input_values),
	NXT_CMD(RESET_INPUT_SCALED_VALUE, struct nxt_input_port, nxt_encode_input_port, NULL),
	NXT_CMD(MESSAGE_WRITE, struct nxt_message,
		nxt_encode_message_write, NULL),
	NXT_CMD(RESET_MOTOR_POSITION, struct nxt_motor_position, nxt_encode_motor_position, NULL),
	NXT_CMD(GET_BATTERY_LEVEL, struct nxt_battery,
		nxt_encode_battery, nxt_decode_battery),
	NXT_CMD(STOP_SOUND_PLAYBACK, struct nxt_status_only, nxt_encode_status_only, NULL),
	NXT_CMD(KEEP_ALIVE, struct nxt_keep_alive,
		nxt_encode_keep_alive, nxt_decode_keep_alive),
	NXT_CMD(LS_GET_STATUS, struct nxt_ls_status,
		nxt_encode_ls_status, nxt_decode_ls_status),
	NXT_CMD(LS_WRITE, struct nxt_ls_write,
		nxt_encode_ls_write, NULL),
	NXT_CMD(LS_READ, struct nxt_ls_read,
		nxt_encode_ls_read, nxt_decode_ls_read),
	NXT_CMD(GET_CURRENT_PROGRAM_NAME, struct nxt_program,
		nxt_encode_program_name, nxt_decode_program_name),
	NXT_CMD(MESSAGE_READ, struct nxt_message,
		nxt_encode_message_read, nxt_decode_message_read),
};

/**
 * nxt_command_find() - the typed direct command of an ioctl number
 * @ioctl: the ioctl number, size and direction included
 *
 * Return: the command, or NULL if @ioctl is not a typed direct command.
 */
const struct nxt_command *nxt_command_find(unsigned int ioctl)
{
	size_t i;

	for (i = 0; i < ARRAY_SIZE(nxt_commands); i++)
		if (nxt_commands[i].ioctl == ioctl)
			return &nxt_commands[i];
	return NULL;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_command_find);

/**
 * nxt_command_encode() - check a typed command's argument, build its telegram
 * @cmd: the command
 * @arg: its ioctl argument, _IOC_SIZE(@cmd->ioctl) bytes
 * @tg: NXT_TELEGRAM_MAX bytes for the telegram; bytes past its length are zero
 *
 * Return: the telegram's length, or -%EINVAL if an argument is out of range
 * or a reserved member is not zero.
 */
int nxt_command_encode(const struct nxt_command *cmd, const void *arg, u8 *tg)
{
	int len;

	memset(tg, 0, NXT_TELEGRAM_MAX);
	nxt_put_hdr(tg, cmd->opcode);
	len = cmd->encode(arg, tg);
	if (len < 0)
		memset(tg, 0, NXT_TELEGRAM_MAX);
	return len;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_command_encode);

/**
 * nxt_command_decode() - fill a typed command's argument from its reply
 * @cmd: the command
 * @reply: a reply that passed nxt_reply_check() for the command's telegram
 * @len: its length, NXT_REPLY_MIN to NXT_TELEGRAM_MAX
 * @arg: the ioctl argument; its status and output members are written, its
 *	input members are left as they are
 *
 * When the status is not success, the output members are zero.
 *
 * Return: 0, or -%EPROTO if a count in the reply does not fit its field.
 */
int nxt_command_decode(const struct nxt_command *cmd, const u8 *reply,
		       size_t len, void *arg)
{
	u8 buf[NXT_TELEGRAM_MAX] = { };
	u8 status = reply[2];
	int ret = 0;

	if (WARN_ON_ONCE(len < NXT_REPLY_MIN || len > NXT_TELEGRAM_MAX))
		return -EPROTO;
	memcpy(buf, reply, status == NXT_STATUS_SUCCESS ? len : NXT_REPLY_MIN);
	if (cmd->decode)
		ret = cmd->decode(buf, arg);
	((u8 *)arg)[cmd->status_offset] = status;
	return ret;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_command_decode);

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
