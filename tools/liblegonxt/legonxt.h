/* SPDX-License-Identifier: LGPL-2.1-or-later */
/*
 * liblegonxt: the LEGO MINDSTORMS NXT brick's direct and system commands,
 * encoded and decoded in userspace.
 *
 * The kernel's /dev/nxtN carries telegrams (write()/read(), or
 * NXT_IOC_TRANSACT for a telegram and its reply in one call); what a
 * telegram means is this library's: a builder per command checks its
 * arguments against the firmware's limits and writes the telegram,
 * lnxt_reply_check() tells whether a reply answers it and returns the
 * brick's status byte, and a parser per reply turns its bytes into a
 * structure. lnxt_status_name() names the brick's status codes.
 *
 * Builders return 0, or -EINVAL for an argument out of the firmware's
 * range. Every telegram asks for a reply; lnxt_no_reply() clears that
 * (the brick then acts and answers nothing). Multi-byte fields are
 * little-endian on the wire and host order in the structures.
 */
#ifndef LEGONXT_H
#define LEGONXT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** LNXT_TELEGRAM_MAX - the longest telegram or reply, type byte included */
#define LNXT_TELEGRAM_MAX	64
/** LNXT_NAME_MAX - the longest file or program name, without its NUL */
#define LNXT_NAME_MAX		19
/** LNXT_BRICK_NAME_MAX - the longest brick name, without its NUL */
#define LNXT_BRICK_NAME_MAX	15
/** LNXT_MESSAGE_MAX - the longest mailbox message, without its NUL */
#define LNXT_MESSAGE_MAX	58
/** LNXT_LS_MAX - the most bytes one low-speed (I2C) write sends or reads */
#define LNXT_LS_MAX		16
/** LNXT_READ_MAX - the most data bytes one Read returns over USB */
#define LNXT_READ_MAX		58
/** LNXT_WRITE_MAX - the most data bytes one Write carries */
#define LNXT_WRITE_MAX		61
/** LNXT_IOMAP_MAX - the most bytes one ReadIOMap returns over USB */
#define LNXT_IOMAP_MAX		55
/** LNXT_IOMAP_WRITE_MAX - the most bytes one WriteIOMap carries */
#define LNXT_IOMAP_WRITE_MAX	54
/** LNXT_POLL_MAX - the most bytes one PollCommand returns over USB */
#define LNXT_POLL_MAX		59
/** LNXT_PORT_ALL - every output port, for SetOutputState */
#define LNXT_PORT_ALL		0xff

/* The type byte. */
#define LNXT_DIRECT		0x00
#define LNXT_SYSTEM		0x01
#define LNXT_REPLY		0x02
#define LNXT_NO_REPLY		0x80

/** enum lnxt_op - the opcodes: direct commands below 0x80, system at and above */
enum lnxt_op {
	LNXT_START_PROGRAM		= 0x00,
	LNXT_STOP_PROGRAM		= 0x01,
	LNXT_PLAY_SOUND_FILE		= 0x02,
	LNXT_PLAY_TONE			= 0x03,
	LNXT_SET_OUTPUT_STATE		= 0x04,
	LNXT_SET_INPUT_MODE		= 0x05,
	LNXT_GET_OUTPUT_STATE		= 0x06,
	LNXT_GET_INPUT_VALUES		= 0x07,
	LNXT_RESET_INPUT_SCALED_VALUE	= 0x08,
	LNXT_MESSAGE_WRITE		= 0x09,
	LNXT_RESET_MOTOR_POSITION	= 0x0a,
	LNXT_GET_BATTERY_LEVEL		= 0x0b,
	LNXT_STOP_SOUND_PLAYBACK	= 0x0c,
	LNXT_KEEP_ALIVE			= 0x0d,
	LNXT_LS_GET_STATUS		= 0x0e,
	LNXT_LS_WRITE			= 0x0f,
	LNXT_LS_READ			= 0x10,
	LNXT_GET_CURRENT_PROGRAM_NAME	= 0x11,
	LNXT_MESSAGE_READ		= 0x13,
	LNXT_DATALOG_READ		= 0x19,	/* firmware 1.28 on */
	LNXT_DATALOG_SET_TIMES		= 0x1a,
	LNXT_BT_GET_CONTACT_COUNT	= 0x1b,
	LNXT_BT_GET_CONTACT_NAME	= 0x1c,
	LNXT_BT_GET_CONN_COUNT		= 0x1d,
	LNXT_BT_GET_CONN_NAME		= 0x1e,
	LNXT_SET_PROPERTY		= 0x1f,
	LNXT_GET_PROPERTY		= 0x20,
	LNXT_UPDATE_RESET_COUNT		= 0x21,

	LNXT_OPEN_READ			= 0x80,
	LNXT_OPEN_WRITE			= 0x81,
	LNXT_READ			= 0x82,
	LNXT_WRITE			= 0x83,
	LNXT_CLOSE			= 0x84,
	LNXT_DELETE			= 0x85,
	LNXT_FIND_FIRST			= 0x86,
	LNXT_FIND_NEXT			= 0x87,
	LNXT_GET_VERSIONS		= 0x88,
	LNXT_OPEN_WRITE_LINEAR		= 0x89,
	LNXT_OPEN_WRITE_DATA		= 0x8b,
	LNXT_OPEN_APPEND_DATA		= 0x8c,
	LNXT_CROP_DATA_FILE		= 0x8d,	/* firmware 1.28 on */
	LNXT_FIND_FIRST_MODULE		= 0x90,
	LNXT_FIND_NEXT_MODULE		= 0x91,
	LNXT_CLOSE_MODULE_HANDLE	= 0x92,
	LNXT_READ_IO_MAP		= 0x94,
	LNXT_WRITE_IO_MAP		= 0x95,
	LNXT_BOOT_COMMAND		= 0x97,
	LNXT_SET_BRICK_NAME		= 0x98,
	LNXT_GET_BT_ADDRESS		= 0x9a,
	LNXT_GET_DEVICE_INFO		= 0x9b,
	LNXT_DELETE_USER_FLASH		= 0xa0,
	LNXT_POLL_COMMAND_LENGTH	= 0xa1,
	LNXT_POLL_COMMAND		= 0xa2,
	LNXT_BT_FACTORY_RESET		= 0xa4,
};

/* struct lnxt_output's mode bits, regulation and run states. */
#define LNXT_MODE_MOTORON	0x01
#define LNXT_MODE_BRAKE		0x02
#define LNXT_MODE_REGULATED	0x04
#define LNXT_REGULATION_IDLE	0
#define LNXT_REGULATION_SPEED	1
#define LNXT_REGULATION_SYNC	2
#define LNXT_RUN_IDLE		0x00
#define LNXT_RUN_RAMPUP		0x10
#define LNXT_RUN_RUNNING	0x20
#define LNXT_RUN_RAMPDOWN	0x40

/** enum lnxt_sensor_type - SetInputMode's sensor types */
enum lnxt_sensor_type {
	LNXT_SENSOR_NONE		= 0x00,
	LNXT_SENSOR_SWITCH		= 0x01,
	LNXT_SENSOR_TEMPERATURE		= 0x02,
	LNXT_SENSOR_REFLECTION		= 0x03,
	LNXT_SENSOR_ANGLE		= 0x04,
	LNXT_SENSOR_LIGHT_ACTIVE	= 0x05,
	LNXT_SENSOR_LIGHT_INACTIVE	= 0x06,
	LNXT_SENSOR_SOUND_DB		= 0x07,
	LNXT_SENSOR_SOUND_DBA		= 0x08,
	LNXT_SENSOR_CUSTOM		= 0x09,
	LNXT_SENSOR_LOWSPEED		= 0x0a,
	LNXT_SENSOR_LOWSPEED_9V		= 0x0b,
	LNXT_SENSOR_TYPES		= 0x0c,
};

/*
 * SetInputMode's sensor modes: the top three bits; the low five are the
 * slope of the transition and period counts.
 */
#define LNXT_SENSOR_MODE_RAW		0x00
#define LNXT_SENSOR_MODE_BOOLEAN	0x20
#define LNXT_SENSOR_MODE_TRANSITIONS	0x40
#define LNXT_SENSOR_MODE_PERIODS	0x60
#define LNXT_SENSOR_MODE_PERCENT	0x80
#define LNXT_SENSOR_MODE_CELSIUS	0xa0
#define LNXT_SENSOR_MODE_FAHRENHEIT	0xc0
#define LNXT_SENSOR_MODE_ANGLE_STEPS	0xe0
#define LNXT_SENSOR_SLOPE_MASK		0x1f

/* The brick's status bytes that callers test for. */
#define LNXT_STATUS_PENDING		0x20	/* an I2C transaction still runs */
#define LNXT_STATUS_MAILBOX_EMPTY	0x40
#define LNXT_STATUS_FILE_NOT_FOUND	0x87
#define LNXT_STATUS_FILE_EXISTS		0x8f
#define LNXT_STATUS_OUT_OF_RANGE	0xc0
#define LNXT_STATUS_CHANNEL_BUSY	0xe0	/* the I2C port is not ready */
#define LNXT_STATUS_NO_PROGRAM		0xec

/** enum lnxt_property - SetProperty and GetProperty */
enum lnxt_property {
	LNXT_PROP_BT_ON		= 0,	/* u8 */
	LNXT_PROP_VOLUME	= 1,	/* u8, 0 to 4 */
	LNXT_PROP_SLEEP_MS	= 2,	/* u32 */
};

/**
 * struct lnxt_msg - a telegram to send
 * @len: its length, 2 to LNXT_TELEGRAM_MAX
 * @buf: its bytes: type, opcode, arguments
 */
struct lnxt_msg {
	size_t len;
	uint8_t buf[LNXT_TELEGRAM_MAX];
};

/**
 * struct lnxt_output - SetOutputState's arguments, GetOutputState's reply
 * @port: 0 to 2 (A to C); SetOutputState also takes LNXT_PORT_ALL
 * @power: -100 to 100
 * @mode: bits: 0x01 motor on, 0x02 brake, 0x04 regulated
 * @regulation: 0 idle, 1 motor speed, 2 motor sync
 * @turn: turn ratio, -100 to 100
 * @run_state: 0x00 idle, 0x10 ramp up, 0x20 running, 0x40 ramp down
 * @tacho_limit: degrees to turn, 0 for no limit
 * @tacho_count: reply only: degrees since the last reset of the limit
 * @block_tacho_count: reply only: degrees since the last relative reset
 * @rotation_count: reply only: degrees since the last absolute reset
 */
struct lnxt_output {
	uint8_t port;
	int8_t power;
	uint8_t mode;
	uint8_t regulation;
	int8_t turn;
	uint8_t run_state;
	uint32_t tacho_limit;
	int32_t tacho_count;
	int32_t block_tacho_count;
	int32_t rotation_count;
};

/**
 * struct lnxt_input - GetInputValues' reply
 * @port: 0 to 3 (S1 to S4)
 * @valid: the value was read since the type or mode was set
 * @calibrated: whether a calibration file applies (always 0 on LEGO's firmware)
 * @type: the sensor type SetInputMode set
 * @mode: the sensor mode SetInputMode set
 * @raw: the A/D value, 0 to 1023
 * @normalized: the normalized value
 * @scaled: the value in the mode's unit
 * @calibrated_value: the calibrated value
 */
struct lnxt_input {
	uint8_t port;
	bool valid;
	bool calibrated;
	uint8_t type;
	uint8_t mode;
	uint16_t raw;
	uint16_t normalized;
	int16_t scaled;
	int16_t calibrated_value;
};

/**
 * struct lnxt_file - a file handle and size (OpenRead, FindFirst, FindNext,
 * OpenAppendData: @size is the room left)
 * @handle: the brick's handle
 * @name: the file name (FindFirst and FindNext only), NUL-terminated
 * @size: the size in bytes
 */
struct lnxt_file {
	uint8_t handle;
	char name[LNXT_NAME_MAX + 1];
	uint32_t size;
};

/**
 * struct lnxt_module - FindFirstModule and FindNextModule's reply
 * @handle: the brick's handle
 * @name: the module's name, NUL-terminated
 * @id: the module's ID, for ReadIOMap and WriteIOMap
 * @size: the module's size
 * @iomap_size: the size of its I/O map
 */
struct lnxt_module {
	uint8_t handle;
	char name[LNXT_NAME_MAX + 1];
	uint32_t id;
	uint32_t size;
	uint16_t iomap_size;
};

/**
 * struct lnxt_versions - GetVersions' reply
 * @protocol_major: the protocol's version
 * @protocol_minor: the protocol's version
 * @firmware_major: the firmware's version (1.29: 1 and 29)
 * @firmware_minor: the firmware's version
 */
struct lnxt_versions {
	uint8_t protocol_major;
	uint8_t protocol_minor;
	uint8_t firmware_major;
	uint8_t firmware_minor;
};

/**
 * struct lnxt_device_info - GetDeviceInfo's reply
 * @name: the brick's name, NUL-terminated
 * @bt_address: its Bluetooth address
 * @link_quality: the Bluetooth link quality (0 on LEGO's firmware)
 * @free_flash: the free user flash in bytes
 */
struct lnxt_device_info {
	char name[LNXT_BRICK_NAME_MAX + 1];
	uint8_t bt_address[6];
	uint32_t link_quality;
	uint32_t free_flash;
};

/**
 * struct lnxt_data - a reply that carries bytes
 * @handle: the handle, inbox, port or buffer the bytes came from
 * @len: how many bytes of @data the reply says are valid
 * @data: the bytes
 * @id: ReadIOMap: the module's ID
 */
struct lnxt_data {
	uint8_t handle;
	size_t len;
	uint8_t data[LNXT_TELEGRAM_MAX];
	uint32_t id;
};

/* Direct commands. */
int lnxt_start_program(struct lnxt_msg *m, const char *name);
void lnxt_stop_program(struct lnxt_msg *m);
int lnxt_play_sound_file(struct lnxt_msg *m, bool loop, const char *name);
void lnxt_play_tone(struct lnxt_msg *m, uint16_t hz, uint16_t ms);
int lnxt_set_output_state(struct lnxt_msg *m, const struct lnxt_output *o);
int lnxt_set_input_mode(struct lnxt_msg *m, unsigned int port, uint8_t type, uint8_t mode);
int lnxt_get_output_state(struct lnxt_msg *m, unsigned int port);
int lnxt_get_input_values(struct lnxt_msg *m, unsigned int port);
int lnxt_reset_input_scaled_value(struct lnxt_msg *m, unsigned int port);
int lnxt_message_write(struct lnxt_msg *m, unsigned int inbox, const void *data, size_t len);
int lnxt_reset_motor_position(struct lnxt_msg *m, unsigned int port, bool relative);
void lnxt_get_battery_level(struct lnxt_msg *m);
void lnxt_stop_sound_playback(struct lnxt_msg *m);
void lnxt_keep_alive(struct lnxt_msg *m);
int lnxt_ls_get_status(struct lnxt_msg *m, unsigned int port);
int lnxt_ls_write(struct lnxt_msg *m, unsigned int port, const void *tx, size_t tx_len,
		  size_t rx_len);
int lnxt_ls_read(struct lnxt_msg *m, unsigned int port);
void lnxt_get_current_program_name(struct lnxt_msg *m);
int lnxt_message_read(struct lnxt_msg *m, unsigned int remote, unsigned int local, bool remove);
void lnxt_datalog_read(struct lnxt_msg *m, bool remove);
void lnxt_datalog_set_times(struct lnxt_msg *m, uint32_t sync_time);
void lnxt_bt_get_contact_count(struct lnxt_msg *m);
void lnxt_bt_get_contact_name(struct lnxt_msg *m, uint8_t index);
void lnxt_bt_get_conn_count(struct lnxt_msg *m);
void lnxt_bt_get_conn_name(struct lnxt_msg *m, uint8_t index);
int lnxt_set_property(struct lnxt_msg *m, enum lnxt_property prop, uint32_t value);
int lnxt_get_property(struct lnxt_msg *m, enum lnxt_property prop);
int lnxt_update_reset_count(struct lnxt_msg *m, unsigned int port);

/* System commands. */
int lnxt_open_read(struct lnxt_msg *m, const char *name);
int lnxt_open_write(struct lnxt_msg *m, const char *name, uint32_t size);
int lnxt_read(struct lnxt_msg *m, uint8_t handle, size_t n);
int lnxt_write(struct lnxt_msg *m, uint8_t handle, const void *data, size_t len);
void lnxt_close(struct lnxt_msg *m, uint8_t handle);
int lnxt_delete(struct lnxt_msg *m, const char *name);
int lnxt_find_first(struct lnxt_msg *m, const char *pattern);
void lnxt_find_next(struct lnxt_msg *m, uint8_t handle);
void lnxt_get_versions(struct lnxt_msg *m);
int lnxt_open_write_linear(struct lnxt_msg *m, const char *name, uint32_t size);
int lnxt_open_write_data(struct lnxt_msg *m, const char *name, uint32_t size);
int lnxt_open_append_data(struct lnxt_msg *m, const char *name);
void lnxt_crop_data_file(struct lnxt_msg *m, uint8_t handle);
int lnxt_find_first_module(struct lnxt_msg *m, const char *pattern);
void lnxt_find_next_module(struct lnxt_msg *m, uint8_t handle);
void lnxt_close_module_handle(struct lnxt_msg *m, uint8_t handle);
int lnxt_read_io_map(struct lnxt_msg *m, uint32_t id, uint16_t offset, size_t n);
int lnxt_write_io_map(struct lnxt_msg *m, uint32_t id, uint16_t offset, const void *data,
		      size_t len);
void lnxt_boot_command(struct lnxt_msg *m);
int lnxt_set_brick_name(struct lnxt_msg *m, const char *name);
void lnxt_get_bt_address(struct lnxt_msg *m);
void lnxt_get_device_info(struct lnxt_msg *m);
void lnxt_delete_user_flash(struct lnxt_msg *m);
void lnxt_poll_command_length(struct lnxt_msg *m, uint8_t buffer);
int lnxt_poll_command(struct lnxt_msg *m, uint8_t buffer, size_t n);
void lnxt_bt_factory_reset(struct lnxt_msg *m);

/** lnxt_no_reply() - make @m a telegram the brick answers with nothing */
void lnxt_no_reply(struct lnxt_msg *m);
/** lnxt_wants_reply() - whether the brick answers @m */
bool lnxt_wants_reply(const struct lnxt_msg *m);

/**
 * lnxt_reply_len() - the length of the reply to @m when its status is 0
 * Return: 3 to LNXT_TELEGRAM_MAX, or 0 for an opcode this library does not know.
 */
size_t lnxt_reply_len(const struct lnxt_msg *m);

/**
 * lnxt_reply_check() - whether @reply (@len bytes) answers @m
 *
 * A reply is type 0x02, @m's opcode and the brick's status, then the
 * command's fields: as long as lnxt_reply_len() says, or only those three
 * bytes when the status is not 0 (an unknown opcode, a bad port).
 *
 * Return: the status byte (0 for success), or -EBADMSG.
 */
int lnxt_reply_check(const struct lnxt_msg *m, const uint8_t *reply, size_t len);

/**
 * lnxt_status_name() - what the brick's status byte @status means
 * Return: a text such as "no active program", or NULL for a code the
 * firmware does not define.
 */
const char *lnxt_status_name(uint8_t status);

/*
 * Parsers of a reply that lnxt_reply_check() accepted with status 0: each
 * returns 0, or -EBADMSG when @reply is not a whole reply of its command.
 */
int lnxt_parse_output_state(const uint8_t *reply, size_t len, struct lnxt_output *o);
int lnxt_parse_input_values(const uint8_t *reply, size_t len, struct lnxt_input *in);
int lnxt_parse_battery_level(const uint8_t *reply, size_t len, uint16_t *mv);
int lnxt_parse_keep_alive(const uint8_t *reply, size_t len, uint32_t *sleep_ms);
int lnxt_parse_ls_get_status(const uint8_t *reply, size_t len, uint8_t *ready);
int lnxt_parse_ls_read(const uint8_t *reply, size_t len, struct lnxt_data *d);
int lnxt_parse_program_name(const uint8_t *reply, size_t len, char name[LNXT_NAME_MAX + 1]);
int lnxt_parse_message_read(const uint8_t *reply, size_t len, struct lnxt_data *d);
int lnxt_parse_datalog_read(const uint8_t *reply, size_t len, struct lnxt_data *d);
int lnxt_parse_bt_count(const uint8_t *reply, size_t len, uint8_t *count);
int lnxt_parse_bt_name(const uint8_t *reply, size_t len, uint8_t *type, char name[18]);
int lnxt_parse_property(const uint8_t *reply, size_t len, uint32_t *value);
int lnxt_parse_file(const uint8_t *reply, size_t len, struct lnxt_file *f);
int lnxt_parse_handle(const uint8_t *reply, size_t len, uint8_t *handle);
int lnxt_parse_read(const uint8_t *reply, size_t len, struct lnxt_data *d);
int lnxt_parse_write(const uint8_t *reply, size_t len, uint8_t *handle, uint16_t *written);
int lnxt_parse_versions(const uint8_t *reply, size_t len, struct lnxt_versions *v);
int lnxt_parse_module(const uint8_t *reply, size_t len, struct lnxt_module *mod);
int lnxt_parse_read_io_map(const uint8_t *reply, size_t len, struct lnxt_data *d);
int lnxt_parse_write_io_map(const uint8_t *reply, size_t len, uint32_t *id, uint16_t *written);
int lnxt_parse_bt_address(const uint8_t *reply, size_t len, uint8_t addr[6]);
int lnxt_parse_device_info(const uint8_t *reply, size_t len, struct lnxt_device_info *info);
int lnxt_parse_poll_length(const uint8_t *reply, size_t len, uint8_t *buffer, uint8_t *length);
int lnxt_parse_poll(const uint8_t *reply, size_t len, struct lnxt_data *d);

#ifdef __cplusplus
}
#endif

#endif /* LEGONXT_H */
