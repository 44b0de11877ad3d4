/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensor protocol core.
 *
 * Pure functions and a byte-driven state machine with no tty, timer or
 * device calls, so that the protocol is tested with KUnit and fuzzed in
 * userspace. The line discipline (ev3_uart_ldisc.c) feeds it bytes and acts
 * on the events it returns.
 */
#ifndef _EV3_UART_PROTO_H
#define _EV3_UART_PROTO_H

#include <linux/types.h>

/* Message header: 0bTTLLLCCC, T = message type, L = log2(payload), C = command/mode. */
#define EV3_UART_MSG_TYPE_MASK		0xc0
#define EV3_UART_MSG_SIZE_MASK		0x38
#define EV3_UART_MSG_SIZE_SHIFT		3
#define EV3_UART_MSG_CMD_MASK		0x07

/**
 * enum ev3_uart_msg_type - the two top bits of a message header
 * @EV3_UART_MSG_SYS: one-byte system message (SYNC, NACK, ACK)
 * @EV3_UART_MSG_CMD: command (TYPE, MODES, SPEED, SELECT, WRITE)
 * @EV3_UART_MSG_INFO: mode information, with an extra info-type byte
 * @EV3_UART_MSG_DATA: sensor values for one mode
 */
enum ev3_uart_msg_type {
	EV3_UART_MSG_SYS	= 0x00,
	EV3_UART_MSG_CMD	= 0x40,
	EV3_UART_MSG_INFO	= 0x80,
	EV3_UART_MSG_DATA	= 0xc0,
};

/* System messages. */
#define EV3_UART_SYS_SYNC		0x00
#define EV3_UART_SYS_NACK		0x02
#define EV3_UART_SYS_ACK		0x04

/* Commands (the low three bits of a CMD header). */
#define EV3_UART_CMD_TYPE		0
#define EV3_UART_CMD_MODES		1
#define EV3_UART_CMD_SPEED		2
#define EV3_UART_CMD_SELECT		3
#define EV3_UART_CMD_WRITE		4
#define EV3_UART_CMD_EXT_MODE		6	/* Powered Up only */
#define EV3_UART_CMD_VERSION		7	/* Powered Up only */

/* INFO types (the byte after an INFO header). */
#define EV3_UART_INFO_NAME		0x00
#define EV3_UART_INFO_RAW		0x01
#define EV3_UART_INFO_PCT		0x02
#define EV3_UART_INFO_SI		0x03
#define EV3_UART_INFO_UNITS		0x04
#define EV3_UART_INFO_PUP_FIRST		0x05	/* 0x05..0x0c: Powered Up only */
#define EV3_UART_INFO_MAPPING		0x05	/* in and out flags */
#define EV3_UART_INFO_MODE_COMBOS	0x06	/* u16 bitmaps of modes */
#define EV3_UART_INFO_PUP_LAST		0x0c
#define EV3_UART_INFO_MODE_PLUS_8	0x20	/* flag: describes mode + 8 */
#define EV3_UART_INFO_FORMAT		0x80

/* The largest payload any sensor or host uses; the header allows 128. */
#define EV3_UART_MAX_PAYLOAD		32
/* Header + INFO byte + payload + checksum. */
#define EV3_UART_MAX_MSG_LEN		(EV3_UART_MAX_PAYLOAD + 3)

/* Modes a header's 3-bit field can name; Powered Up devices have up to 16. */
#define EV3_UART_MAX_EV3_MODES		8
#define EV3_UART_MAX_MODES		16
/* A Powered Up mode name of up to this length may be followed by flags. */
#define EV3_UART_SHORT_NAME_LEN		5
#define EV3_UART_NAME_FLAGS		6
/* The mode combinations a MODE_COMBOS INFO (16 bytes at most) can hold. */
#define EV3_UART_MAX_COMBOS		8
/* The one EXT_MODE message a Powered Up device sends in the data phase. */
#define EV3_UART_EXT_MODE_HDR		(EV3_UART_MSG_CMD | EV3_UART_CMD_EXT_MODE)
#define EV3_UART_NAME_LEN		11
#define EV3_UART_UNITS_LEN		4
#define EV3_UART_TYPE_MIN		1
#define EV3_UART_TYPE_MAX		101
#define EV3_UART_SPEED_MIN		2400
#define EV3_UART_SPEED_MAX		460800
/*
 * Powered Up devices' speed, at which the host may offer them a "fast
 * sync": it sends SPEED 115200 at 115200 baud, and a device that answers
 * ACK sends its handshake at that speed (see ev3_uart_parser_probe()).
 */
#define EV3_UART_SPEED_FAST		115200
/* The length of a SPEED message (ev3_uart_build_speed()). */
#define EV3_UART_SPEED_MSG_LEN		6
/* Decimals beyond this make 10^decimals overflow the fixed-point values. */
#define EV3_UART_MAX_DECIMALS		9
#define EV3_UART_MAX_FIGURES		15
/* How far ahead of the clock ev3_uart_msg_time() may date a message. */
#define EV3_UART_MSG_AHEAD_NS		50000000
/* Bad frames (net of good ones) or silent keep-alive periods before a resync. */
#define EV3_UART_MAX_DATA_ERR		6

/* Sensor types with quirks or well-known names. */
#define EV3_UART_TYPE_COLOR		29
#define EV3_UART_TYPE_US		30
#define EV3_UART_TYPE_GYRO		32
#define EV3_UART_TYPE_IR		33
/* Powered Up (LUMP) device types (&ev3_uart_sensor.lump set). */
#define EV3_UART_TYPE_BOOST_CDS		37
#define EV3_UART_TYPE_SPIKE_COLOR	61
#define EV3_UART_TYPE_SPIKE_DIST	62

#define EV3_UART_NO_MODE		0xff
/**
 * enum ev3_uart_data_type - the wire type of the values of a mode
 * @EV3_UART_DATA_S8: signed 8-bit
 * @EV3_UART_DATA_S16: signed 16-bit little endian
 * @EV3_UART_DATA_S32: signed 32-bit little endian
 * @EV3_UART_DATA_FLOAT: IEEE 754 single precision, little endian
 */
enum ev3_uart_data_type {
	EV3_UART_DATA_S8,
	EV3_UART_DATA_S16,
	EV3_UART_DATA_S32,
	EV3_UART_DATA_FLOAT,
};

/**
 * struct ev3_uart_mode - one mode as the sensor described it
 * @name: NUL-terminated mode name, e.g. "COL-REFLECT"
 * @units: NUL-terminated unit symbol, e.g. "pct"; empty if none was sent
 * @raw_min: lowest raw value, rounded to an integer
 * @raw_max: highest raw value, rounded to an integer
 * @pct_min: percent value at @raw_min
 * @pct_max: percent value at @raw_max
 * @si_min: SI value at @raw_min, times 10^@decimals
 * @si_max: SI value at @raw_max, times 10^@decimals
 * @num_values: number of values in a DATA message of this mode
 * @data_type: an &enum ev3_uart_data_type
 * @figures: digits to show, including the decimals
 * @decimals: decimals of the SI value (and of float values)
 * @mapping_in: Powered Up MAPPING INFO, input flags (0 if none was sent)
 * @mapping_out: Powered Up MAPPING INFO, output flags; non-zero if the mode
 *	takes values from the host
 * @flags: Powered Up capability flags sent after a short NAME (all 0 if
 *	none were sent); bits 6 and 7 of @flags[0] ask for battery power on
 *	pin 1 or 2
 */
struct ev3_uart_mode {
	char name[EV3_UART_NAME_LEN + 1];
	char units[EV3_UART_UNITS_LEN + 1];
	s32 raw_min;
	s32 raw_max;
	s32 pct_min;
	s32 pct_max;
	s32 si_min;
	s32 si_max;
	u8 num_values;
	u8 data_type;
	u8 figures;
	u8 decimals;
	u8 mapping_in;
	u8 mapping_out;
	u8 flags[EV3_UART_NAME_FLAGS];
};

/**
 * struct ev3_uart_sensor - what a sensor said about itself in its handshake
 * @type: the sensor type id (29 colour, 30 ultrasonic, 32 gyro, 33 infrared)
 * @num_modes: number of modes, 1 to 8 (EV3), 1 to 16 (Powered Up)
 * @num_view_modes: number of modes meant to be shown to users
 * @lump: the device spoke the Powered Up extensions of the protocol (a
 *	4-byte MODES, VERSION, INFO types 0x05 to 0x0c, the mode-plus-8 flag
 *	or NAME flags): in the data phase it may send EXT_MODE
 * @num_combos: number of mode combinations in @combos
 * @speed: the baud rate to use after the handshake
 * @fw_version: Powered Up firmware version (BCD), 0 if not sent
 * @hw_version: Powered Up hardware version (BCD), 0 if not sent
 * @combos: Powered Up MODE_COMBOS: bitmaps of modes that can be combined
 * @modes: the modes, indexed by mode number
 */
struct ev3_uart_sensor {
	u8 type;
	u8 num_modes;
	u8 num_view_modes;
	bool lump;
	u8 num_combos;
	u32 speed;
	u32 fw_version;
	u32 hw_version;
	u16 combos[EV3_UART_MAX_COMBOS];
	struct ev3_uart_mode modes[EV3_UART_MAX_MODES];
};

/**
 * enum ev3_uart_state - where the parser is in the life of a connection
 * @EV3_UART_STATE_SYNC: at 2400 baud, hunting for a TYPE message
 * @EV3_UART_STATE_INFO: receiving the handshake (mode descriptions)
 * @EV3_UART_STATE_ACKED: the sensor sent ACK; the host must answer ACK and
 *	switch speed, then call ev3_uart_parser_start_data(). Bytes received
 *	meanwhile are dropped: they come at a speed the tty is not set to.
 * @EV3_UART_STATE_DATA: data phase, at the sensor's speed
 * @EV3_UART_STATE_PROBE: the host sent SPEED at &ev3_uart_parser.sync_speed
 *	(the fast sync probe) and waits for a Powered Up device's ACK; the
 *	TYPE hunt at 2400 goes on meanwhile, line errors are dropped. The ACK
 *	makes it SYNC at that speed; a TYPE makes it INFO at 2400 (a sensor
 *	that talks at 2400, on a line with no speeds such as a pty); neither,
 *	ev3_uart_parser_probe_end() makes it SYNC at 2400.
 */
enum ev3_uart_state {
	EV3_UART_STATE_SYNC,
	EV3_UART_STATE_INFO,
	EV3_UART_STATE_ACKED,
	EV3_UART_STATE_DATA,
	EV3_UART_STATE_PROBE,
};

/**
 * enum ev3_uart_event_type - what the caller must act on after a feed
 * @EV3_UART_EV_NONE: nothing (all bytes consumed)
 * @EV3_UART_EV_SYNC: a TYPE message started a handshake
 * @EV3_UART_EV_HANDSHAKE: the sensor sent ACK after a valid handshake: the
 *	description is ev3_uart_parser_sensor()'s; answer ACK, switch speed
 * @EV3_UART_EV_DATA: a DATA message for the current mode; its payload is in
 *	ev3_uart_parser_data()
 * @EV3_UART_EV_ERROR: a protocol error; the parser is back in SYNC state and
 *	the caller must go back to 2400 baud
 * @EV3_UART_EV_MSG: a handshake message (CMD or INFO) was taken; only with
 *	ev3_uart_parser_report_msgs() on (for tracing): nothing to act on
 * @EV3_UART_EV_FAST: a device answered the SPEED probe with ACK: the line
 *	stays at &ev3_uart_parser.sync_speed, where the parser now hunts for
 *	its TYPE message (SYNC state)
 */
enum ev3_uart_event_type {
	EV3_UART_EV_NONE,
	EV3_UART_EV_SYNC,
	EV3_UART_EV_HANDSHAKE,
	EV3_UART_EV_DATA,
	EV3_UART_EV_ERROR,
	EV3_UART_EV_MSG,
	EV3_UART_EV_FAST,
};

/**
 * struct ev3_uart_event - one event returned by ev3_uart_parser_feed()
 * @type: what happened
 * @mode: for %EV3_UART_EV_DATA, the mode the values belong to (0 to 15);
 *	for %EV3_UART_EV_MSG, the message's header
 * @mode_changed: for %EV3_UART_EV_DATA, this DATA confirmed a SELECT
 * @us_dc_in: for %EV3_UART_EV_DATA, the message was tagged mode 5 and taken
 *	as mode 6 (the ultrasonic sensor's US-DC-IN quirk, ev3_uart_data_msg())
 * @len: for %EV3_UART_EV_DATA, the payload length in bytes; for
 *	%EV3_UART_EV_MSG, the whole message's
 * @reason: for %EV3_UART_EV_ERROR, a static string saying what was wrong
 */
struct ev3_uart_event {
	enum ev3_uart_event_type type;
	u8 mode;
	bool mode_changed;
	bool us_dc_in;
	u8 len;
	const char *reason;
};

/**
 * struct ev3_uart_parser - state of the protocol on one line
 *
 * Its fields are the parser's own: ev3_uart_proto.c alone reads or writes
 * them (and its KUnit suite); the port asks the questions below.
 *
 * @state: see &enum ev3_uart_state
 * @sync_speed: the speed the line runs at in the SYNC, PROBE and INFO
 *	states: %EV3_UART_SPEED_MIN, or the probe's (after the device
 *	answered it, until the parser restarts); a handshake without SPEED
 *	asks for it
 * @sensor: the sensor description, complete from %EV3_UART_EV_HANDSHAKE on
 * @msg: the message being received (in SYNC state: the sliding window)
 * @msg_len: bytes held in @msg
 * @msg_size: in the INFO and DATA states, the length of the message in @msg
 *	(from its header), once it has one
 * @replay: bytes to parse again before new input (after a data-phase resync)
 * @replay_len: bytes held in @replay
 * @replay_pos: next byte of @replay to parse
 * @cmd_seen: bitmap of the commands seen in this handshake
 * @info_mode: the mode being described (after its NAME), or %EV3_UART_NO_MODE
 * @info_seen: bitmap of the INFO types seen for @info_mode
 * @modes_done: bitmap of the modes whose FORMAT was received
 * @ext_mode: in the data phase, what the last EXT_MODE message (Powered Up)
 *	adds to the mode of a DATA header: 0 or 8
 * @stash: the RAW, PCT and SI ranges of @info_mode as sent (f32 bit patterns)
 * @mode: the sensor's current mode in the data phase
 * @pending_mode: the mode a SELECT asked for, or %EV3_UART_NO_MODE
 * @select_ticks: keep-alive ticks since @pending_mode was set (at most 255)
 * @data_err: bad frames, less good ones (never below 0)
 * @silent_ticks: keep-alive periods in a row without a good DATA message
 * @data_since_tick: a good DATA message arrived since the last tick
 * @data: payload of the last DATA message delivered
 * @frames: good DATA messages since the last handshake
 * @bad_frames: DATA messages dropped (checksum, size or mode)
 * @garbage: bytes dropped while hunting for a message
 * @report_msgs: return %EV3_UART_EV_MSG for each handshake message taken
 *	(set by the caller, for tracing; cleared by ev3_uart_parser_init())
 * @msg_info: for %EV3_UART_EV_MSG, the INFO type of an INFO message (0 for
 *	a CMD)
 */
struct ev3_uart_parser {
	enum ev3_uart_state state;
	u32 sync_speed;
	struct ev3_uart_sensor sensor;
	u8 msg[EV3_UART_MAX_MSG_LEN];
	u8 msg_len;
	u8 msg_size;
	u8 replay[EV3_UART_MAX_MSG_LEN];
	u8 replay_len;
	u8 replay_pos;
	u8 cmd_seen;
	u8 info_mode;
	u8 info_seen;
	u16 modes_done;
	u8 ext_mode;
	u32 stash[3][2];
	u8 mode;
	u8 pending_mode;
	u8 select_ticks;
	u8 data_err;
	u8 silent_ticks;
	bool data_since_tick;
	u8 data[EV3_UART_MAX_PAYLOAD];
	unsigned long frames;
	unsigned long bad_frames;
	unsigned long garbage;
	bool report_msgs;
	u8 msg_info;
};

/* What the port may ask the parser (its lock held, as for a feed). */

/* The state, for traces and statistics (&enum ev3_uart_state). */
static inline u8 ev3_uart_parser_state(const struct ev3_uart_parser *p)
{
	return p->state;
}

/* Hunting for a TYPE message. */
static inline bool ev3_uart_parser_syncing(const struct ev3_uart_parser *p)
{
	return p->state == EV3_UART_STATE_SYNC;
}

/* A sensor sent its handshake and ACK: ours is due (%EV3_UART_EV_HANDSHAKE). */
static inline bool ev3_uart_parser_acked(const struct ev3_uart_parser *p)
{
	return p->state == EV3_UART_STATE_ACKED;
}

/* In the data phase. */
static inline bool ev3_uart_parser_in_data(const struct ev3_uart_parser *p)
{
	return p->state == EV3_UART_STATE_DATA;
}

/* A device answered the fast sync probe; its handshake is yet to end. */
static inline bool ev3_uart_parser_fast_handshake(const struct ev3_uart_parser *p)
{
	return p->sync_speed != EV3_UART_SPEED_MIN &&
	       (p->state == EV3_UART_STATE_SYNC || p->state == EV3_UART_STATE_INFO);
}

/* The sensor's description, complete from %EV3_UART_EV_HANDSHAKE on. */
static inline const struct ev3_uart_sensor *
ev3_uart_parser_sensor(const struct ev3_uart_parser *p)
{
	return &p->sensor;
}

/* The payload of the DATA message of the last %EV3_UART_EV_DATA. */
static inline const u8 *ev3_uart_parser_data(const struct ev3_uart_parser *p)
{
	return p->data;
}

/* The mode a SELECT asked for and no DATA confirmed yet, or %EV3_UART_NO_MODE. */
static inline u8 ev3_uart_parser_pending(const struct ev3_uart_parser *p)
{
	return p->pending_mode;
}

/* For %EV3_UART_EV_MSG: the INFO type of an INFO message, 0 for a CMD. */
static inline u8 ev3_uart_parser_msg_info(const struct ev3_uart_parser *p)
{
	return p->msg_info;
}

/* Whether to return %EV3_UART_EV_MSG for each handshake message (tracing). */
static inline void ev3_uart_parser_report_msgs(struct ev3_uart_parser *p, bool on)
{
	p->report_msgs = on;
}

/* Bytes dropped while hunting for a message, since the parser's init. */
static inline unsigned long ev3_uart_parser_garbage(const struct ev3_uart_parser *p)
{
	return p->garbage;
}

/* DATA messages dropped (checksum, size or mode), since the parser's init. */
static inline unsigned long ev3_uart_parser_bad_frames(const struct ev3_uart_parser *p)
{
	return p->bad_frames;
}

/*
 * Back-off of a device that keeps failing (ev3_uart_backoff_lost()): a
 * sensor lost less than EV3_UART_SHORT_LIFE_MS after it was registered
 * failed (an unplugged one lives longer: silence takes 700 ms to be
 * noticed); after EV3_UART_FREE_RETRIES failures in a row, its next
 * handshakes are left unanswered for EV3_UART_BACKOFF_MIN_MS, doubled at
 * every failure up to EV3_UART_BACKOFF_MAX_MS.
 */
#define EV3_UART_SHORT_LIFE_MS		500
#define EV3_UART_FREE_RETRIES		3
#define EV3_UART_BACKOFF_MIN_MS		1000
#define EV3_UART_BACKOFF_MAX_SHIFT	5
#define EV3_UART_BACKOFF_MAX_MS		(EV3_UART_BACKOFF_MIN_MS << EV3_UART_BACKOFF_MAX_SHIFT)

/**
 * struct ev3_uart_backoff - how a line's sensors have been failing
 * @failures: sensors in a row lost soon after they were registered
 */
struct ev3_uart_backoff {
	unsigned int failures;
};

u8 ev3_uart_checksum(const u8 *msg, size_t len);
unsigned int ev3_uart_payload_len(u8 hdr);
unsigned int ev3_uart_msg_len(u8 hdr);
unsigned int ev3_uart_data_size(enum ev3_uart_data_type type);
s64 ev3_uart_msg_time(s64 now, size_t rest, unsigned int msg_len, u32 speed,
		      s64 last);

void ev3_uart_parser_init(struct ev3_uart_parser *p);
size_t ev3_uart_parser_feed(struct ev3_uart_parser *p, const u8 *buf,
			    size_t len, struct ev3_uart_event *ev);
void ev3_uart_parser_line_error(struct ev3_uart_parser *p,
				struct ev3_uart_event *ev);
void ev3_uart_parser_start_data(struct ev3_uart_parser *p);
int ev3_uart_parser_select(struct ev3_uart_parser *p, u8 mode);
int ev3_uart_parser_probe(struct ev3_uart_parser *p, u32 speed);
u32 ev3_uart_parser_probe_end(struct ev3_uart_parser *p);
bool ev3_uart_parser_tick(struct ev3_uart_parser *p, struct ev3_uart_event *ev);
unsigned int ev3_uart_backoff_lost(struct ev3_uart_backoff *b,
				   unsigned int lived_ms);

size_t ev3_uart_build_ack(u8 *buf);
size_t ev3_uart_build_nack(u8 *buf);
size_t ev3_uart_build_select(u8 *buf, u8 mode);
size_t ev3_uart_build_speed(u8 *buf, u32 speed);
int ev3_uart_build_write(u8 *buf, const u8 *data, size_t len);
int ev3_uart_build_lump_data(u8 *buf, u8 mode, const u8 *data, size_t len);

/* Powered Up lights: at most this many in a "LIGHT" mode (ev3_uart_lump_lights()). */
#define EV3_UART_MAX_LIGHTS		8
/* A light's brightness, in percent (the values of a "LIGHT" mode). */
#define EV3_UART_LIGHT_MAX		100
int ev3_uart_lump_data_len(const struct ev3_uart_sensor *s, u8 mode);
unsigned int ev3_uart_lump_lights(const struct ev3_uart_sensor *s, u8 *mode);
int ev3_uart_pack_values(const struct ev3_uart_sensor *s, u8 mode,
			 const s32 *v, unsigned int n, u8 *buf);

/*
 * Powered Up combined modes ("combi modes"): values of several modes in
 * one DATA message. The host sets one up with a WRITE whose payload is
 * EV3_UART_COMBO_CMD plus the number of entries, the index of the
 * combination in the device's MODE_COMBOS, then one byte per entry: the
 * mode in the high nibble, the value's index in that mode ("dataset") in
 * the low one. See Documentation/lego/ev3-uart.rst for the sources.
 */
#define EV3_UART_COMBO_CMD		0x20
#define EV3_UART_MAX_COMBO_ENTRIES	8
/* The WRITE of a combination: header, 2 + 8 bytes padded to 16, checksum. */
#define EV3_UART_COMBO_MSG_LEN		18

/**
 * struct ev3_uart_combo_entry - one value of a combined mode
 * @mode: the mode it belongs to
 * @index: which value of that mode (the "dataset")
 */
struct ev3_uart_combo_entry {
	u8 mode;
	u8 index;
};

int ev3_uart_combo_find(const struct ev3_uart_sensor *s,
			const struct ev3_uart_combo_entry *e, unsigned int n,
			unsigned int *len);
int ev3_uart_combo_offset(const struct ev3_uart_sensor *s,
			  const struct ev3_uart_combo_entry *e, unsigned int n,
			  unsigned int j);
int ev3_uart_build_combo(u8 *buf, u8 combo,
			 const struct ev3_uart_combo_entry *e, unsigned int n);

int ev3_uart_f32_to_fixed(u32 bits, unsigned int decimals, s32 *out);
int ev3_uart_read_value(const struct ev3_uart_mode *mode, const u8 *data,
			size_t len, unsigned int index, s32 *out);
/* |@v| as a u64, exact for S64_MIN too. */
static inline u64 ev3_uart_abs64(s64 v)
{
	return v < 0 ? -(u64)v : (u64)v;
}

int ev3_uart_mul_div(u64 a, u64 b, u64 c, bool round, u64 *q);
s32 ev3_uart_scale_value(const struct ev3_uart_mode *mode, s32 raw);
/*
 * Room for a driver name with its NUL: the longest in the tables
 * ("lego-technic-m-angular-motor") and "lump-uart-255" (a KUnit case checks).
 */
#define EV3_UART_DRIVER_NAME_LEN	32
const char *ev3_uart_driver_name(u8 type);
const char *ev3_uart_lump_driver_name(u8 type);

#endif /* _EV3_UART_PROTO_H */
