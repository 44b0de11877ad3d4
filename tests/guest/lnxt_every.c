// SPDX-License-Identifier: GPL-2.0
/*
 * Every direct and system command of liblegonxt against a brick: each
 * telegram built by the library, sent with NXT_IOC_TRANSACT, its reply
 * checked by lnxt_reply_check() and, when its status is 0, decoded by the
 * command's parser. One line a command on stdout:
 *
 *   NAME STATUS FIELDS...
 *
 * (STATUS in hex; FIELDS what the parser found), for the test to compare
 * with what the emulated firmware did (tests/guest/test_liblegonxt_brick.py).
 * Exit status 1 if a reply is not one lnxt_reply_check() accepts, or a
 * parser refuses a reply of status 0; 2 on a usage or system error.
 *
 *   lnxt_every /dev/nxtN            all but BootCommand
 *   lnxt_every /dev/nxtN boot       BootCommand alone (the brick then leaves)
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <linux/lego_nxt.h>

#include "legonxt.h"

/* A builder that refuses its arguments is this program's error. */
#define BUILD(call)							\
	do {								\
		if ((call) < 0) {					\
			fprintf(stderr, "%s: refused\n", #call);	\
			exit(2);					\
		}							\
	} while (0)

static int fd;
static int bad;
static uint8_t reply[NXT_TELEGRAM_MAX];
static size_t reply_len;

/* Send @m; its status, or -1 (counted as a failure) for a refused reply. */
static int run(const char *name, const struct lnxt_msg *m)
{
	struct nxt_transaction t;
	int status;

	memset(&t, 0, sizeof(t));
	memcpy(t.telegram, m->buf, m->len);
	t.length = m->len;
	if (ioctl(fd, NXT_IOC_TRANSACT, &t) < 0) {
		fprintf(stderr, "%s: NXT_IOC_TRANSACT: %s\n", name, strerror(errno));
		exit(2);
	}
	memcpy(reply, t.reply, sizeof(reply));
	reply_len = t.reply_length;
	status = lnxt_reply_check(m, reply, reply_len);
	if (status < 0) {
		fprintf(stderr, "%s: reply of %zu bytes refused\n", name, reply_len);
		bad++;
		return -1;
	}
	printf("%s %02x", name, status);
	return status;
}

/* A parser's verdict on a reply of status 0. */
static void parsed(const char *name, int ret)
{
	if (ret) {
		fprintf(stderr, "%s: the parser refused the reply: %d\n", name, ret);
		bad++;
	}
}

static void end(void)
{
	putchar('\n');
}

static void hexdump(const uint8_t *p, size_t n)
{
	printf(" ");
	if (!n)
		printf("-");
	while (n--)
		printf("%02x", *p++);
}

static void direct_outputs(void)
{
	struct lnxt_output o = { .port = 1, .power = 40, .mode = 0x01,
				 .run_state = 0x20, .tacho_limit = 90 };
	struct lnxt_msg m;

	BUILD(lnxt_set_output_state(&m, &o));
	run("set_output_state", &m);
	end();
	BUILD(lnxt_get_output_state(&m, 1));
	if (run("get_output_state", &m) == 0) {
		parsed("get_output_state", lnxt_parse_output_state(reply, reply_len, &o));
		printf(" port=%u power=%d mode=%u limit=%u", o.port, o.power, o.mode,
		       o.tacho_limit);
	}
	end();
	BUILD(lnxt_reset_motor_position(&m, 1, false));
	run("reset_motor_position", &m);
	end();
	BUILD(lnxt_update_reset_count(&m, 1));
	run("update_reset_count", &m);
	end();
}

static void direct_inputs(void)
{
	static const uint8_t tx[2] = { 0x02, 0x42 };	/* the distance register */
	struct lnxt_input in;
	struct lnxt_data d;
	struct lnxt_msg m;
	uint8_t ready = 0;
	int i, status = -1;

	BUILD(lnxt_set_input_mode(&m, 0, 0x01, 0x20));		/* SWITCH, BOOLEAN */
	run("set_input_mode", &m);
	end();
	BUILD(lnxt_get_input_values(&m, 0));
	if (run("get_input_values", &m) == 0) {
		parsed("get_input_values", lnxt_parse_input_values(reply, reply_len, &in));
		printf(" port=%u type=%u mode=%u", in.port, in.type, in.mode);
	}
	end();
	BUILD(lnxt_reset_input_scaled_value(&m, 0));
	run("reset_input_scaled_value", &m);
	end();
	/* The ultrasonic sensor on port 4, LOWSPEED_9V. */
	BUILD(lnxt_set_input_mode(&m, 3, 0x0b, 0x00));
	run("set_input_mode_lowspeed", &m);
	end();
	/*
	 * The port takes a while to set up after SetInputMode, and the
	 * sensor to answer: the brick says so (0x20 pending, 0xe0 busy).
	 */
	for (i = 0; i < 100 && status != 0; i++) {
		BUILD(lnxt_ls_write(&m, 3, tx, sizeof(tx), 1));
		status = run("ls_write", &m);
		end();
		if (status)
			usleep(5000);
	}
	for (i = 0, status = -1; i < 100 && (status != 0 || !ready); i++) {
		BUILD(lnxt_ls_get_status(&m, 3));
		status = run("ls_get_status", &m);
		if (status == 0) {
			parsed("ls_get_status", lnxt_parse_ls_get_status(reply, reply_len, &ready));
			printf(" ready=%u", ready);
		}
		end();
		if (status || !ready)
			usleep(5000);
	}
	BUILD(lnxt_ls_read(&m, 3));
	if (run("ls_read", &m) == 0) {
		parsed("ls_read", lnxt_parse_ls_read(reply, reply_len, &d));
		hexdump(d.data, d.len);
	}
	end();
}

/* The Bluetooth queries: the contacts' and the connections' count, and a name. */
static void bt_count(const char *name, const struct lnxt_msg *m)
{
	uint8_t count;

	if (run(name, m) == 0) {
		parsed(name, lnxt_parse_bt_count(reply, reply_len, &count));
		printf(" count=%u", count);
	}
	end();
}

static void bt_name(const char *name, const struct lnxt_msg *m)
{
	uint8_t type;
	char bt[18];

	if (run(name, m) == 0) {
		parsed(name, lnxt_parse_bt_name(reply, reply_len, &type, bt));
		printf(" type=%u name=%s", type, bt);
	}
	end();
}

static void direct_others(void)
{
	char name[LNXT_NAME_MAX + 1];
	struct lnxt_data d;
	struct lnxt_msg m;
	uint32_t value;
	uint16_t mv;

	lnxt_get_battery_level(&m);
	if (run("get_battery_level", &m) == 0) {
		parsed("get_battery_level", lnxt_parse_battery_level(reply, reply_len, &mv));
		printf(" mv=%u", mv);
	}
	end();
	lnxt_keep_alive(&m);
	if (run("keep_alive", &m) == 0) {
		parsed("keep_alive", lnxt_parse_keep_alive(reply, reply_len, &value));
		printf(" sleep_ms=%u", value);
	}
	end();
	lnxt_play_tone(&m, 440, 50);
	run("play_tone", &m);
	end();
	BUILD(lnxt_play_sound_file(&m, false, "nosuch.rso"));
	run("play_sound_file", &m);
	end();
	lnxt_stop_sound_playback(&m);
	run("stop_sound_playback", &m);
	end();
	BUILD(lnxt_start_program(&m, "nosuch.rxe"));
	run("start_program", &m);
	end();
	lnxt_stop_program(&m);
	run("stop_program", &m);
	end();
	lnxt_get_current_program_name(&m);
	if (run("get_current_program_name", &m) == 0) {
		parsed("get_current_program_name", lnxt_parse_program_name(reply, reply_len, name));
		printf(" %s", name);
	}
	end();
	BUILD(lnxt_message_write(&m, 1, "hi", 3));
	run("message_write", &m);
	end();
	BUILD(lnxt_message_read(&m, 11, 1, true));
	if (run("message_read", &m) == 0) {
		parsed("message_read", lnxt_parse_message_read(reply, reply_len, &d));
		hexdump(d.data, d.len);
	}
	end();
	lnxt_datalog_set_times(&m, 1000);
	run("datalog_set_times", &m);
	end();
	lnxt_datalog_read(&m, false);
	if (run("datalog_read", &m) == 0) {
		parsed("datalog_read", lnxt_parse_datalog_read(reply, reply_len, &d));
		hexdump(d.data, d.len);
	}
	end();
	lnxt_bt_get_contact_count(&m);
	bt_count("bt_get_contact_count", &m);
	lnxt_bt_get_contact_name(&m, 0);
	bt_name("bt_get_contact_name", &m);
	lnxt_bt_get_conn_count(&m);
	bt_count("bt_get_conn_count", &m);
	lnxt_bt_get_conn_name(&m, 0);
	bt_name("bt_get_conn_name", &m);
	BUILD(lnxt_set_property(&m, LNXT_PROP_VOLUME, 2));
	run("set_property", &m);
	end();
	BUILD(lnxt_get_property(&m, LNXT_PROP_VOLUME));
	if (run("get_property", &m) == 0) {
		parsed("get_property", lnxt_parse_property(reply, reply_len, &value));
		printf(" value=%u", value);
	}
	end();
}

static void system_info(void)
{
	struct lnxt_device_info info;
	struct lnxt_versions v;
	struct lnxt_msg m;
	uint8_t addr[6];

	lnxt_get_versions(&m);
	if (run("get_versions", &m) == 0) {
		parsed("get_versions", lnxt_parse_versions(reply, reply_len, &v));
		printf(" protocol=%u.%u firmware=%u.%u", v.protocol_major, v.protocol_minor,
		       v.firmware_major, v.firmware_minor);
	}
	end();
	BUILD(lnxt_set_brick_name(&m, "every"));
	run("set_brick_name", &m);
	end();
	lnxt_get_device_info(&m);
	if (run("get_device_info", &m) == 0) {
		parsed("get_device_info", lnxt_parse_device_info(reply, reply_len, &info));
		printf(" name=%s", info.name);
		hexdump(info.bt_address, 6);
	}
	end();
	lnxt_get_bt_address(&m);
	if (run("get_bt_address", &m) == 0) {
		parsed("get_bt_address", lnxt_parse_bt_address(reply, reply_len, addr));
		hexdump(addr, 6);
	}
	end();
}

/* Open with @open_msg (its reply is a handle), write @data, close. */
static void write_file(const char *what, const struct lnxt_msg *open_msg,
		       const char *data)
{
	char name[64];
	struct lnxt_msg m;
	uint16_t written;
	uint8_t h = 0;

	snprintf(name, sizeof(name), "open_%s", what);
	if (run(name, open_msg) == 0) {
		parsed(name, lnxt_parse_handle(reply, reply_len, &h));
		printf(" handle=%u", h);
	}
	end();
	BUILD(lnxt_write(&m, h, data, strlen(data)));
	if (run("write", &m) == 0) {
		parsed("write", lnxt_parse_write(reply, reply_len, &h, &written));
		printf(" written=%u", written);
	}
	end();
	lnxt_close(&m, h);
	if (run("close", &m) == 0)
		parsed("close", lnxt_parse_handle(reply, reply_len, &h));
	end();
}

static void system_files(void)
{
	struct lnxt_file f;
	struct lnxt_data d;
	struct lnxt_msg m;
	uint8_t h = 0;

	BUILD(lnxt_open_write(&m, "every.txt", 10));
	write_file("write", &m, "0123456789");
	BUILD(lnxt_open_write_linear(&m, "every.rxe", 4));
	write_file("write_linear", &m, "abcd");
	BUILD(lnxt_open_write_data(&m, "every.rdt", 16));
	write_file("write_data", &m, "wxyz");

	BUILD(lnxt_open_append_data(&m, "every.rdt"));
	if (run("open_append_data", &m) == 0) {
		parsed("open_append_data", lnxt_parse_file(reply, reply_len, &f));
		h = f.handle;
		printf(" handle=%u room=%u", f.handle, f.size);
	}
	end();
	lnxt_crop_data_file(&m, h);
	if (run("crop_data_file", &m) == 0)
		parsed("crop_data_file", lnxt_parse_handle(reply, reply_len, &h));
	end();
	lnxt_close(&m, h);
	run("close", &m);
	end();

	BUILD(lnxt_open_read(&m, "every.txt"));
	if (run("open_read", &m) == 0) {
		parsed("open_read", lnxt_parse_file(reply, reply_len, &f));
		h = f.handle;
		printf(" size=%u", f.size);
	}
	end();
	BUILD(lnxt_read(&m, h, 10));
	if (run("read", &m) == 0) {
		parsed("read", lnxt_parse_read(reply, reply_len, &d));
		hexdump(d.data, d.len);
	}
	end();
	lnxt_close(&m, h);
	run("close", &m);
	end();

	BUILD(lnxt_find_first(&m, "every.*"));
	if (run("find_first", &m) == 0) {
		parsed("find_first", lnxt_parse_file(reply, reply_len, &f));
		h = f.handle;
		printf(" %s size=%u", f.name, f.size);
	}
	end();
	lnxt_find_next(&m, h);
	if (run("find_next", &m) == 0) {
		parsed("find_next", lnxt_parse_file(reply, reply_len, &f));
		printf(" %s size=%u", f.name, f.size);
	}
	end();
	lnxt_close(&m, h);
	run("close", &m);
	end();

	BUILD(lnxt_delete(&m, "every.rxe"));
	run("delete", &m);
	end();
}

static void system_modules(void)
{
	uint8_t map[2] = { 0, 0 };
	struct lnxt_module mod;
	struct lnxt_data d;
	struct lnxt_msg m;
	uint16_t written;
	uint32_t id = 0;
	uint8_t h = 0, buffer, length;

	BUILD(lnxt_find_first_module(&m, "*.*"));
	if (run("find_first_module", &m) == 0) {
		parsed("find_first_module", lnxt_parse_module(reply, reply_len, &mod));
		h = mod.handle;
		id = mod.id;
		printf(" %s id=%08x iomap=%u", mod.name, mod.id, mod.iomap_size);
	}
	end();
	BUILD(lnxt_read_io_map(&m, id, 0, 2));
	if (run("read_io_map", &m) == 0) {
		parsed("read_io_map", lnxt_parse_read_io_map(reply, reply_len, &d));
		hexdump(d.data, d.len);
		if (d.len == sizeof(map))
			memcpy(map, d.data, sizeof(map));
	}
	end();
	/* The same bytes back: the module's state is left as it was. */
	BUILD(lnxt_write_io_map(&m, id, 0, map, sizeof(map)));
	if (run("write_io_map", &m) == 0) {
		parsed("write_io_map", lnxt_parse_write_io_map(reply, reply_len, &id, &written));
		printf(" written=%u", written);
	}
	end();
	lnxt_find_next_module(&m, h);
	if (run("find_next_module", &m) == 0) {
		parsed("find_next_module", lnxt_parse_module(reply, reply_len, &mod));
		printf(" %s", mod.name);
	}
	end();
	lnxt_close_module_handle(&m, h);
	if (run("close_module_handle", &m) == 0)
		parsed("close_module_handle", lnxt_parse_handle(reply, reply_len, &h));
	end();

	lnxt_poll_command_length(&m, 0);
	if (run("poll_command_length", &m) == 0) {
		parsed("poll_command_length",
		       lnxt_parse_poll_length(reply, reply_len, &buffer, &length));
		printf(" buffer=%u length=%u", buffer, length);
	}
	end();
	BUILD(lnxt_poll_command(&m, 0, 8));
	if (run("poll_command", &m) == 0) {
		parsed("poll_command", lnxt_parse_poll(reply, reply_len, &d));
		hexdump(d.data, d.len);
	}
	end();
}

int main(int argc, char **argv)
{
	uint32_t timeout_ms = 5000;
	struct lnxt_msg m;

	if (argc < 2) {
		fprintf(stderr, "usage: %s /dev/nxtN [boot]\n", argv[0]);
		return 2;
	}
	fd = open(argv[1], O_RDWR);
	if (fd < 0) {
		perror(argv[1]);
		return 2;
	}
	/* DeleteUserFlash takes the brick about a second (LEGO's firmware, the emulator). */
	if (ioctl(fd, NXT_IOC_SET_TIMEOUT, &timeout_ms) < 0) {
		perror("NXT_IOC_SET_TIMEOUT");
		return 2;
	}
	if (argc > 2 && !strcmp(argv[2], "boot")) {
		lnxt_boot_command(&m);
		if (run("boot_command", &m) == 0)
			hexdump(reply + 3, reply_len - 3);
		end();
		return bad ? 1 : 0;
	}
	direct_others();
	direct_outputs();
	direct_inputs();
	system_info();
	system_files();
	system_modules();
	lnxt_delete_user_flash(&m);
	run("delete_user_flash", &m);
	end();
	lnxt_bt_factory_reset(&m);
	run("bt_factory_reset", &m);
	end();
	fflush(stdout);
	return bad ? 1 : 0;
}
