// SPDX-License-Identifier: LGPL-2.1-or-later
/*
 * liblegonxt's unit test: each builder against the bytes the brick
 * expects, each parser against a reply of the brick (the request and
 * reply pairs of nxt-python's test suite and the LEGO firmware's
 * handlers), and what must be refused. Exit status 1 on any failure.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "legonxt.h"

static int failures;
static int checks;

#define CHECK(cond) check((cond), #cond, __LINE__)

static void check(int ok, const char *what, int line)
{
	checks++;
	if (!ok) {
		failures++;
		fprintf(stderr, "%s:%d: FAILED: %s\n", __FILE__, line, what);
	}
}

/* Parse "00 0a ff" into @buf; returns the length. */
static size_t hex(uint8_t *buf, const char *s)
{
	size_t n = 0;
	char *end;

	while (*s) {
		unsigned long b = strtoul(s, &end, 16);

		if (end == s)
			break;
		buf[n++] = (uint8_t)b;
		s = end;
	}
	return n;
}

/* @m is exactly the telegram @want (hex), and asks for a reply or not. */
static void telegram(const struct lnxt_msg *m, const char *want, int line)
{
	uint8_t buf[LNXT_TELEGRAM_MAX];
	size_t n = hex(buf, want);

	check(m->len == n && !memcmp(m->buf, buf, n), want, line);
}

#define TELEGRAM(m, want) telegram((m), (want), __LINE__)

/* A name field: @s NUL-padded to @size bytes, as hex. */
static const char *field(const char *s, size_t size)
{
	static char out[4][3 * LNXT_TELEGRAM_MAX + 1];
	static int which;
	char *o = out[which++ % 4];
	size_t i;

	o[0] = 0;
	for (i = 0; i < size; i++)
		sprintf(o + 3 * i, "%02x ", i < strlen(s) ? (unsigned char)s[i] : 0);
	return o;
}

static char *cat(const char *a, const char *b, const char *c)
{
	static char out[4][4 * 3 * LNXT_TELEGRAM_MAX];
	static int which;
	char *o = out[which++ % 4];

	snprintf(o, sizeof(out[0]), "%s %s %s", a, b, c ? c : "");
	return o;
}

static void test_direct(void)
{
	struct lnxt_msg m;
	struct lnxt_output o = { .port = 1, .power = -100, .mode = 0x01, .regulation = 0,
				 .turn = -5, .run_state = 0x20, .tacho_limit = 0x04030201 };
	const uint8_t msg[] = "!\"#$%&'";
	const uint8_t i2c[] = { 0x21, 0x22, 0x23, 0x24, 0x25, 0x26, 0x27 };

	CHECK(lnxt_start_program(&m, "test.rxe") == 0);
	TELEGRAM(&m, cat("00 00", field("test.rxe", 20), NULL));
	lnxt_stop_program(&m);
	TELEGRAM(&m, "00 01");
	CHECK(lnxt_play_sound_file(&m, true, "test.rso") == 0);
	lnxt_no_reply(&m);
	CHECK(!lnxt_wants_reply(&m));
	TELEGRAM(&m, cat("80 02 01", field("test.rso", 20), NULL));
	lnxt_play_tone(&m, 440, 1000);
	CHECK(lnxt_wants_reply(&m));
	lnxt_no_reply(&m);
	TELEGRAM(&m, "80 03 b8 01 e8 03");
	CHECK(lnxt_set_output_state(&m, &o) == 0);
	lnxt_no_reply(&m);
	TELEGRAM(&m, "80 04 01 9c 01 00 fb 20 01 02 03 04");
	CHECK(lnxt_set_input_mode(&m, 2, 0x01, 0x20) == 0);
	lnxt_no_reply(&m);
	TELEGRAM(&m, "80 05 02 01 20");
	CHECK(lnxt_get_output_state(&m, 1) == 0);
	TELEGRAM(&m, "00 06 01");
	CHECK(lnxt_get_input_values(&m, 2) == 0);
	TELEGRAM(&m, "00 07 02");
	CHECK(lnxt_reset_input_scaled_value(&m, 2) == 0);
	TELEGRAM(&m, "00 08 02");
	CHECK(lnxt_message_write(&m, 3, msg, 7) == 0);
	TELEGRAM(&m, "00 09 03 08 21 22 23 24 25 26 27 00");
	CHECK(lnxt_reset_motor_position(&m, 1, true) == 0);
	TELEGRAM(&m, "00 0a 01 01");
	lnxt_get_battery_level(&m);
	TELEGRAM(&m, "00 0b");
	lnxt_stop_sound_playback(&m);
	TELEGRAM(&m, "00 0c");
	lnxt_keep_alive(&m);
	TELEGRAM(&m, "00 0d");
	CHECK(lnxt_ls_get_status(&m, 2) == 0);
	TELEGRAM(&m, "00 0e 02");
	CHECK(lnxt_ls_write(&m, 2, i2c, sizeof(i2c), 9) == 0);
	TELEGRAM(&m, "00 0f 02 07 09 21 22 23 24 25 26 27");
	CHECK(lnxt_ls_read(&m, 2) == 0);
	TELEGRAM(&m, "00 10 02");
	lnxt_get_current_program_name(&m);
	TELEGRAM(&m, "00 11");
	CHECK(lnxt_message_read(&m, 10, 0, true) == 0);
	TELEGRAM(&m, "00 13 0a 00 01");
	lnxt_datalog_read(&m, true);
	TELEGRAM(&m, "00 19 01");
	lnxt_datalog_set_times(&m, 0x04030201);
	TELEGRAM(&m, "00 1a 01 02 03 04");
	lnxt_bt_get_contact_count(&m);
	TELEGRAM(&m, "00 1b");
	lnxt_bt_get_contact_name(&m, 5);
	TELEGRAM(&m, "00 1c 05");
	lnxt_bt_get_conn_count(&m);
	TELEGRAM(&m, "00 1d");
	lnxt_bt_get_conn_name(&m, 3);
	TELEGRAM(&m, "00 1e 03");
	CHECK(lnxt_set_property(&m, LNXT_PROP_VOLUME, 4) == 0);
	TELEGRAM(&m, "00 1f 01 04");
	CHECK(lnxt_set_property(&m, LNXT_PROP_SLEEP_MS, 600000) == 0);
	TELEGRAM(&m, "00 1f 02 c0 27 09 00");
	CHECK(lnxt_get_property(&m, LNXT_PROP_SLEEP_MS) == 0);
	TELEGRAM(&m, "00 20 02");
	CHECK(lnxt_reply_len(&m) == 7);
	CHECK(lnxt_get_property(&m, LNXT_PROP_BT_ON) == 0);
	CHECK(lnxt_reply_len(&m) == 4);
	CHECK(lnxt_update_reset_count(&m, 2) == 0);
	TELEGRAM(&m, "00 21 02");
}

static void test_direct_refused(void)
{
	struct lnxt_msg m;
	struct lnxt_output o = { .port = 3 };
	uint8_t big[LNXT_MESSAGE_MAX + 1] = { 0 };

	CHECK(lnxt_start_program(&m, "") == -EINVAL);
	CHECK(lnxt_start_program(&m, "a-name-of-20-chars.x") == -EINVAL);
	CHECK(lnxt_start_program(&m, "name-of-19-chars.xy") == 0);
	CHECK(lnxt_set_output_state(&m, &o) == -EINVAL);
	o.port = LNXT_PORT_ALL;
	CHECK(lnxt_set_output_state(&m, &o) == 0);
	o.power = 101;
	CHECK(lnxt_set_output_state(&m, &o) == -EINVAL);
	o.power = 0;
	o.mode = 0x08;
	CHECK(lnxt_set_output_state(&m, &o) == -EINVAL);
	o.mode = 0;
	o.run_state = 0x30;
	CHECK(lnxt_set_output_state(&m, &o) == -EINVAL);
	CHECK(lnxt_set_input_mode(&m, 4, 0, 0) == -EINVAL);
	CHECK(lnxt_get_output_state(&m, 3) == -EINVAL);
	CHECK(lnxt_get_input_values(&m, 4) == -EINVAL);
	CHECK(lnxt_message_write(&m, 20, big, 1) == -EINVAL);
	CHECK(lnxt_message_write(&m, 0, big, LNXT_MESSAGE_MAX) == 0);
	CHECK(m.len == 4 + LNXT_MESSAGE_MAX + 1 && m.len <= LNXT_TELEGRAM_MAX);
	CHECK(lnxt_message_write(&m, 0, big, LNXT_MESSAGE_MAX + 1) == -EINVAL);
	CHECK(lnxt_ls_write(&m, 0, big, LNXT_LS_MAX + 1, 0) == -EINVAL);
	CHECK(lnxt_ls_write(&m, 0, big, 0, LNXT_LS_MAX + 1) == -EINVAL);
	CHECK(lnxt_message_read(&m, 20, 0, false) == -EINVAL);
	CHECK(lnxt_set_property(&m, LNXT_PROP_VOLUME, 5) == -EINVAL);
	CHECK(lnxt_get_property(&m, (enum lnxt_property)3) == -EINVAL);
	CHECK(lnxt_update_reset_count(&m, 3) == -EINVAL);
}

static void test_system(void)
{
	struct lnxt_msg m;
	const uint8_t data[] = { 0x21, 0x22, 0x23, 0x24, 0x25, 0x26, 0x27 };

	CHECK(lnxt_open_read(&m, "test.rxe") == 0);
	TELEGRAM(&m, cat("01 80", field("test.rxe", 20), NULL));
	CHECK(lnxt_open_write(&m, "test.rxe", 0x04030201) == 0);
	TELEGRAM(&m, cat("01 81", field("test.rxe", 20), "01 02 03 04"));
	CHECK(lnxt_read(&m, 0x42, 7) == 0);
	TELEGRAM(&m, "01 82 42 07 00");
	CHECK(lnxt_write(&m, 0x42, data, sizeof(data)) == 0);
	TELEGRAM(&m, "01 83 42 21 22 23 24 25 26 27");
	lnxt_close(&m, 0x42);
	TELEGRAM(&m, "01 84 42");
	CHECK(lnxt_delete(&m, "test.rxe") == 0);
	TELEGRAM(&m, cat("01 85", field("test.rxe", 20), NULL));
	CHECK(lnxt_find_first(&m, "*.*") == 0);
	TELEGRAM(&m, cat("01 86", field("*.*", 20), NULL));
	lnxt_find_next(&m, 0x42);
	TELEGRAM(&m, "01 87 42");
	lnxt_get_versions(&m);
	TELEGRAM(&m, "01 88");
	CHECK(lnxt_open_write_linear(&m, "test.rxe", 0x04030201) == 0);
	TELEGRAM(&m, cat("01 89", field("test.rxe", 20), "01 02 03 04"));
	CHECK(lnxt_open_write_data(&m, "test.rxe", 0x04030201) == 0);
	TELEGRAM(&m, cat("01 8b", field("test.rxe", 20), "01 02 03 04"));
	CHECK(lnxt_open_append_data(&m, "test.rxe") == 0);
	TELEGRAM(&m, cat("01 8c", field("test.rxe", 20), NULL));
	lnxt_crop_data_file(&m, 0x42);
	TELEGRAM(&m, "01 8d 42");
	CHECK(lnxt_find_first_module(&m, "*.*") == 0);
	TELEGRAM(&m, cat("01 90", field("*.*", 20), NULL));
	lnxt_find_next_module(&m, 0x42);
	TELEGRAM(&m, "01 91 42");
	lnxt_close_module_handle(&m, 0x42);
	TELEGRAM(&m, "01 92 42");
	CHECK(lnxt_read_io_map(&m, 0x04030201, 0x3231, 7) == 0);
	TELEGRAM(&m, "01 94 01 02 03 04 31 32 07 00");
	CHECK(lnxt_write_io_map(&m, 0x04030201, 0x3231, data, sizeof(data)) == 0);
	TELEGRAM(&m, "01 95 01 02 03 04 31 32 07 00 21 22 23 24 25 26 27");
	lnxt_boot_command(&m);
	TELEGRAM(&m, cat("01 97", field("Let's dance: SAMBA", 19), NULL));
	CHECK(lnxt_set_brick_name(&m, "NXT") == 0);
	TELEGRAM(&m, cat("01 98", field("NXT", 16), NULL));
	lnxt_get_bt_address(&m);
	TELEGRAM(&m, "01 9a");
	lnxt_get_device_info(&m);
	TELEGRAM(&m, "01 9b");
	lnxt_delete_user_flash(&m);
	TELEGRAM(&m, "01 a0");
	lnxt_poll_command_length(&m, 1);
	TELEGRAM(&m, "01 a1 01");
	CHECK(lnxt_poll_command(&m, 1, 9) == 0);
	TELEGRAM(&m, "01 a2 01 09");
	lnxt_bt_factory_reset(&m);
	TELEGRAM(&m, "01 a4");

	CHECK(lnxt_read(&m, 0, LNXT_READ_MAX + 1) == -EINVAL);
	CHECK(lnxt_read(&m, 0, 0) == -EINVAL);
	CHECK(lnxt_write(&m, 0, data, LNXT_WRITE_MAX + 1) == -EINVAL);
	CHECK(lnxt_read_io_map(&m, 0, 0, LNXT_IOMAP_MAX + 1) == -EINVAL);
	CHECK(lnxt_write_io_map(&m, 0, 0, data, LNXT_IOMAP_WRITE_MAX + 1) == -EINVAL);
	CHECK(lnxt_set_brick_name(&m, "sixteen-chars-xx") == -EINVAL);
	CHECK(lnxt_poll_command(&m, 0, LNXT_POLL_MAX + 1) == -EINVAL);
}

/* Check @reply (hex) against the request @m: the status, or -EBADMSG. */
static int reply(const struct lnxt_msg *m, uint8_t *buf, size_t *len, const char *hexs)
{
	*len = hex(buf, hexs);
	return lnxt_reply_check(m, buf, *len);
}

/* nxt-python's GetOutputState reply: port B, its fields counting up. */
#define GET_OUTPUT_STATE_REPLY \
	"02 06 00 01 9c 01 00 fb 20 01 02 03 04 11 12 13 14 21 22 23 24 31 32 33 34"

static void test_replies(void)
{
	struct lnxt_msg m;
	uint8_t r[LNXT_TELEGRAM_MAX];
	size_t n;
	struct lnxt_output o;
	struct lnxt_input in;
	struct lnxt_data d;
	struct lnxt_file f;
	struct lnxt_module mod;
	struct lnxt_versions v;
	struct lnxt_device_info info;
	uint16_t mv, written;
	uint32_t ms, id;
	uint8_t ready, handle;
	char name[LNXT_NAME_MAX + 1];

	lnxt_get_output_state(&m, 1);
	CHECK(reply(&m, r, &n, GET_OUTPUT_STATE_REPLY) == 0);
	CHECK(lnxt_parse_output_state(r, n, &o) == 0);
	CHECK(o.port == 1 && o.power == -100 && o.turn == -5 && o.run_state == 0x20);
	CHECK(o.tacho_limit == 0x04030201 && o.tacho_count == 0x14131211 &&
	      o.block_tacho_count == 0x24232221 && o.rotation_count == 0x34333231);
	/* A bad port: C0 and 22 zero bytes, or only the status. */
	CHECK(reply(&m, r, &n, cat("02 06 c0", field("", 22), NULL)) == 0xc0);
	CHECK(lnxt_parse_output_state(r, n, &o) == -EBADMSG);
	CHECK(reply(&m, r, &n, "02 06 be") == 0xbe);
	CHECK(reply(&m, r, &n, "02 06 00") == -EBADMSG);
	/* The whole reply, of another opcode. */
	CHECK(reply(&m, r, &n, GET_OUTPUT_STATE_REPLY) == 0);
	r[1] = LNXT_GET_INPUT_VALUES;
	CHECK(lnxt_reply_check(&m, r, n) == -EBADMSG);
	CHECK(reply(&m, r, &n, "01 06 00") == -EBADMSG);

	lnxt_get_input_values(&m, 2);
	CHECK(reply(&m, r, &n, "02 07 00 02 01 00 01 20 01 02 11 12 21 22 31 32") == 0);
	CHECK(lnxt_parse_input_values(r, n, &in) == 0);
	CHECK(in.port == 2 && in.valid && !in.calibrated && in.type == 1 && in.mode == 0x20);
	CHECK(in.raw == 0x0201 && in.normalized == 0x1211 && in.scaled == 0x2221 &&
	      in.calibrated_value == 0x3231);

	lnxt_get_battery_level(&m);
	CHECK(reply(&m, r, &n, "02 0b 00 28 23") == 0);
	CHECK(lnxt_parse_battery_level(r, n, &mv) == 0 && mv == 9000);

	lnxt_keep_alive(&m);
	CHECK(reply(&m, r, &n, "02 0d 00 c0 27 09 00") == 0);
	CHECK(lnxt_parse_keep_alive(r, n, &ms) == 0 && ms == 600000);

	lnxt_ls_get_status(&m, 2);
	CHECK(reply(&m, r, &n, "02 0e 00 07") == 0);
	CHECK(lnxt_parse_ls_get_status(r, n, &ready) == 0 && ready == 7);
	CHECK(reply(&m, r, &n, "02 0e c0") == 0xc0);

	lnxt_ls_read(&m, 2);
	CHECK(reply(&m, r, &n, "02 10 00 07 21 22 23 24 25 26 27 00 00 00 00 00 00 00 00 00")
	      == 0);
	CHECK(lnxt_parse_ls_read(r, n, &d) == 0 && d.len == 7 && d.data[6] == 0x27);
	CHECK(reply(&m, r, &n, "02 10 00 11 21 22 23 24 25 26 27 00 00 00 00 00 00 00 00 00")
	      == 0);
	CHECK(lnxt_parse_ls_read(r, n, &d) == -EBADMSG);	/* 17 bytes of 16 */

	lnxt_get_current_program_name(&m);
	CHECK(reply(&m, r, &n, cat("02 11 00", field("test.rxe", 20), NULL)) == 0);
	CHECK(lnxt_parse_program_name(r, n, name) == 0 && !strcmp(name, "test.rxe"));
	/* No NUL in the field: the name still ends. */
	CHECK(reply(&m, r, &n, cat("02 11 00", field("abcdefghijklmnopqrst", 20), NULL)) == 0);
	CHECK(lnxt_parse_program_name(r, n, name) == 0 && strlen(name) == LNXT_NAME_MAX);

	lnxt_message_read(&m, 10, 0, true);
	CHECK(reply(&m, r, &n, cat("02 13 00 00 08 21 22 23 24 25 26 27 00",
				   field("", 51), NULL)) == 0);
	CHECK(n == 64);
	CHECK(lnxt_parse_message_read(r, n, &d) == 0 && d.len == 7 && d.data[0] == 0x21);
	CHECK(reply(&m, r, &n, cat("02 13 40 00 00", field("", 59), NULL)) == 0x40);
	CHECK(!strcmp(lnxt_status_name(0x40), "mailbox empty"));

	lnxt_open_read(&m, "test.rxe");
	CHECK(reply(&m, r, &n, "02 80 00 42 01 02 03 04") == 0);
	CHECK(lnxt_parse_file(r, n, &f) == 0 && f.handle == 0x42 && f.size == 0x04030201);
	CHECK(reply(&m, r, &n, "02 80 87 00 00 00 00 00") == 0x87);
	CHECK(!strcmp(lnxt_status_name(0x87), "file not found"));

	lnxt_open_write(&m, "test.rxe", 7);
	CHECK(reply(&m, r, &n, "02 81 00 42") == 0);
	CHECK(lnxt_parse_handle(r, n, &handle) == 0 && handle == 0x42);

	lnxt_read(&m, 0x42, 7);
	CHECK(reply(&m, r, &n, "02 82 00 42 07 00 21 22 23 24 25 26 27") == 0);
	CHECK(lnxt_parse_read(r, n, &d) == 0 && d.handle == 0x42 && d.len == 7);
	CHECK(reply(&m, r, &n, "02 82 00 42 07 00 21 22") == -EBADMSG);

	lnxt_write(&m, 0x42, "!", 1);
	CHECK(reply(&m, r, &n, "02 83 00 42 07 00") == 0);
	CHECK(lnxt_parse_write(r, n, &handle, &written) == 0 && written == 7);

	lnxt_find_first(&m, "*.*");
	CHECK(reply(&m, r, &n, cat("02 86 00 42", field("test.rxe", 20), "01 02 03 04")) == 0);
	CHECK(lnxt_parse_file(r, n, &f) == 0 && !strcmp(f.name, "test.rxe") &&
	      f.size == 0x04030201);

	lnxt_get_versions(&m);
	CHECK(reply(&m, r, &n, "02 88 00 01 02 03 04") == 0);
	CHECK(lnxt_parse_versions(r, n, &v) == 0 && v.protocol_major == 2 &&
	      v.protocol_minor == 1 && v.firmware_major == 4 && v.firmware_minor == 3);

	lnxt_find_first_module(&m, "*.*");
	CHECK(reply(&m, r, &n, cat("02 90 00 42", field("Loader", 20),
				   "01 00 09 00 00 00 00 00 08 00")) == 0);
	CHECK(lnxt_parse_module(r, n, &mod) == 0 && !strcmp(mod.name, "Loader") &&
	      mod.id == 0x00090001 && mod.iomap_size == 8);

	lnxt_read_io_map(&m, 0x04030201, 0x3231, 7);
	CHECK(reply(&m, r, &n, "02 94 00 01 02 03 04 07 00 21 22 23 24 25 26 27") == 0);
	CHECK(lnxt_parse_read_io_map(r, n, &d) == 0 && d.id == 0x04030201 && d.len == 7);

	lnxt_write_io_map(&m, 0x04030201, 0x3231, "!", 1);
	CHECK(reply(&m, r, &n, "02 95 00 01 02 03 04 07 00") == 0);
	CHECK(lnxt_parse_write_io_map(r, n, &id, &written) == 0 && id == 0x04030201 &&
	      written == 7);

	lnxt_get_device_info(&m);
	CHECK(reply(&m, r, &n, cat("02 9b 00", field("NXT", 15),
				   "01 02 03 04 05 06 00 11 12 13 14 21 22 23 24")) == 0);
	CHECK(lnxt_parse_device_info(r, n, &info) == 0 && !strcmp(info.name, "NXT") &&
	      info.bt_address[5] == 6 && info.free_flash == 0x24232221);

	lnxt_poll_command(&m, 1, 9);
	CHECK(reply(&m, r, &n, "02 a2 00 01 07 21 22 23 24 25 26 27 00 00") == 0);
	CHECK(lnxt_parse_poll(r, n, &d) == 0 && d.len == 7 && d.handle == 1);

	lnxt_boot_command(&m);
	CHECK(reply(&m, r, &n, "02 97 00 59 65 73 00") == 0);
	CHECK(reply(&m, r, &n, "02 99 00 59 65 73 00") == -EBADMSG);

	CHECK(!lnxt_status_name(0x01));
	CHECK(!strcmp(lnxt_status_name(0xec), "no program running"));
}

static uint32_t rng_state = 0x2545f491;

static uint32_t rnd(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 17;
	rng_state ^= rng_state << 5;
	return rng_state;
}

/*
 * Replies come from a brick, or from whatever else answers on its node:
 * random ones, most with a reply's type byte and a known opcode, through
 * lnxt_reply_check() and every parser, with ASan and UBSan watching
 * (make check). What a parser accepts must be a reply of its own command
 * and say no more bytes than its buffer holds.
 */
static void test_random_replies(void)
{
	static const uint8_t ops[] = {
		0x00, 0x06, 0x07, 0x0b, 0x0d, 0x0e, 0x10, 0x11, 0x13, 0x19, 0x1b, 0x1c,
		0x1d, 0x1e, 0x20, 0x80, 0x81, 0x82, 0x83, 0x84, 0x86, 0x87, 0x88, 0x8c,
		0x90, 0x91, 0x94, 0x95, 0x9a, 0x9b, 0xa1, 0xa2, 0xff,
	};
	uint8_t r[LNXT_TELEGRAM_MAX + 8];
	struct lnxt_device_info info;
	struct lnxt_versions v;
	struct lnxt_module mod;
	struct lnxt_output o;
	struct lnxt_input in;
	struct lnxt_data d;
	struct lnxt_file f;
	struct lnxt_msg m;
	char name[LNXT_NAME_MAX + 1], bt[18];
	uint8_t b1, b2, addr[6];
	uint16_t u16;
	uint32_t u32;
	int i, bad = 0, accepted = 0;
	size_t len, k;

	for (i = 0; i < 200000; i++) {
		len = rnd() % (LNXT_TELEGRAM_MAX + 1);
		for (k = 0; k < len; k++)
			r[k] = rnd();
		if (len > 0 && rnd() % 8)
			r[0] = LNXT_REPLY;
		if (len > 1 && rnd() % 8)
			r[1] = ops[rnd() % sizeof(ops)];
		if (len > 2 && rnd() % 2)
			r[2] = 0;
		/* A request of the reply's opcode, its arguments random too. */
		memset(&m, 0, sizeof(m));
		m.len = 2 + rnd() % (LNXT_TELEGRAM_MAX - 1);
		for (k = 0; k < m.len; k++)
			m.buf[k] = rnd();
		m.buf[1] = len > 1 ? r[1] : 0;
		if (lnxt_reply_check(&m, r, len) >= 0)
			accepted++;
		d.len = 0;
		if (!lnxt_parse_ls_read(r, len, &d) || !lnxt_parse_message_read(r, len, &d) ||
		    !lnxt_parse_datalog_read(r, len, &d) || !lnxt_parse_read(r, len, &d) ||
		    !lnxt_parse_read_io_map(r, len, &d) || !lnxt_parse_poll(r, len, &d))
			bad += d.len > sizeof(d.data) || r[0] != LNXT_REPLY || r[2] != 0;
		lnxt_parse_output_state(r, len, &o);
		lnxt_parse_input_values(r, len, &in);
		lnxt_parse_battery_level(r, len, &u16);
		lnxt_parse_keep_alive(r, len, &u32);
		lnxt_parse_ls_get_status(r, len, &b1);
		lnxt_parse_program_name(r, len, name);
		bad += strlen(name) > LNXT_NAME_MAX;
		lnxt_parse_bt_count(r, len, &b1);
		lnxt_parse_bt_name(r, len, &b1, bt);
		lnxt_parse_property(r, len, &u32);
		if (!lnxt_parse_file(r, len, &f))
			bad += strlen(f.name) > LNXT_NAME_MAX;
		lnxt_parse_handle(r, len, &b1);
		lnxt_parse_write(r, len, &b1, &u16);
		lnxt_parse_versions(r, len, &v);
		if (!lnxt_parse_module(r, len, &mod))
			bad += strlen(mod.name) > LNXT_NAME_MAX;
		lnxt_parse_write_io_map(r, len, &u32, &u16);
		lnxt_parse_bt_address(r, len, addr);
		if (!lnxt_parse_device_info(r, len, &info))
			bad += strlen(info.name) > LNXT_BRICK_NAME_MAX;
		lnxt_parse_poll_length(r, len, &b1, &b2);
	}
	CHECK(bad == 0);
	/* The sweep reached the accepting paths, not only the refusals. */
	CHECK(accepted > 1000);
}

int main(void)
{
	test_direct();
	test_direct_refused();
	test_system();
	test_replies();
	test_random_replies();
	printf("test_legonxt: %d checks, %d failed\n", checks, failures);
	return failures ? 1 : 0;
}
