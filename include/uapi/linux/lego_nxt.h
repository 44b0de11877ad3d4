/* SPDX-License-Identifier: GPL-2.0 WITH Linux-syscall-note */
/*
 * LEGO MINDSTORMS NXT brick over USB: userspace interface of /dev/nxtN.
 *
 * A telegram is what the brick's firmware calls one command or reply: a
 * type byte, an opcode and the command's arguments, all in one USB packet.
 *
 * Three ways to talk to a brick through /dev/nxtN:
 *
 *  - write() one telegram, then read() its reply (only telegrams of type
 *    NXT_DIRECT_CMD and NXT_SYSTEM_CMD get one);
 *  - NXT_IOC_TRANSACT: one telegram and its reply in a single call;
 *  - one typed ioctl per direct command (NXT_IOC_START_PROGRAM ...
 *    NXT_IOC_MESSAGE_READ), which checks the arguments, builds the telegram,
 *    waits for the reply and decodes it.
 *
 * All three need a file opened for writing (EBADF otherwise): a file
 * opened O_RDONLY cannot make the brick act. NXT_IOC_SET_TIMEOUT and
 * NXT_IOC_GET_TIMEOUT send nothing and work on any open file.
 *
 * Every typed structure has a @status member: the brick's status byte
 * (enum nxt_status), copied back to userspace as is. When it is not
 * NXT_STATUS_SUCCESS, the ioctl still copies the structure back and then
 * fails with the errno that the status maps to (see
 * Documentation/lego/nxt-usb.rst; NXT_STATUS_PENDING is EINPROGRESS). Any
 * other error, EAGAIN included (O_NONBLOCK: the brick is busy and nothing
 * was sent), leaves the structure as it was. Members named reserved must
 * be zero.
 * All multi-byte members are in host byte order; the driver converts them
 * to and from the brick's little-endian wire format.
 */
#ifndef _UAPI_LINUX_LEGO_NXT_H
#define _UAPI_LINUX_LEGO_NXT_H

#include <linux/ioctl.h>
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

/**
 * enum nxt_direct_opcode - opcodes of the direct commands
 * @NXT_START_PROGRAM: start a program (.rxe file)
 * @NXT_STOP_PROGRAM: stop the running program
 * @NXT_PLAY_SOUND_FILE: play a sound file (.rso)
 * @NXT_PLAY_TONE: play a tone
 * @NXT_SET_OUTPUT_STATE: drive a motor
 * @NXT_SET_INPUT_MODE: set a sensor port's type and mode
 * @NXT_GET_OUTPUT_STATE: read a motor's state and counters
 * @NXT_GET_INPUT_VALUES: read a sensor port
 * @NXT_RESET_INPUT_SCALED_VALUE: reset a sensor port's scaled value
 * @NXT_MESSAGE_WRITE: put a message in one of the running program's inboxes
 * @NXT_RESET_MOTOR_POSITION: reset a motor's position counters
 * @NXT_GET_BATTERY_LEVEL: read the battery voltage
 * @NXT_STOP_SOUND_PLAYBACK: stop playing sound
 * @NXT_KEEP_ALIVE: reset the sleep timer, read the sleep limit
 * @NXT_LS_GET_STATUS: bytes ready from a low-speed (I2C) sensor
 * @NXT_LS_WRITE: start a low-speed (I2C) transaction
 * @NXT_LS_READ: read the result of a low-speed (I2C) transaction
 * @NXT_GET_CURRENT_PROGRAM_NAME: name of the running program
 * @NXT_MESSAGE_READ: take a message from one of the program's outboxes
 */
enum nxt_direct_opcode {
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

/**
 * enum nxt_status - the status byte of a reply
 * @NXT_STATUS_SUCCESS: success
 * @NXT_STATUS_PENDING: a low-speed (I2C) transaction is still in progress
 * @NXT_STATUS_MAILBOX_EMPTY: the mailbox queue is empty
 * @NXT_STATUS_NO_MORE_HANDLES: system command: no more file handles
 * @NXT_STATUS_NO_SPACE: system command: no space
 * @NXT_STATUS_NO_MORE_FILES: system command: no more files
 * @NXT_STATUS_EOF_EXPECTED: system command: end of file expected
 * @NXT_STATUS_END_OF_FILE: system command: end of file
 * @NXT_STATUS_NOT_LINEAR_FILE: system command: not a linear file
 * @NXT_STATUS_FILE_NOT_FOUND: system command: file not found
 * @NXT_STATUS_HANDLE_CLOSED: system command: handle already closed
 * @NXT_STATUS_NO_LINEAR_SPACE: system command: no linear space
 * @NXT_STATUS_UNDEFINED_ERROR: system command: undefined error
 * @NXT_STATUS_FILE_BUSY: system command: file is busy
 * @NXT_STATUS_NO_WRITE_BUFFERS: system command: no write buffers
 * @NXT_STATUS_APPEND_NOT_POSSIBLE: system command: append not possible
 * @NXT_STATUS_FILE_FULL: system command: file is full
 * @NXT_STATUS_FILE_EXISTS: system command: file exists
 * @NXT_STATUS_MODULE_NOT_FOUND: system command: module not found
 * @NXT_STATUS_OUT_OF_BOUNDS: system command: out of boundary
 * @NXT_STATUS_ILLEGAL_FILE_NAME: system command: illegal file name
 * @NXT_STATUS_ILLEGAL_HANDLE: system command: illegal handle
 * @NXT_STATUS_BT_BUSY: system command: Bluetooth busy
 * @NXT_STATUS_BT_CONNECT_FAIL: system command: Bluetooth connection failed
 * @NXT_STATUS_BT_TIMEOUT: system command: Bluetooth timeout
 * @NXT_STATUS_FILE_TX_TIMEOUT: system command: file transfer timeout
 * @NXT_STATUS_FILE_TX_DST_EXISTS: system command: destination file exists
 * @NXT_STATUS_FILE_TX_SRC_MISSING: system command: source file missing
 * @NXT_STATUS_FILE_TX_STREAM_ERROR: system command: file transfer stream error
 * @NXT_STATUS_FILE_TX_CLOSE_ERROR: system command: file transfer close error
 * @NXT_STATUS_REQUEST_FAILED: request failed (defined, never sent by LEGO's firmware)
 * @NXT_STATUS_UNKNOWN_OPCODE: unknown command opcode
 * @NXT_STATUS_INSANE_PACKET: insane packet (defined, never sent by LEGO's firmware)
 * @NXT_STATUS_OUT_OF_RANGE: data contains out-of-range values; also a
 *	missing program or sound file
 * @NXT_STATUS_BUS_ERROR: communication bus error
 * @NXT_STATUS_BUFFER_FULL: no free memory in the communication buffer
 * @NXT_STATUS_BAD_CHANNEL: the channel or connection is not valid
 * @NXT_STATUS_CHANNEL_BUSY: the channel is not configured or is busy
 * @NXT_STATUS_NO_PROGRAM: no active program
 * @NXT_STATUS_BAD_SIZE: illegal size
 * @NXT_STATUS_BAD_MAILBOX: illegal mailbox queue
 * @NXT_STATUS_BAD_FIELD: invalid field of a structure
 * @NXT_STATUS_BAD_PORT: bad input or output
 * @NXT_STATUS_NO_MEMORY: insufficient memory
 * @NXT_STATUS_BAD_ARGUMENTS: bad arguments
 */
enum nxt_status {
	NXT_STATUS_SUCCESS		= 0x00,
	NXT_STATUS_PENDING		= 0x20,
	NXT_STATUS_MAILBOX_EMPTY	= 0x40,
	NXT_STATUS_NO_MORE_HANDLES	= 0x81,
	NXT_STATUS_NO_SPACE		= 0x82,
	NXT_STATUS_NO_MORE_FILES	= 0x83,
	NXT_STATUS_EOF_EXPECTED		= 0x84,
	NXT_STATUS_END_OF_FILE		= 0x85,
	NXT_STATUS_NOT_LINEAR_FILE	= 0x86,
	NXT_STATUS_FILE_NOT_FOUND	= 0x87,
	NXT_STATUS_HANDLE_CLOSED	= 0x88,
	NXT_STATUS_NO_LINEAR_SPACE	= 0x89,
	NXT_STATUS_UNDEFINED_ERROR	= 0x8a,
	NXT_STATUS_FILE_BUSY		= 0x8b,
	NXT_STATUS_NO_WRITE_BUFFERS	= 0x8c,
	NXT_STATUS_APPEND_NOT_POSSIBLE	= 0x8d,
	NXT_STATUS_FILE_FULL		= 0x8e,
	NXT_STATUS_FILE_EXISTS		= 0x8f,
	NXT_STATUS_MODULE_NOT_FOUND	= 0x90,
	NXT_STATUS_OUT_OF_BOUNDS	= 0x91,
	NXT_STATUS_ILLEGAL_FILE_NAME	= 0x92,
	NXT_STATUS_ILLEGAL_HANDLE	= 0x93,
	NXT_STATUS_BT_BUSY		= 0x94,
	NXT_STATUS_BT_CONNECT_FAIL	= 0x95,
	NXT_STATUS_BT_TIMEOUT		= 0x96,
	NXT_STATUS_FILE_TX_TIMEOUT	= 0x97,
	NXT_STATUS_FILE_TX_DST_EXISTS	= 0x98,
	NXT_STATUS_FILE_TX_SRC_MISSING	= 0x99,
	NXT_STATUS_FILE_TX_STREAM_ERROR	= 0x9a,
	NXT_STATUS_FILE_TX_CLOSE_ERROR	= 0x9b,
	NXT_STATUS_REQUEST_FAILED	= 0xbd,
	NXT_STATUS_UNKNOWN_OPCODE	= 0xbe,
	NXT_STATUS_INSANE_PACKET	= 0xbf,
	NXT_STATUS_OUT_OF_RANGE		= 0xc0,
	NXT_STATUS_BUS_ERROR		= 0xdd,
	NXT_STATUS_BUFFER_FULL		= 0xde,
	NXT_STATUS_BAD_CHANNEL		= 0xdf,
	NXT_STATUS_CHANNEL_BUSY		= 0xe0,
	NXT_STATUS_NO_PROGRAM		= 0xec,
	NXT_STATUS_BAD_SIZE		= 0xed,
	NXT_STATUS_BAD_MAILBOX		= 0xee,
	NXT_STATUS_BAD_FIELD		= 0xef,
	NXT_STATUS_BAD_PORT		= 0xf0,
	NXT_STATUS_NO_MEMORY		= 0xfb,
	NXT_STATUS_BAD_ARGUMENTS	= 0xff,
};

/* Limits of the direct commands' arguments. */

/** NXT_NAME_LEN - a file name: at most 19 characters ("15.3") and a NUL */
#define NXT_NAME_LEN		20
/** NXT_OUTPUT_PORTS - motor ports A, B and C are numbered 0 to 2 */
#define NXT_OUTPUT_PORTS	3
/** NXT_OUTPUT_ALL - port number of SetOutputState that means every motor */
#define NXT_OUTPUT_ALL		0xff
/** NXT_INPUT_PORTS - sensor ports 1 to 4 are numbered 0 to 3 */
#define NXT_INPUT_PORTS		4
/** NXT_INBOXES - a program's inboxes, and the outboxes of a master brick */
#define NXT_INBOXES		10
/** NXT_REMOTE_INBOXES - MessageRead's remote inbox: 0 to 19 */
#define NXT_REMOTE_INBOXES	20
/** NXT_MESSAGE_MAX - longest mailbox message, its NUL included */
#define NXT_MESSAGE_MAX		59
/** NXT_LS_DATA_MAX - longest low-speed (I2C) transfer each way */
#define NXT_LS_DATA_MAX		16
/** NXT_TONE_MIN_HZ - lowest tone frequency */
#define NXT_TONE_MIN_HZ		200
/** NXT_TONE_MAX_HZ - highest tone frequency */
#define NXT_TONE_MAX_HZ		14000
/** NXT_POWER_MAX - motor power and turn ratio range from -100 to 100 */
#define NXT_POWER_MAX		100

/* struct nxt_output_state @mode bits */
/** NXT_MODE_MOTORON - turn the motor on */
#define NXT_MODE_MOTORON	0x01
/** NXT_MODE_BRAKE - brake between PWM pulses instead of floating */
#define NXT_MODE_BRAKE		0x02
/** NXT_MODE_REGULATED - turn on the regulation */
#define NXT_MODE_REGULATED	0x04

/**
 * enum nxt_regulation_mode - struct nxt_output_state @regulation_mode
 * @NXT_REGULATION_IDLE: no regulation
 * @NXT_REGULATION_MOTOR_SPEED: speed regulation
 * @NXT_REGULATION_MOTOR_SYNC: two motors synchronised
 */
enum nxt_regulation_mode {
	NXT_REGULATION_IDLE		= 0x00,
	NXT_REGULATION_MOTOR_SPEED	= 0x01,
	NXT_REGULATION_MOTOR_SYNC	= 0x02,
};

/**
 * enum nxt_run_state - struct nxt_output_state @run_state
 * @NXT_RUN_STATE_IDLE: output idle
 * @NXT_RUN_STATE_RAMPUP: output ramps up
 * @NXT_RUN_STATE_RUNNING: output running
 * @NXT_RUN_STATE_RAMPDOWN: output ramps down
 */
enum nxt_run_state {
	NXT_RUN_STATE_IDLE	= 0x00,
	NXT_RUN_STATE_RAMPUP	= 0x10,
	NXT_RUN_STATE_RUNNING	= 0x20,
	NXT_RUN_STATE_RAMPDOWN	= 0x40,
};

/**
 * enum nxt_sensor_type - struct nxt_input_mode @type
 * @NXT_SENSOR_NONE: nothing
 * @NXT_SENSOR_SWITCH: touch sensor
 * @NXT_SENSOR_TEMPERATURE: RCX temperature sensor
 * @NXT_SENSOR_REFLECTION: RCX light sensor
 * @NXT_SENSOR_ANGLE: RCX rotation sensor
 * @NXT_SENSOR_LIGHT_ACTIVE: light sensor with its lamp on
 * @NXT_SENSOR_LIGHT_INACTIVE: light sensor with its lamp off
 * @NXT_SENSOR_SOUND_DB: sound sensor, dB
 * @NXT_SENSOR_SOUND_DBA: sound sensor, dBA
 * @NXT_SENSOR_CUSTOM: custom
 * @NXT_SENSOR_LOWSPEED: I2C sensor
 * @NXT_SENSOR_LOWSPEED_9V: I2C sensor with 9 V supply (ultrasonic)
 */
enum nxt_sensor_type {
	NXT_SENSOR_NONE			= 0x00,
	NXT_SENSOR_SWITCH		= 0x01,
	NXT_SENSOR_TEMPERATURE		= 0x02,
	NXT_SENSOR_REFLECTION		= 0x03,
	NXT_SENSOR_ANGLE		= 0x04,
	NXT_SENSOR_LIGHT_ACTIVE		= 0x05,
	NXT_SENSOR_LIGHT_INACTIVE	= 0x06,
	NXT_SENSOR_SOUND_DB		= 0x07,
	NXT_SENSOR_SOUND_DBA		= 0x08,
	NXT_SENSOR_CUSTOM		= 0x09,
	NXT_SENSOR_LOWSPEED		= 0x0a,
	NXT_SENSOR_LOWSPEED_9V		= 0x0b,
};

/** NXT_SENSOR_TYPES - number of sensor types */
#define NXT_SENSOR_TYPES	0x0c

/**
 * enum nxt_sensor_mode - struct nxt_input_mode @mode: one of these in the
 * top three bits, a slope (0 to 31) in the low five
 * @NXT_SENSOR_MODE_RAW: raw value
 * @NXT_SENSOR_MODE_BOOLEAN: 0 or 1
 * @NXT_SENSOR_MODE_TRANSITION_COUNT: count of transitions
 * @NXT_SENSOR_MODE_PERIOD_COUNT: count of periods
 * @NXT_SENSOR_MODE_PERCENT: percent of full scale
 * @NXT_SENSOR_MODE_CELSIUS: degrees Celsius
 * @NXT_SENSOR_MODE_FAHRENHEIT: degrees Fahrenheit
 * @NXT_SENSOR_MODE_ANGLE_STEPS: angle steps
 */
enum nxt_sensor_mode {
	NXT_SENSOR_MODE_RAW		= 0x00,
	NXT_SENSOR_MODE_BOOLEAN		= 0x20,
	NXT_SENSOR_MODE_TRANSITION_COUNT = 0x40,
	NXT_SENSOR_MODE_PERIOD_COUNT	= 0x60,
	NXT_SENSOR_MODE_PERCENT		= 0x80,
	NXT_SENSOR_MODE_CELSIUS		= 0xa0,
	NXT_SENSOR_MODE_FAHRENHEIT	= 0xc0,
	NXT_SENSOR_MODE_ANGLE_STEPS	= 0xe0,
};

/**
 * struct nxt_transaction - NXT_IOC_TRANSACT: one telegram and its reply
 * @telegram: in: the telegram, type byte first (any direct or system command)
 * @reply: out: the brick's reply, unchecked beyond its type byte, echoed
 *	opcode and length; the bytes past @reply_length are zero
 * @length: in: length of @telegram, NXT_TELEGRAM_MIN to NXT_TELEGRAM_MAX
 * @reply_length: out: length of @reply; 0 for a telegram that asks for none
 */
struct nxt_transaction {
	__u8 telegram[NXT_TELEGRAM_MAX];
	__u8 reply[NXT_TELEGRAM_MAX];
	__u32 length;
	__u32 reply_length;
};

/**
 * struct nxt_status_only - a command with no arguments and no reply data
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_status_only {
	__u8 status;
	__u8 reserved[3];
};

/**
 * struct nxt_program - StartProgram, GetCurrentProgramName
 * @name: NUL-terminated file name, at most 19 characters (StartProgram: in;
 *	GetCurrentProgramName: out, all zero when no program runs)
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_program {
	char name[NXT_NAME_LEN];
	__u8 status;
	__u8 reserved[3];
};

/**
 * struct nxt_sound_file - PlaySoundFile
 * @name: in: NUL-terminated file name (.rso), at most 19 characters
 * @loop: in: 1 to repeat the sound until StopSoundPlayback, 0 to play it once
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_sound_file {
	char name[NXT_NAME_LEN];
	__u8 loop;
	__u8 status;
	__u8 reserved[2];
};

/**
 * struct nxt_tone - PlayTone
 * @frequency: in: NXT_TONE_MIN_HZ to NXT_TONE_MAX_HZ
 * @duration: in: milliseconds
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_tone {
	__u16 frequency;
	__u16 duration;
	__u8 status;
	__u8 reserved[3];
};

/**
 * struct nxt_output_state - SetOutputState (in), GetOutputState (out)
 * @port: in: 0 to 2 (A to C); SetOutputState also takes NXT_OUTPUT_ALL
 * @power: -100 to 100
 * @mode: NXT_MODE_* bits
 * @regulation_mode: enum nxt_regulation_mode
 * @turn_ratio: -100 to 100
 * @run_state: enum nxt_run_state
 * @status: out: the brick's status byte
 * @reserved: zero
 * @tacho_limit: degrees to turn, 0 for no limit
 * @tacho_count: out: degrees since the last reset of the motor counter
 * @block_tacho_count: out: degrees relative to the last programmed movement
 * @rotation_count: out: degrees since the last reset of the rotation sensor
 */
struct nxt_output_state {
	__u8 port;
	__s8 power;
	__u8 mode;
	__u8 regulation_mode;
	__s8 turn_ratio;
	__u8 run_state;
	__u8 status;
	__u8 reserved;
	__u32 tacho_limit;
	__s32 tacho_count;
	__s32 block_tacho_count;
	__s32 rotation_count;
};

/**
 * struct nxt_input_mode - SetInputMode
 * @port: in: 0 to 3 (sensor ports 1 to 4)
 * @type: in: enum nxt_sensor_type
 * @mode: in: enum nxt_sensor_mode, ORed with a slope of 0 to 31
 * @status: out: the brick's status byte
 */
struct nxt_input_mode {
	__u8 port;
	__u8 type;
	__u8 mode;
	__u8 status;
};

/**
 * struct nxt_input_values - GetInputValues
 * @port: in: 0 to 3
 * @valid: out: 1 when the values are valid (not right after SetInputMode)
 * @calibrated: out: 1 when a calibration file was used
 * @type: out: enum nxt_sensor_type
 * @mode: out: enum nxt_sensor_mode and slope
 * @status: out: the brick's status byte
 * @raw: out: raw A/D value
 * @normalized: out: normalised A/D value, 0 to 1023
 * @scaled: out: value in the port's mode
 * @calibrated_value: out: calibrated value
 * @reserved: zero
 */
struct nxt_input_values {
	__u8 port;
	__u8 valid;
	__u8 calibrated;
	__u8 type;
	__u8 mode;
	__u8 status;
	__u16 raw;
	__u16 normalized;
	__s16 scaled;
	__s16 calibrated_value;
	__u16 reserved;
};

/**
 * struct nxt_input_port - ResetInputScaledValue
 * @port: in: 0 to 3
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_input_port {
	__u8 port;
	__u8 status;
	__u8 reserved[2];
};

/**
 * struct nxt_motor_position - ResetMotorPosition
 * @port: in: 0 to 2
 * @relative: in: 1 resets the count relative to the last movement (block
 *	tacho count), 0 the absolute position (rotation count)
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_motor_position {
	__u8 port;
	__u8 relative;
	__u8 status;
	__u8 reserved;
};

/**
 * struct nxt_message - MessageWrite, MessageRead
 * @inbox: in: MessageWrite: the inbox, 0 to 9; MessageRead: the remote
 *	inbox, 0 to 19 (10 to 19 hold a slave brick's messages to its master)
 * @local_inbox: MessageRead: in: the local inbox, 0 to 9; out: as echoed
 *	by a reply of success (an error leaves it as it was)
 * @remove: MessageRead: in: 1 to take the message out of the queue
 * @size: bytes in @data, its terminating NUL included, 1 to
 *	NXT_MESSAGE_MAX (MessageWrite: in; MessageRead: out)
 * @data: the message, ending in a NUL (MessageRead: bytes past @size zero)
 * @status: out: the brick's status byte
 */
struct nxt_message {
	__u8 inbox;
	__u8 local_inbox;
	__u8 remove;
	__u8 size;
	__u8 data[NXT_MESSAGE_MAX];
	__u8 status;
};

/**
 * struct nxt_battery - GetBatteryLevel
 * @millivolts: out: battery voltage
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_battery {
	__u16 millivolts;
	__u8 status;
	__u8 reserved;
};

/**
 * struct nxt_keep_alive - KeepAlive
 * @sleep_limit: out: milliseconds of inactivity before the brick turns
 *	itself off, 0 for never
 * @status: out: the brick's status byte
 * @reserved: zero
 */
struct nxt_keep_alive {
	__u32 sleep_limit;
	__u8 status;
	__u8 reserved[3];
};

/**
 * struct nxt_ls_status - LSGetStatus
 * @port: in: 0 to 3
 * @bytes_ready: out: bytes the sensor's answer holds, ready for LSRead
 * @status: out: the brick's status byte (NXT_STATUS_PENDING while busy:
 *	the ioctl then fails with EINPROGRESS)
 * @reserved: zero
 */
struct nxt_ls_status {
	__u8 port;
	__u8 bytes_ready;
	__u8 status;
	__u8 reserved;
};

/**
 * struct nxt_ls_write - LSWrite
 * @port: in: 0 to 3, set to NXT_SENSOR_LOWSPEED or NXT_SENSOR_LOWSPEED_9V
 * @tx_length: in: bytes of @tx_data to send, 1 to NXT_LS_DATA_MAX
 * @rx_length: in: bytes to read back, 0 to NXT_LS_DATA_MAX
 * @status: out: the brick's status byte
 * @tx_data: in: the bytes to send (I2C address first)
 */
struct nxt_ls_write {
	__u8 port;
	__u8 tx_length;
	__u8 rx_length;
	__u8 status;
	__u8 tx_data[NXT_LS_DATA_MAX];
};

/**
 * struct nxt_ls_read - LSRead
 * @port: in: 0 to 3
 * @length: out: bytes of @data read, 0 to NXT_LS_DATA_MAX
 * @status: out: the brick's status byte
 * @reserved: zero
 * @data: out: the bytes read; the bytes past @length are zero
 */
struct nxt_ls_read {
	__u8 port;
	__u8 length;
	__u8 status;
	__u8 reserved;
	__u8 data[NXT_LS_DATA_MAX];
};

#define NXT_IOC_MAGIC		0xE4

/**
 * NXT_IOC_TRANSACT - send any telegram and wait for its reply
 *
 * Errors: EBADF (the file is not open for writing), EINVAL (@length under
 * NXT_TELEGRAM_MIN or under what the telegram's command reads, or a type
 * byte that is not a command), EMSGSIZE (@length over NXT_TELEGRAM_MAX),
 * ETIMEDOUT (no reply within the file's timeout), EPROTO (only packets
 * that were not the reply came within the timeout: wrong type, opcode,
 * length, or echoed port or inbox), EPIPE (an endpoint stalled), EIO (a
 * USB reset or suspend, or a transfer error), ENODEV (the brick was
 * unplugged), EAGAIN (O_NONBLOCK and the brick busy: nothing was sent),
 * EINTR (a signal after the telegram was sent).
 */
#define NXT_IOC_TRANSACT	_IOWR(NXT_IOC_MAGIC, 0x00, struct nxt_transaction)

/**
 * NXT_IOC_SET_TIMEOUT - set this open file's reply timeout, in milliseconds
 *
 * 1 to 60000; the default is 1000. Errors: EINVAL.
 */
#define NXT_IOC_SET_TIMEOUT	_IOW(NXT_IOC_MAGIC, 0x01, __u32)

/** NXT_IOC_GET_TIMEOUT - read this open file's reply timeout, in milliseconds */
#define NXT_IOC_GET_TIMEOUT	_IOR(NXT_IOC_MAGIC, 0x02, __u32)

/* The direct commands: ioctl number 0x10 + opcode. */
#define NXT_IOC_DIRECT(op)	(0x10 + (op))

/** NXT_IOC_START_PROGRAM - StartProgram */
#define NXT_IOC_START_PROGRAM \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_START_PROGRAM), struct nxt_program)
/** NXT_IOC_STOP_PROGRAM - StopProgram */
#define NXT_IOC_STOP_PROGRAM \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_STOP_PROGRAM), struct nxt_status_only)
/** NXT_IOC_PLAY_SOUND_FILE - PlaySoundFile */
#define NXT_IOC_PLAY_SOUND_FILE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_PLAY_SOUND_FILE), struct nxt_sound_file)
/** NXT_IOC_PLAY_TONE - PlayTone */
#define NXT_IOC_PLAY_TONE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_PLAY_TONE), struct nxt_tone)
/** NXT_IOC_SET_OUTPUT_STATE - SetOutputState (the counters are ignored) */
#define NXT_IOC_SET_OUTPUT_STATE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_SET_OUTPUT_STATE), struct nxt_output_state)
/** NXT_IOC_SET_INPUT_MODE - SetInputMode */
#define NXT_IOC_SET_INPUT_MODE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_SET_INPUT_MODE), struct nxt_input_mode)
/** NXT_IOC_GET_OUTPUT_STATE - GetOutputState */
#define NXT_IOC_GET_OUTPUT_STATE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_GET_OUTPUT_STATE), struct nxt_output_state)
/** NXT_IOC_GET_INPUT_VALUES - GetInputValues */
#define NXT_IOC_GET_INPUT_VALUES \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_GET_INPUT_VALUES), struct nxt_input_values)
/** NXT_IOC_RESET_INPUT_SCALED_VALUE - ResetInputScaledValue */
#define NXT_IOC_RESET_INPUT_SCALED_VALUE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_RESET_INPUT_SCALED_VALUE), struct nxt_input_port)
/** NXT_IOC_MESSAGE_WRITE - MessageWrite */
#define NXT_IOC_MESSAGE_WRITE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_MESSAGE_WRITE), struct nxt_message)
/** NXT_IOC_RESET_MOTOR_POSITION - ResetMotorPosition */
#define NXT_IOC_RESET_MOTOR_POSITION \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_RESET_MOTOR_POSITION), struct nxt_motor_position)
/** NXT_IOC_GET_BATTERY_LEVEL - GetBatteryLevel */
#define NXT_IOC_GET_BATTERY_LEVEL \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_GET_BATTERY_LEVEL), struct nxt_battery)
/** NXT_IOC_STOP_SOUND_PLAYBACK - StopSoundPlayback */
#define NXT_IOC_STOP_SOUND_PLAYBACK \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_STOP_SOUND_PLAYBACK), struct nxt_status_only)
/** NXT_IOC_KEEP_ALIVE - KeepAlive */
#define NXT_IOC_KEEP_ALIVE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_KEEP_ALIVE), struct nxt_keep_alive)
/** NXT_IOC_LS_GET_STATUS - LSGetStatus */
#define NXT_IOC_LS_GET_STATUS \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_LS_GET_STATUS), struct nxt_ls_status)
/** NXT_IOC_LS_WRITE - LSWrite */
#define NXT_IOC_LS_WRITE \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_LS_WRITE), struct nxt_ls_write)
/** NXT_IOC_LS_READ - LSRead */
#define NXT_IOC_LS_READ \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_LS_READ), struct nxt_ls_read)
/** NXT_IOC_GET_CURRENT_PROGRAM_NAME - GetCurrentProgramName */
#define NXT_IOC_GET_CURRENT_PROGRAM_NAME \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_GET_CURRENT_PROGRAM_NAME), struct nxt_program)
/** NXT_IOC_MESSAGE_READ - MessageRead */
#define NXT_IOC_MESSAGE_READ \
	_IOWR(NXT_IOC_MAGIC, NXT_IOC_DIRECT(NXT_MESSAGE_READ), struct nxt_message)

#endif /* _UAPI_LINUX_LEGO_NXT_H */
