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
 * union nxt_command_arg - room for the argument of any typed ioctl, aligned
 *	for each of them
 * @program: StartProgram, GetCurrentProgramName
 * @status_only: StopProgram, StopSoundPlayback
 * @sound_file: PlaySoundFile
 * @tone: PlayTone
 * @output_state: SetOutputState, GetOutputState
 * @input_mode: SetInputMode
 * @input_values: GetInputValues
 * @input_port: ResetInputScaledValue
 * @motor_position: ResetMotorPosition
 * @message: MessageWrite, MessageRead
 * @battery: GetBatteryLevel
 * @keep_alive: KeepAlive
 * @ls_status: LSGetStatus
 * @ls_write: LSWrite
 * @ls_read: LSRead
 * @bytes: the argument as bytes
 */
union nxt_command_arg {
	struct nxt_program program;
	struct nxt_status_only status_only;
	struct nxt_sound_file sound_file;
	struct nxt_tone tone;
	struct nxt_output_state output_state;
	struct nxt_input_mode input_mode;
	struct nxt_input_values input_values;
	struct nxt_input_port input_port;
	struct nxt_motor_position motor_position;
	struct nxt_message message;
	struct nxt_battery battery;
	struct nxt_keep_alive keep_alive;
	struct nxt_ls_status ls_status;
	struct nxt_ls_write ls_write;
	struct nxt_ls_read ls_read;
	u8 bytes[NXT_TELEGRAM_MAX];
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

/**
 * struct nxt_brick_info - what the brick last said about itself
 * @have_versions: @protocol and @firmware hold a reply to GetVersions
 * @have_device: @device holds a reply to GetDeviceInfo, and no command that
 *	may change the name or the free flash was sent after it
 * @have_battery: @battery_mv holds a reply to GetBatteryLevel
 * @protocol: protocol version, major and minor
 * @firmware: firmware version, major and minor
 * @battery_mv: battery voltage in millivolts
 * @device: name, Bluetooth address and free flash
 *
 * Filled from the replies to the telegrams that the users of the brick send
 * (nxt_info_note_reply()); the driver never asks the brick for it itself.
 */
struct nxt_brick_info {
	bool have_versions;
	bool have_device;
	bool have_battery;
	u8 protocol[2];
	u8 firmware[2];
	u16 battery_mv;
	struct nxt_device_info device;
};

/* System commands whose replies fill struct nxt_brick_info. */
#define NXT_GET_VERSIONS	0x88
#define NXT_GET_DEVICE_INFO	0x9b
/* The system command the brick is slow to answer. */
#define NXT_DELETE_USER_FLASH	0xa0

/* How late a reply may come after its transaction ended (nxt_reply_late_ms()). */
#define NXT_LATE_REPLY_MS	20
#define NXT_SLOW_REPLY_MS	3000

/* Waits before clearing a stall again (nxt_stall_backoff_ms()). */
#define NXT_STALL_BACKOFF_MIN_MS	10U
#define NXT_STALL_BACKOFF_MAX_MS	1000U

int nxt_telegram_check(const u8 *tg, size_t len);
unsigned int nxt_reply_length(const u8 *tg, size_t len);
int nxt_reply_check(const u8 *tg, size_t tg_len, const u8 *reply, size_t len);
int nxt_status_to_errno(u8 status);
unsigned int nxt_reply_late_ms(const u8 *tg, size_t len);
unsigned int nxt_stall_backoff_ms(unsigned int stalls);
u64 nxt_time_left(u64 now, u64 until, u64 max);
bool nxt_request_complete(const u8 *tg, size_t len);

const struct nxt_command *nxt_command_find(unsigned int ioctl);
int nxt_command_encode(const struct nxt_command *cmd, const void *arg, u8 *tg);
int nxt_command_decode(const struct nxt_command *cmd, const u8 *reply,
		       size_t len, void *arg);
int nxt_decode_versions(const u8 *reply, size_t len, u8 protocol[2],
			u8 firmware[2]);
int nxt_decode_device_info(const u8 *reply, size_t len,
			   struct nxt_device_info *info);
void nxt_info_note_sent(struct nxt_brick_info *info, const u8 *tg, size_t len);
void nxt_info_note_reply(struct nxt_brick_info *info, const u8 *tg,
			 size_t tg_len, const u8 *reply, size_t len);

#endif /* _NXT_PROTO_H */
