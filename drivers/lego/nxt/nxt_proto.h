/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT telegrams: what may be sent, and which packet answers
 * which telegram.
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

/*
 * The direct commands the driver checks by name: those of LEGO's firmware
 * 1.05. The driver also knows the shapes of 1.28's and of the system
 * commands, by number (nxt_proto.c).
 */
enum nxt_opcode {
	NXT_START_PROGRAM		= 0x00,
	NXT_STOP_PROGRAM		= 0x01,
	NXT_PLAY_SOUND_FILE		= 0x02,
	NXT_PLAY_TONE			= 0x03,
	NXT_SET_OUTPUT_STATE		= 0x04,
	NXT_SET_INPUT_MODE		= 0x05,
	NXT_GET_OUTPUT_STATE		= 0x06,
	NXT_GET_INPUT_VALUES		= 0x07,
	NXT_RESET_INPUT_SCALED_VALUE	= 0x08,
	NXT_MESSAGE_WRITE		= 0x09,
	NXT_RESET_MOTOR_POSITION	= 0x0a,
	NXT_GET_BATTERY_LEVEL		= 0x0b,
	NXT_STOP_SOUND_PLAYBACK		= 0x0c,
	NXT_KEEP_ALIVE			= 0x0d,
	NXT_LS_GET_STATUS		= 0x0e,
	NXT_LS_WRITE			= 0x0f,
	NXT_LS_READ			= 0x10,
	NXT_GET_CURRENT_PROGRAM_NAME	= 0x11,
	NXT_MESSAGE_READ		= 0x13,
};

/* The status byte of a successful reply; any other value is the brick's error. */
#define NXT_STATUS_SUCCESS	0x00

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

/*
 * Bluetooth (the brick's serial port profile, or any serial line) carries
 * each telegram after a 2-byte little-endian length that does not count
 * itself. The driver sends and accepts telegrams of the USB sizes only: one
 * /dev/nxtN ABI whatever the link.
 */
#define NXT_BT_PREFIX		2
#define NXT_BT_FRAME_MAX	(NXT_BT_PREFIX + NXT_TELEGRAM_MAX)

/**
 * struct nxt_bt_rx - the brick's replies read out of a serial byte stream
 * @have: bytes of the frame being read, in @buf (its prefix included)
 * @dropped: bytes skipped to find a frame again, since the reset
 * @buf: the frame being read: the length, then the reply
 *
 * Only nxt_bt_rx_reset() and nxt_bt_rx_feed() touch it; the transport
 * serialises their calls.
 */
struct nxt_bt_rx {
	unsigned int have;
	unsigned int dropped;
	u8 buf[NXT_BT_FRAME_MAX];
};

void nxt_bt_rx_reset(struct nxt_bt_rx *rx);
size_t nxt_bt_rx_feed(struct nxt_bt_rx *rx, const u8 *data, size_t len,
		      const u8 **reply, unsigned int *reply_len);
unsigned int nxt_bt_frame(u8 *frame, const u8 *tg, size_t len);

/*
 * A sensor port in low-speed (I2C) mode: the brick runs one I2C transaction
 * per LSWrite, whose first byte is the device's address in 8-bit form (the
 * 7-bit address shifted left, as LEGO writes it: 0x02 for the ultrasonic
 * sensor), followed by up to 15 bytes to write, then, if bytes are to be
 * read, a repeated start and up to 16 bytes read. LSGetStatus says whether
 * that transaction is still running and how many bytes it read; LSRead
 * returns them.
 */
#define NXT_INPUT_PORTS		4
#define NXT_LS_MAX		16
#define NXT_LS_WRITE_MAX	(NXT_LS_MAX - 1)
/* The sensor types and mode of SetInputMode that a low-speed port needs. */
#define NXT_SENSOR_LOWSPEED_9V	0x0b
#define NXT_SENSOR_MODE_RAW	0x00
/* The status bytes of a low-speed port the driver tells apart. */
#define NXT_STATUS_PENDING	0x20	/* the I2C transaction is still running */
#define NXT_STATUS_BUS_ERROR	0xdd	/* nothing acknowledged, or the bus failed */
#define NXT_STATUS_NOT_READY	0xe0	/* not in low-speed mode, or settling, or busy */

/* The longest telegram of a low-speed transaction: LSWrite with 16 bytes. */
#define NXT_LS_TG_MAX		(5 + NXT_LS_MAX)

unsigned int nxt_ls_mode_tg(u8 *tg, u8 port);
int nxt_ls_write_tg(u8 *tg, u8 port, u16 addr, const u8 *buf, size_t len,
		    size_t rx_len);
unsigned int nxt_ls_port_tg(u8 *tg, u8 opcode, u8 port);
int nxt_ls_errno(u8 status);
int nxt_ls_status(const u8 *reply, size_t len, u8 opcode);
int nxt_ls_ready(const u8 *reply, size_t len);
int nxt_ls_read_data(const u8 *reply, size_t len, u8 *buf, size_t want);

int nxt_telegram_check(const u8 *tg, size_t len);
unsigned int nxt_reply_length(const u8 *tg, size_t len);
int nxt_reply_check(const u8 *tg, size_t tg_len, const u8 *reply, size_t len);
unsigned int nxt_reply_late_ms(const u8 *tg, size_t len);
unsigned int nxt_stall_backoff_ms(unsigned int stalls);
u64 nxt_time_left(u64 now, u64 until, u64 max);
bool nxt_request_complete(const u8 *tg, size_t len);

int nxt_decode_versions(const u8 *reply, size_t len, u8 protocol[2],
			u8 firmware[2]);
int nxt_decode_device_info(const u8 *reply, size_t len,
			   struct nxt_device_info *info);
void nxt_info_note_sent(struct nxt_brick_info *info, const u8 *tg, size_t len);
void nxt_info_note_reply(struct nxt_brick_info *info, const u8 *tg,
			 size_t tg_len, const u8 *reply, size_t len);

#endif /* _NXT_PROTO_H */
