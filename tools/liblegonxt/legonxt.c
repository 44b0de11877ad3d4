// SPDX-License-Identifier: LGPL-2.1-or-later
/*
 * liblegonxt: the NXT brick's commands as the LEGO firmware (1.29, with
 * 1.28's additions) defines them. Every length and limit below is the
 * firmware's over USB; a reply's fields are read only after its length
 * was checked, and nothing in a reply is trusted beyond that.
 */
#include <errno.h>
#include <string.h>

#include "legonxt.h"

#define OUTPUT_PORTS	3
#define INPUT_PORTS	4
#define INBOXES		20	/* MessageWrite and MessageRead's queues */
#define NAME_FIELD	(LNXT_NAME_MAX + 1)
#define REPLY_HDR	3	/* 0x02, opcode, status */
#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))

/* ---- writing a telegram ---- */

static void put_u16(uint8_t *p, uint16_t v)
{
	p[0] = v & 0xff;
	p[1] = v >> 8;
}

static void put_u32(uint8_t *p, uint32_t v)
{
	put_u16(p, v & 0xffff);
	put_u16(p + 2, v >> 16);
}

static uint8_t *start(struct lnxt_msg *m, enum lnxt_op op)
{
	memset(m, 0, sizeof(*m));
	m->buf[0] = op >= 0x80 ? LNXT_SYSTEM : LNXT_DIRECT;
	m->buf[1] = op;
	m->len = 2;
	return m->buf + 2;
}

/* A command whose only argument is one byte. */
static void with_byte(struct lnxt_msg *m, enum lnxt_op op, uint8_t b)
{
	start(m, op)[0] = b;
	m->len = 3;
}

/* A name field: @size bytes, NUL-padded; -EINVAL when it does not fit. */
static int put_name(uint8_t *field, size_t size, const char *name)
{
	size_t n = strnlen(name, size);

	if (n == 0 || n >= size)
		return -EINVAL;
	memcpy(field, name, n);
	return 0;
}

static int with_name(struct lnxt_msg *m, enum lnxt_op op, const char *name)
{
	uint8_t *p = start(m, op);

	m->len = 2 + NAME_FIELD;
	return put_name(p, NAME_FIELD, name);
}

static int with_name_size(struct lnxt_msg *m, enum lnxt_op op, const char *name,
			  uint32_t size)
{
	int ret = with_name(m, op, name);

	put_u32(m->buf + 2 + NAME_FIELD, size);
	m->len += 4;
	return ret;
}

static int with_port(struct lnxt_msg *m, enum lnxt_op op, unsigned int port,
		     unsigned int ports)
{
	if (port >= ports)
		return -EINVAL;
	with_byte(m, op, port);
	return 0;
}

/* ---- direct commands ---- */

int lnxt_start_program(struct lnxt_msg *m, const char *name)
{
	return with_name(m, LNXT_START_PROGRAM, name);
}

void lnxt_stop_program(struct lnxt_msg *m)
{
	start(m, LNXT_STOP_PROGRAM);
}

int lnxt_play_sound_file(struct lnxt_msg *m, bool loop, const char *name)
{
	uint8_t *p = start(m, LNXT_PLAY_SOUND_FILE);

	p[0] = loop;
	m->len = 3 + NAME_FIELD;
	return put_name(p + 1, NAME_FIELD, name);
}

void lnxt_play_tone(struct lnxt_msg *m, uint16_t hz, uint16_t ms)
{
	uint8_t *p = start(m, LNXT_PLAY_TONE);

	put_u16(p, hz);
	put_u16(p + 2, ms);
	m->len = 6;
}

int lnxt_set_output_state(struct lnxt_msg *m, const struct lnxt_output *o)
{
	uint8_t *p = start(m, LNXT_SET_OUTPUT_STATE);

	p[0] = o->port;
	p[1] = (uint8_t)o->power;
	p[2] = o->mode;
	p[3] = o->regulation;
	p[4] = (uint8_t)o->turn;
	p[5] = o->run_state;
	put_u32(p + 6, o->tacho_limit);
	m->len = 12;
	if ((o->port >= OUTPUT_PORTS && o->port != LNXT_PORT_ALL) ||
	    o->power < -100 || o->power > 100 || o->turn < -100 || o->turn > 100 ||
	    (o->mode & ~(LNXT_MODE_MOTORON | LNXT_MODE_BRAKE | LNXT_MODE_REGULATED)) ||
	    o->regulation > LNXT_REGULATION_SYNC ||
	    (o->run_state != LNXT_RUN_IDLE && o->run_state != LNXT_RUN_RAMPUP &&
	     o->run_state != LNXT_RUN_RUNNING && o->run_state != LNXT_RUN_RAMPDOWN))
		return -EINVAL;
	return 0;
}

int lnxt_set_input_mode(struct lnxt_msg *m, unsigned int port, uint8_t type, uint8_t mode)
{
	int ret = with_port(m, LNXT_SET_INPUT_MODE, port, INPUT_PORTS);

	m->buf[3] = type;
	m->buf[4] = mode;
	m->len = 5;
	return ret;
}

int lnxt_get_output_state(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_GET_OUTPUT_STATE, port, OUTPUT_PORTS);
}

int lnxt_get_input_values(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_GET_INPUT_VALUES, port, INPUT_PORTS);
}

int lnxt_reset_input_scaled_value(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_RESET_INPUT_SCALED_VALUE, port, INPUT_PORTS);
}

/* The message goes with its NUL, which the firmware requires. */
int lnxt_message_write(struct lnxt_msg *m, unsigned int inbox, const void *data, size_t len)
{
	uint8_t *p = start(m, LNXT_MESSAGE_WRITE);

	if (inbox >= INBOXES || len > LNXT_MESSAGE_MAX)
		return -EINVAL;
	p[0] = inbox;
	p[1] = len + 1;
	memcpy(p + 2, data, len);
	m->len = 4 + len + 1;
	return 0;
}

int lnxt_reset_motor_position(struct lnxt_msg *m, unsigned int port, bool relative)
{
	int ret = with_port(m, LNXT_RESET_MOTOR_POSITION, port, OUTPUT_PORTS);

	m->buf[3] = relative;
	m->len = 4;
	return ret;
}

void lnxt_get_battery_level(struct lnxt_msg *m)
{
	start(m, LNXT_GET_BATTERY_LEVEL);
}

void lnxt_stop_sound_playback(struct lnxt_msg *m)
{
	start(m, LNXT_STOP_SOUND_PLAYBACK);
}

void lnxt_keep_alive(struct lnxt_msg *m)
{
	start(m, LNXT_KEEP_ALIVE);
}

int lnxt_ls_get_status(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_LS_GET_STATUS, port, INPUT_PORTS);
}

int lnxt_ls_write(struct lnxt_msg *m, unsigned int port, const void *tx, size_t tx_len,
		  size_t rx_len)
{
	uint8_t *p = start(m, LNXT_LS_WRITE);

	if (port >= INPUT_PORTS || tx_len > LNXT_LS_MAX || rx_len > LNXT_LS_MAX)
		return -EINVAL;
	p[0] = port;
	p[1] = tx_len;
	p[2] = rx_len;
	memcpy(p + 3, tx, tx_len);
	m->len = 5 + tx_len;
	return 0;
}

int lnxt_ls_read(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_LS_READ, port, INPUT_PORTS);
}

void lnxt_get_current_program_name(struct lnxt_msg *m)
{
	start(m, LNXT_GET_CURRENT_PROGRAM_NAME);
}

int lnxt_message_read(struct lnxt_msg *m, unsigned int remote, unsigned int local, bool remove)
{
	uint8_t *p = start(m, LNXT_MESSAGE_READ);

	p[0] = remote;
	p[1] = local;
	p[2] = remove;
	m->len = 5;
	return remote >= INBOXES || local >= INBOXES ? -EINVAL : 0;
}

void lnxt_datalog_read(struct lnxt_msg *m, bool remove)
{
	with_byte(m, LNXT_DATALOG_READ, remove);
}

void lnxt_datalog_set_times(struct lnxt_msg *m, uint32_t sync_time)
{
	put_u32(start(m, LNXT_DATALOG_SET_TIMES), sync_time);
	m->len = 6;
}

void lnxt_bt_get_contact_count(struct lnxt_msg *m)
{
	start(m, LNXT_BT_GET_CONTACT_COUNT);
}

void lnxt_bt_get_contact_name(struct lnxt_msg *m, uint8_t index)
{
	with_byte(m, LNXT_BT_GET_CONTACT_NAME, index);
}

void lnxt_bt_get_conn_count(struct lnxt_msg *m)
{
	start(m, LNXT_BT_GET_CONN_COUNT);
}

void lnxt_bt_get_conn_name(struct lnxt_msg *m, uint8_t index)
{
	with_byte(m, LNXT_BT_GET_CONN_NAME, index);
}

int lnxt_set_property(struct lnxt_msg *m, enum lnxt_property prop, uint32_t value)
{
	uint8_t *p = start(m, LNXT_SET_PROPERTY);

	p[0] = prop;
	switch (prop) {
	case LNXT_PROP_BT_ON:
	case LNXT_PROP_VOLUME:
		p[1] = value;
		m->len = 4;
		return value > (prop == LNXT_PROP_VOLUME ? 4 : 1) ? -EINVAL : 0;
	case LNXT_PROP_SLEEP_MS:
		put_u32(p + 1, value);
		m->len = 7;
		return 0;
	}
	return -EINVAL;
}

int lnxt_get_property(struct lnxt_msg *m, enum lnxt_property prop)
{
	with_byte(m, LNXT_GET_PROPERTY, prop);
	return prop > LNXT_PROP_SLEEP_MS ? -EINVAL : 0;
}

int lnxt_update_reset_count(struct lnxt_msg *m, unsigned int port)
{
	return with_port(m, LNXT_UPDATE_RESET_COUNT, port, OUTPUT_PORTS);
}

/* ---- system commands ---- */

int lnxt_open_read(struct lnxt_msg *m, const char *name)
{
	return with_name(m, LNXT_OPEN_READ, name);
}

int lnxt_open_write(struct lnxt_msg *m, const char *name, uint32_t size)
{
	return with_name_size(m, LNXT_OPEN_WRITE, name, size);
}

int lnxt_read(struct lnxt_msg *m, uint8_t handle, size_t n)
{
	uint8_t *p = start(m, LNXT_READ);

	p[0] = handle;
	put_u16(p + 1, n);
	m->len = 5;
	/* Over USB the firmware overruns its buffer past 58 bytes. */
	return n == 0 || n > LNXT_READ_MAX ? -EINVAL : 0;
}

int lnxt_write(struct lnxt_msg *m, uint8_t handle, const void *data, size_t len)
{
	uint8_t *p = start(m, LNXT_WRITE);

	if (len == 0 || len > LNXT_WRITE_MAX)
		return -EINVAL;
	p[0] = handle;
	memcpy(p + 1, data, len);
	m->len = 3 + len;
	return 0;
}

void lnxt_close(struct lnxt_msg *m, uint8_t handle)
{
	with_byte(m, LNXT_CLOSE, handle);
}

int lnxt_delete(struct lnxt_msg *m, const char *name)
{
	return with_name(m, LNXT_DELETE, name);
}

int lnxt_find_first(struct lnxt_msg *m, const char *pattern)
{
	return with_name(m, LNXT_FIND_FIRST, pattern);
}

void lnxt_find_next(struct lnxt_msg *m, uint8_t handle)
{
	with_byte(m, LNXT_FIND_NEXT, handle);
}

void lnxt_get_versions(struct lnxt_msg *m)
{
	start(m, LNXT_GET_VERSIONS);
}

int lnxt_open_write_linear(struct lnxt_msg *m, const char *name, uint32_t size)
{
	return with_name_size(m, LNXT_OPEN_WRITE_LINEAR, name, size);
}

int lnxt_open_write_data(struct lnxt_msg *m, const char *name, uint32_t size)
{
	return with_name_size(m, LNXT_OPEN_WRITE_DATA, name, size);
}

int lnxt_open_append_data(struct lnxt_msg *m, const char *name)
{
	return with_name(m, LNXT_OPEN_APPEND_DATA, name);
}

void lnxt_crop_data_file(struct lnxt_msg *m, uint8_t handle)
{
	with_byte(m, LNXT_CROP_DATA_FILE, handle);
}

int lnxt_find_first_module(struct lnxt_msg *m, const char *pattern)
{
	return with_name(m, LNXT_FIND_FIRST_MODULE, pattern);
}

void lnxt_find_next_module(struct lnxt_msg *m, uint8_t handle)
{
	with_byte(m, LNXT_FIND_NEXT_MODULE, handle);
}

void lnxt_close_module_handle(struct lnxt_msg *m, uint8_t handle)
{
	with_byte(m, LNXT_CLOSE_MODULE_HANDLE, handle);
}

static uint8_t *io_map(struct lnxt_msg *m, enum lnxt_op op, uint32_t id, uint16_t offset,
		       size_t n)
{
	uint8_t *p = start(m, op);

	put_u32(p, id);
	put_u16(p + 4, offset);
	put_u16(p + 6, n);
	m->len = 10;
	return p + 8;
}

int lnxt_read_io_map(struct lnxt_msg *m, uint32_t id, uint16_t offset, size_t n)
{
	io_map(m, LNXT_READ_IO_MAP, id, offset, n);
	return n == 0 || n > LNXT_IOMAP_MAX ? -EINVAL : 0;
}

int lnxt_write_io_map(struct lnxt_msg *m, uint32_t id, uint16_t offset, const void *data,
		      size_t len)
{
	if (len == 0 || len > LNXT_IOMAP_WRITE_MAX) {
		io_map(m, LNXT_WRITE_IO_MAP, id, offset, 0);
		return -EINVAL;
	}
	memcpy(io_map(m, LNXT_WRITE_IO_MAP, id, offset, len), data, len);
	m->len += len;
	return 0;
}

/* The firmware checks the words; the brick then reboots into SAM-BA. */
void lnxt_boot_command(struct lnxt_msg *m)
{
	static const char words[] = "Let's dance: SAMBA";

	memcpy(start(m, LNXT_BOOT_COMMAND), words, sizeof(words));
	m->len = 2 + sizeof(words);
}

int lnxt_set_brick_name(struct lnxt_msg *m, const char *name)
{
	uint8_t *p = start(m, LNXT_SET_BRICK_NAME);

	m->len = 2 + LNXT_BRICK_NAME_MAX + 1;
	return put_name(p, LNXT_BRICK_NAME_MAX + 1, name);
}

void lnxt_get_bt_address(struct lnxt_msg *m)
{
	start(m, LNXT_GET_BT_ADDRESS);
}

void lnxt_get_device_info(struct lnxt_msg *m)
{
	start(m, LNXT_GET_DEVICE_INFO);
}

void lnxt_delete_user_flash(struct lnxt_msg *m)
{
	start(m, LNXT_DELETE_USER_FLASH);
}

void lnxt_poll_command_length(struct lnxt_msg *m, uint8_t buffer)
{
	with_byte(m, LNXT_POLL_COMMAND_LENGTH, buffer);
}

int lnxt_poll_command(struct lnxt_msg *m, uint8_t buffer, size_t n)
{
	uint8_t *p = start(m, LNXT_POLL_COMMAND);

	p[0] = buffer;
	p[1] = n;
	m->len = 4;
	return n == 0 || n > LNXT_POLL_MAX ? -EINVAL : 0;
}

void lnxt_bt_factory_reset(struct lnxt_msg *m)
{
	start(m, LNXT_BT_FACTORY_RESET);
}

void lnxt_no_reply(struct lnxt_msg *m)
{
	m->buf[0] |= LNXT_NO_REPLY;
}

bool lnxt_wants_reply(const struct lnxt_msg *m)
{
	return !(m->buf[0] & LNXT_NO_REPLY);
}

/* ---- replies ---- */

/*
 * The whole reply of each command, from the firmware's handlers: the
 * same on error, but for the few that answer with three bytes (an unknown
 * opcode, LSGetStatus and LSRead on a bad port). 0: not fixed.
 */
static const uint8_t reply_lens[256] = {
	[LNXT_START_PROGRAM] = 3, [LNXT_STOP_PROGRAM] = 3, [LNXT_PLAY_SOUND_FILE] = 3,
	[LNXT_PLAY_TONE] = 3, [LNXT_SET_OUTPUT_STATE] = 3, [LNXT_SET_INPUT_MODE] = 3,
	[LNXT_GET_OUTPUT_STATE] = 25, [LNXT_GET_INPUT_VALUES] = 16,
	[LNXT_RESET_INPUT_SCALED_VALUE] = 3, [LNXT_MESSAGE_WRITE] = 3,
	[LNXT_RESET_MOTOR_POSITION] = 3, [LNXT_GET_BATTERY_LEVEL] = 5,
	[LNXT_STOP_SOUND_PLAYBACK] = 3, [LNXT_KEEP_ALIVE] = 7, [LNXT_LS_GET_STATUS] = 4,
	[LNXT_LS_WRITE] = 3, [LNXT_LS_READ] = 20, [LNXT_GET_CURRENT_PROGRAM_NAME] = 23,
	[LNXT_MESSAGE_READ] = 64, [LNXT_DATALOG_READ] = 64, [LNXT_DATALOG_SET_TIMES] = 3,
	[LNXT_BT_GET_CONTACT_COUNT] = 4, [LNXT_BT_GET_CONTACT_NAME] = 21,
	[LNXT_BT_GET_CONN_COUNT] = 4, [LNXT_BT_GET_CONN_NAME] = 21, [LNXT_SET_PROPERTY] = 3,
	[LNXT_UPDATE_RESET_COUNT] = 3,
	[LNXT_OPEN_READ] = 8, [LNXT_OPEN_WRITE] = 4, [LNXT_WRITE] = 6, [LNXT_CLOSE] = 4,
	[LNXT_DELETE] = 23, [LNXT_FIND_FIRST] = 28, [LNXT_FIND_NEXT] = 28,
	[LNXT_GET_VERSIONS] = 7, [LNXT_OPEN_WRITE_LINEAR] = 4, [LNXT_OPEN_WRITE_DATA] = 4,
	[LNXT_OPEN_APPEND_DATA] = 8, [LNXT_CROP_DATA_FILE] = 4, [LNXT_FIND_FIRST_MODULE] = 34,
	[LNXT_FIND_NEXT_MODULE] = 34, [LNXT_CLOSE_MODULE_HANDLE] = 4,
	[LNXT_WRITE_IO_MAP] = 9, [LNXT_BOOT_COMMAND] = 7, [LNXT_SET_BRICK_NAME] = 3,
	[LNXT_GET_BT_ADDRESS] = 10, [LNXT_GET_DEVICE_INFO] = 33, [LNXT_DELETE_USER_FLASH] = 3,
	[LNXT_POLL_COMMAND_LENGTH] = 5, [LNXT_BT_FACTORY_RESET] = 3,
};

static uint16_t get_u16(const uint8_t *p)
{
	return p[0] | p[1] << 8;
}

static uint32_t get_u32(const uint8_t *p)
{
	return get_u16(p) | (uint32_t)get_u16(p + 2) << 16;
}

size_t lnxt_reply_len(const struct lnxt_msg *m)
{
	const uint8_t *a = m->buf + 2;	/* the arguments */

	if (m->len < 2)
		return 0;
	switch (m->buf[1]) {
	case LNXT_GET_PROPERTY:
		return m->len >= 3 && a[0] == LNXT_PROP_SLEEP_MS ? 7 : 4;
	case LNXT_READ:		/* the count asked for, echoed; the data capped */
		return m->len < 5 ? 0 : 6 + (get_u16(a + 1) < LNXT_READ_MAX ?
					     get_u16(a + 1) : LNXT_READ_MAX);
	case LNXT_READ_IO_MAP:
		return m->len < 10 ? 0 : 9 + (get_u16(a + 6) < LNXT_IOMAP_MAX ?
					      get_u16(a + 6) : LNXT_IOMAP_MAX);
	case LNXT_POLL_COMMAND:
		return m->len < 4 ? 0 : 5 + (a[1] < LNXT_POLL_MAX ? a[1] : LNXT_POLL_MAX);
	}
	return reply_lens[m->buf[1]];
}

int lnxt_reply_check(const struct lnxt_msg *m, const uint8_t *reply, size_t len)
{
	size_t want = lnxt_reply_len(m);

	if (len < REPLY_HDR || reply[0] != LNXT_REPLY || reply[1] != m->buf[1] || !want)
		return -EBADMSG;
	if (len != want && (reply[2] == 0 || len != REPLY_HDR))
		return -EBADMSG;
	return reply[2];
}

static const struct {
	uint8_t code;
	const char *name;
} statuses[] = {
	{ 0x00, "success" },
	{ 0x20, "transaction pending" },
	{ 0x40, "mailbox empty" },
	{ 0x81, "no more handles" },
	{ 0x82, "no space" },
	{ 0x83, "no more files" },
	{ 0x84, "end of file expected" },
	{ 0x85, "end of file" },
	{ 0x86, "not a linear file" },
	{ 0x87, "file not found" },
	{ 0x88, "handle already closed" },
	{ 0x89, "no linear space" },
	{ 0x8a, "undefined error" },
	{ 0x8b, "file busy" },
	{ 0x8c, "no write buffers" },
	{ 0x8d, "append not possible" },
	{ 0x8e, "file full" },
	{ 0x8f, "file exists" },
	{ 0x90, "module not found" },
	{ 0x91, "out of bounds" },
	{ 0x92, "illegal file name" },
	{ 0x93, "illegal handle" },
	{ 0x94, "Bluetooth busy" },
	{ 0x95, "Bluetooth connection failed" },
	{ 0x96, "Bluetooth timeout" },
	{ 0x97, "file transfer timeout" },
	{ 0x98, "destination file exists" },
	{ 0x99, "source file missing" },
	{ 0x9a, "file transfer stream error" },
	{ 0x9b, "file transfer close error" },
	{ 0xbd, "request failed" },
	{ 0xbe, "unknown command opcode" },
	{ 0xbf, "insane packet" },
	/* LEGO's firmware also answers so for a missing program or sound file. */
	{ 0xc0, "value out of range (or no such file)" },
	{ 0xdd, "communication bus error" },
	{ 0xde, "communication buffer full" },
	{ 0xdf, "invalid channel or connection" },
	{ 0xe0, "channel not configured or busy" },
	{ 0xec, "no program running" },
	{ 0xed, "illegal size" },
	{ 0xee, "illegal mailbox" },
	{ 0xef, "invalid field" },
	{ 0xf0, "bad input or output port" },
	{ 0xfa, "bad pointer" },
	{ 0xfb, "insufficient memory" },
	{ 0xfc, "version mismatch" },
	{ 0xfd, "bad file" },
	{ 0xfe, "bad instruction" },
	{ 0xff, "bad arguments" },
};

const char *lnxt_status_name(uint8_t status)
{
	size_t i;

	for (i = 0; i < ARRAY_SIZE(statuses); i++)
		if (statuses[i].code == status)
			return statuses[i].name;
	return NULL;
}

/* The fields of a whole, successful reply of @op, or NULL. */
static const uint8_t *fields(const uint8_t *reply, size_t len, enum lnxt_op op, size_t want)
{
	if (len != want || len < REPLY_HDR || reply[0] != LNXT_REPLY || reply[1] != op ||
	    reply[2] != 0)
		return NULL;
	return reply + REPLY_HDR;
}

/* A NUL-padded name field of @size bytes into @name (@size + 1 bytes). */
static void get_name(char *name, const uint8_t *field, size_t size)
{
	size_t n = strnlen((const char *)field, size);

	memcpy(name, field, n);
	name[n] = 0;
}

int lnxt_parse_output_state(const uint8_t *reply, size_t len, struct lnxt_output *o)
{
	const uint8_t *p = fields(reply, len, LNXT_GET_OUTPUT_STATE, 25);

	if (!p)
		return -EBADMSG;
	o->port = p[0];
	o->power = (int8_t)p[1];
	o->mode = p[2];
	o->regulation = p[3];
	o->turn = (int8_t)p[4];
	o->run_state = p[5];
	o->tacho_limit = get_u32(p + 6);
	o->tacho_count = (int32_t)get_u32(p + 10);
	o->block_tacho_count = (int32_t)get_u32(p + 14);
	o->rotation_count = (int32_t)get_u32(p + 18);
	return 0;
}

int lnxt_parse_input_values(const uint8_t *reply, size_t len, struct lnxt_input *in)
{
	const uint8_t *p = fields(reply, len, LNXT_GET_INPUT_VALUES, 16);

	if (!p)
		return -EBADMSG;
	in->port = p[0];
	in->valid = p[1];
	in->calibrated = p[2];
	in->type = p[3];
	in->mode = p[4];
	in->raw = get_u16(p + 5);
	in->normalized = get_u16(p + 7);
	in->scaled = (int16_t)get_u16(p + 9);
	in->calibrated_value = (int16_t)get_u16(p + 11);
	return 0;
}

int lnxt_parse_battery_level(const uint8_t *reply, size_t len, uint16_t *mv)
{
	const uint8_t *p = fields(reply, len, LNXT_GET_BATTERY_LEVEL, 5);

	if (!p)
		return -EBADMSG;
	*mv = get_u16(p);
	return 0;
}

int lnxt_parse_keep_alive(const uint8_t *reply, size_t len, uint32_t *sleep_ms)
{
	const uint8_t *p = fields(reply, len, LNXT_KEEP_ALIVE, 7);

	if (!p)
		return -EBADMSG;
	*sleep_ms = get_u32(p);
	return 0;
}

int lnxt_parse_ls_get_status(const uint8_t *reply, size_t len, uint8_t *ready)
{
	const uint8_t *p = fields(reply, len, LNXT_LS_GET_STATUS, 4);

	if (!p)
		return -EBADMSG;
	*ready = p[0];
	return 0;
}

/* A count and up to @max bytes after it; a count past @max is a bad reply. */
static int counted(const uint8_t *p, size_t max, struct lnxt_data *d)
{
	if (p[0] > max)
		return -EBADMSG;
	d->len = p[0];
	memset(d->data, 0, sizeof(d->data));
	memcpy(d->data, p + 1, max);
	return 0;
}

int lnxt_parse_ls_read(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_LS_READ, 20);

	if (!p)
		return -EBADMSG;
	d->handle = 0;
	d->id = 0;
	return counted(p, LNXT_LS_MAX, d);
}

int lnxt_parse_program_name(const uint8_t *reply, size_t len, char name[LNXT_NAME_MAX + 1])
{
	const uint8_t *p = fields(reply, len, LNXT_GET_CURRENT_PROGRAM_NAME, 23);

	if (!p)
		return -EBADMSG;
	get_name(name, p, LNXT_NAME_MAX);
	return 0;
}

/* The size counts the message's NUL; @d->len does not. */
int lnxt_parse_message_read(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_MESSAGE_READ, 64);

	if (!p)
		return -EBADMSG;
	d->handle = p[0];
	d->id = 0;
	if (counted(p + 1, LNXT_MESSAGE_MAX + 1, d))
		return -EBADMSG;
	if (d->len && d->data[d->len - 1] == 0)
		d->len--;
	return 0;
}

int lnxt_parse_datalog_read(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_DATALOG_READ, 64);

	if (!p)
		return -EBADMSG;
	d->handle = 0;
	d->id = 0;
	return counted(p, 60, d);
}

int lnxt_parse_bt_count(const uint8_t *reply, size_t len, uint8_t *count)
{
	if (len != 4 || (reply[1] != LNXT_BT_GET_CONTACT_COUNT &&
			 reply[1] != LNXT_BT_GET_CONN_COUNT))
		return -EBADMSG;
	if (!fields(reply, len, reply[1], 4))
		return -EBADMSG;
	*count = reply[3];
	return 0;
}

int lnxt_parse_bt_name(const uint8_t *reply, size_t len, uint8_t *type, char name[18])
{
	if (len != 21 || (reply[1] != LNXT_BT_GET_CONTACT_NAME &&
			  reply[1] != LNXT_BT_GET_CONN_NAME))
		return -EBADMSG;
	if (!fields(reply, len, reply[1], 21))
		return -EBADMSG;
	*type = reply[3];
	get_name(name, reply + 4, 17);
	return 0;
}

int lnxt_parse_property(const uint8_t *reply, size_t len, uint32_t *value)
{
	if (fields(reply, len, LNXT_GET_PROPERTY, 4))
		*value = reply[3];
	else if (fields(reply, len, LNXT_GET_PROPERTY, 7))
		*value = get_u32(reply + 3);
	else
		return -EBADMSG;
	return 0;
}

/* OpenRead, OpenAppendData (handle, size), FindFirst, FindNext (and a name). */
int lnxt_parse_file(const uint8_t *reply, size_t len, struct lnxt_file *f)
{
	memset(f, 0, sizeof(*f));
	if (len == 8 && (fields(reply, len, LNXT_OPEN_READ, 8) ||
			 fields(reply, len, LNXT_OPEN_APPEND_DATA, 8))) {
		f->handle = reply[3];
		f->size = get_u32(reply + 4);
		return 0;
	}
	if (len == 28 && (fields(reply, len, LNXT_FIND_FIRST, 28) ||
			  fields(reply, len, LNXT_FIND_NEXT, 28))) {
		f->handle = reply[3];
		get_name(f->name, reply + 4, LNXT_NAME_MAX);
		f->size = get_u32(reply + 24);
		return 0;
	}
	return -EBADMSG;
}

/* The replies that are only a handle (OpenWrite*, Close, CropDataFile, ...). */
int lnxt_parse_handle(const uint8_t *reply, size_t len, uint8_t *handle)
{
	if (len != 4 || reply[0] != LNXT_REPLY || reply[2] != 0)
		return -EBADMSG;
	switch (reply[1]) {
	case LNXT_OPEN_WRITE:
	case LNXT_CLOSE:
	case LNXT_OPEN_WRITE_LINEAR:
	case LNXT_OPEN_WRITE_DATA:
	case LNXT_CROP_DATA_FILE:
	case LNXT_CLOSE_MODULE_HANDLE:
		*handle = reply[3];
		return 0;
	}
	return -EBADMSG;
}

/* The count echoes what was asked for; only the bytes present are data. */
int lnxt_parse_read(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_READ, len);
	size_t n;

	if (!p || len < 6)
		return -EBADMSG;
	n = get_u16(p + 1);
	if (len != 6 + (n < LNXT_READ_MAX ? n : LNXT_READ_MAX))
		return -EBADMSG;
	d->handle = p[0];
	d->id = 0;
	d->len = len - 6;
	memset(d->data, 0, sizeof(d->data));
	memcpy(d->data, p + 3, d->len);
	return 0;
}

int lnxt_parse_write(const uint8_t *reply, size_t len, uint8_t *handle, uint16_t *written)
{
	const uint8_t *p = fields(reply, len, LNXT_WRITE, 6);

	if (!p)
		return -EBADMSG;
	*handle = p[0];
	*written = get_u16(p + 1);
	return 0;
}

int lnxt_parse_versions(const uint8_t *reply, size_t len, struct lnxt_versions *v)
{
	const uint8_t *p = fields(reply, len, LNXT_GET_VERSIONS, 7);

	if (!p)
		return -EBADMSG;
	v->protocol_minor = p[0];
	v->protocol_major = p[1];
	v->firmware_minor = p[2];
	v->firmware_major = p[3];
	return 0;
}

int lnxt_parse_module(const uint8_t *reply, size_t len, struct lnxt_module *mod)
{
	const uint8_t *p = fields(reply, len, LNXT_FIND_FIRST_MODULE, 34);

	if (!p)
		p = fields(reply, len, LNXT_FIND_NEXT_MODULE, 34);
	if (!p)
		return -EBADMSG;
	mod->handle = p[0];
	get_name(mod->name, p + 1, LNXT_NAME_MAX);
	mod->id = get_u32(p + 21);
	mod->size = get_u32(p + 25);
	mod->iomap_size = get_u16(p + 29);
	return 0;
}

/* The count is what was read; the data is as long as the count. */
int lnxt_parse_read_io_map(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_READ_IO_MAP, len);
	size_t n;

	if (!p || len < 9)
		return -EBADMSG;
	n = get_u16(p + 4);
	if (n > LNXT_IOMAP_MAX || len < 9 + n)
		return -EBADMSG;
	d->handle = 0;
	d->id = get_u32(p);
	d->len = n;
	memset(d->data, 0, sizeof(d->data));
	memcpy(d->data, p + 6, n);
	return 0;
}

int lnxt_parse_write_io_map(const uint8_t *reply, size_t len, uint32_t *id, uint16_t *written)
{
	const uint8_t *p = fields(reply, len, LNXT_WRITE_IO_MAP, 9);

	if (!p)
		return -EBADMSG;
	*id = get_u32(p);
	*written = get_u16(p + 4);
	return 0;
}

int lnxt_parse_bt_address(const uint8_t *reply, size_t len, uint8_t addr[6])
{
	const uint8_t *p = fields(reply, len, LNXT_GET_BT_ADDRESS, 10);

	if (!p)
		return -EBADMSG;
	memcpy(addr, p, 6);
	return 0;
}

int lnxt_parse_device_info(const uint8_t *reply, size_t len, struct lnxt_device_info *info)
{
	const uint8_t *p = fields(reply, len, LNXT_GET_DEVICE_INFO, 33);

	if (!p)
		return -EBADMSG;
	get_name(info->name, p, LNXT_BRICK_NAME_MAX);
	memcpy(info->bt_address, p + 15, 6);
	info->link_quality = get_u32(p + 22);
	info->free_flash = get_u32(p + 26);
	return 0;
}

int lnxt_parse_poll_length(const uint8_t *reply, size_t len, uint8_t *buffer, uint8_t *length)
{
	const uint8_t *p = fields(reply, len, LNXT_POLL_COMMAND_LENGTH, 5);

	if (!p)
		return -EBADMSG;
	*buffer = p[0];
	*length = p[1];
	return 0;
}

int lnxt_parse_poll(const uint8_t *reply, size_t len, struct lnxt_data *d)
{
	const uint8_t *p = fields(reply, len, LNXT_POLL_COMMAND, len);

	if (!p || len < 5 || p[1] > len - 5)
		return -EBADMSG;
	d->handle = p[0];
	d->id = 0;
	d->len = p[1];
	memset(d->data, 0, sizeof(d->data));
	memcpy(d->data, p + 2, len - 5);
	return 0;
}
