// SPDX-License-Identifier: GPL-2.0
/*
 * KUnit tests for the NXT telegram core.
 *
 * The request bytes are those that nxt-python 3.5.1's test suite
 * (tests/test_brick.py) asserts, and those the firmware reads (research
 * nxt.md), so that the driver refuses no telegram the most used host
 * library sends, and lets through none that the firmware would complete
 * with stale bytes.
 */
#include <kunit/test.h>
#include <linux/module.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "nxt_proto.h"

static void nxt_test_telegram_types(struct kunit *test)
{
	static const u8 battery[] = { 0x00, 0x0b };
	static const u8 battery_noreply[] = { 0x80, 0x0b };
	static const u8 firmware[] = { 0x01, 0x88 };
	static const u8 firmware_noreply[] = { 0x81, 0x88 };
	/* A reply, or garbage, is not something a host sends. */
	static const u8 reply[] = { 0x02, 0x0b };
	static const u8 garbage[] = { 0x42, 0x0b };

	KUNIT_EXPECT_EQ(test, nxt_telegram_check(battery, sizeof(battery)), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(battery_noreply, sizeof(battery_noreply)), 0);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(firmware, sizeof(firmware)), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(firmware_noreply, sizeof(firmware_noreply)), 0);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(reply, sizeof(reply)), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(garbage, sizeof(garbage)), -EINVAL);
}

static void nxt_test_telegram_lengths(struct kunit *test)
{
	/* GetBatteryLevel: two bytes are all of it; the rest is ignored. */
	u8 buf[NXT_TELEGRAM_MAX + 1] = { NXT_DIRECT_CMD, NXT_GET_BATTERY_LEVEL };

	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 0), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 1), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 2), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, NXT_TELEGRAM_MAX), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, NXT_TELEGRAM_MAX + 1), -EMSGSIZE);
}

struct nxt_request_case {
	const char *what;
	u8 tg[NXT_TELEGRAM_MAX];
	u8 len;		/* the shortest complete telegram */
};

/*
 * Requests as nxt-python 3.5.1 sends them (tests/test_brick.py) and as the
 * firmware reads them (research nxt.md, 2.2 and 2.3): each is complete at
 * its length, and one byte less would leave the firmware an argument from
 * an earlier telegram. Strings end at their NUL.
 */
static const struct nxt_request_case nxt_request_cases[] = {
	{ "StartProgram", { 0x00, 0x00, 't', '.', 'r', 'x', 'e', 0 }, 8 },
	{ "StopProgram", { 0x00, 0x01 }, 2 },
	{ "PlaySoundFile", { 0x80, 0x02, 0x01, 'a', '.', 'r', 's', 'o', 0 }, 9 },
	{ "PlayTone", { 0x80, 0x03, 0xb8, 0x01, 0xe8, 0x03 }, 6 },
	{ "SetOutputState", { 0x80, 0x04, 0x01, 0x9c, 0x01, 0x00, 0xfb, 0x20,
			      0x01, 0x02, 0x03, 0x04 }, 12 },
	{ "SetInputMode", { 0x80, 0x05, 0x02, 0x01, 0x20 }, 5 },
	{ "GetOutputState", { 0x00, 0x06, 0x01 }, 3 },
	{ "GetInputValues", { 0x00, 0x07, 0x02 }, 3 },
	{ "ResetInputScaledValue", { 0x00, 0x08, 0x02 }, 3 },
	{ "MessageWrite", { 0x00, 0x09, 0x03, 0x08, 0x21, 0x22, 0x23, 0x24,
			    0x25, 0x26, 0x27, 0x00 }, 12 },
	{ "ResetMotorPosition", { 0x00, 0x0a, 0x01, 0x01 }, 4 },
	{ "GetBatteryLevel", { 0x00, 0x0b }, 2 },
	{ "KeepAlive", { 0x00, 0x0d }, 2 },
	{ "LSGetStatus", { 0x00, 0x0e, 0x02 }, 3 },
	{ "LSWrite", { 0x00, 0x0f, 0x02, 0x07, 0x09, 0x21, 0x22, 0x23, 0x24,
		       0x25, 0x26, 0x27 }, 12 },
	{ "LSRead", { 0x00, 0x10, 0x02 }, 3 },
	{ "MessageRead", { 0x00, 0x13, 0x0a, 0x00, 0x01 }, 5 },
	{ "DatalogSetTimes", { 0x00, 0x1a, 1, 2, 3, 4 }, 6 },
	{ "SetProperty volume", { 0x00, 0x1f, 0x01, 0x04 }, 4 },
	{ "SetProperty sleep", { 0x00, 0x1f, 0x02, 0x10, 0x27, 0x00, 0x00 }, 7 },
	{ "OpenRead", { 0x01, 0x80, 'f', 0 }, 4 },
	{ "OpenWrite", { 0x01, 0x81, 'f', [22] = 0x01, 0x02, 0x03, 0x04 }, 26 },
	{ "Read", { 0x01, 0x82, 0x42, 0x07, 0x00 }, 5 },
	{ "Write", { 0x01, 0x83, 0x42 }, 3 },
	{ "Close", { 0x01, 0x84, 0x42 }, 3 },
	{ "Delete", { 0x01, 0x85, 'f', 0 }, 4 },
	{ "GetVersions", { 0x01, 0x88 }, 2 },
	{ "OpenWriteData", { 0x01, 0x8b, 'f', [22] = 0x01, 0x02, 0x03, 0x04 }, 26 },
	{ "ReadIOMap", { 0x01, 0x94, 0x01, 0x02, 0x03, 0x04, 0x31, 0x32, 0x41,
			 0x42 }, 10 },
	{ "WriteIOMap", { 0x81, 0x95, 0x01, 0x02, 0x03, 0x04, 0x31, 0x32, 0x02,
			  0x00, 0x21, 0x22 }, 12 },
	{ "BootCommand", { 0x01, 0x97, 'L', 'e', 't', '\'', 's', ' ', 'd', 'a',
			   'n', 'c', 'e', ':', ' ', 'S', 'A', 'M', 'B', 'A',
			   0 }, 21 },
	{ "SetBrickName", { 0x01, 0x98, 'N', 'X', 'T', 0 }, 6 },
	{ "GetDeviceInfo", { 0x01, 0x9b }, 2 },
	{ "DeleteUserFlash", { 0x01, 0xa0 }, 2 },
	{ "PollCommand", { 0x01, 0xa2, 0x01, 0x09 }, 4 },
};

static void nxt_test_request_lengths(struct kunit *test)
{
	const struct nxt_request_case *c;
	size_t i;

	for (i = 0; i < ARRAY_SIZE(nxt_request_cases); i++) {
		c = &nxt_request_cases[i];
		KUNIT_EXPECT_TRUE_MSG(test, nxt_request_complete(c->tg, c->len), "%s", c->what);
		KUNIT_EXPECT_GE_MSG(test, nxt_telegram_check(c->tg, c->len), 0, "%s", c->what);
		KUNIT_EXPECT_FALSE_MSG(test, nxt_request_complete(c->tg, c->len - 1),
				       "%s, one byte short", c->what);
		if (c->len > NXT_TELEGRAM_MIN)
			KUNIT_EXPECT_EQ_MSG(test, nxt_telegram_check(c->tg, c->len - 1),
					    -EINVAL, "%s, one byte short", c->what);
	}
}

/* Strings must end in the telegram; counts must not reach past its end. */
static void nxt_test_request_strings_and_counts(struct kunit *test)
{
	/* The NUL of a name, not its 20 bytes, ends it: nxt-python's SetBrickName. */
	static const u8 name15[17] = { 0x01, 0x98, 'N', 'X', 'T' };
	static const u8 no_nul[] = { 0x01, 0x98, 'N', 'X', 'T' };
	/* 15 characters, no NUL: what the firmware reads of a brick name. */
	static const u8 name_full[17] = { 0x01, 0x98, 'A', 'B', 'C', 'D', 'E', 'F', 'G',
					  'H', 'I', 'J', 'K', 'L', 'M', 'N', 'O' };
	static const u8 run_no_nul[] = { 0x00, 0x00, 'a', '.', 'r', 'x', 'e' };
	/* MessageWrite of 8 bytes with 7 sent; LSWrite of 3 bytes with 2. */
	static const u8 msg_short[] = { 0x00, 0x09, 0x03, 0x08, 'a', 'b', 'c', 'd', 'e', 'f', 0 };
	static const u8 ls_short[] = { 0x00, 0x0f, 0x00, 0x03, 0x01, 0x02, 0x42 };
	static const u8 iomap_short[] = { 0x01, 0x95, 1, 2, 3, 4, 0, 0, 0x03, 0x00, 0x21, 0x22 };
	/* Unknown opcodes: the firmware answers them with an error. */
	static const u8 unknown_direct[] = { 0x00, 0x12 };
	static const u8 unknown_system[] = { 0x01, 0xa3 };
	static const u8 nxj_packet_mode[] = { 0x01, 0xff };

	KUNIT_EXPECT_TRUE(test, nxt_request_complete(name15, sizeof(name15)));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(no_nul, sizeof(no_nul)));
	KUNIT_EXPECT_TRUE(test, nxt_request_complete(name_full, sizeof(name_full)));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(name_full, sizeof(name_full) - 1));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(run_no_nul, sizeof(run_no_nul)));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(msg_short, sizeof(msg_short)));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(ls_short, sizeof(ls_short)));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(iomap_short, sizeof(iomap_short)));
	KUNIT_EXPECT_TRUE(test, nxt_request_complete(unknown_direct, 2));
	KUNIT_EXPECT_TRUE(test, nxt_request_complete(unknown_system, 2));
	KUNIT_EXPECT_TRUE(test, nxt_request_complete(nxj_packet_mode, 2));
	/* A system opcode below 0x80 is no system command the firmware knows. */
	KUNIT_EXPECT_TRUE(test, nxt_request_complete((const u8[]){ 0x01, 0x01 }, 2));
}

/*
 * What the sysfs attributes show comes from the replies that passed, and
 * nothing else: not from error replies, replies to other commands, or
 * replies that do not answer the telegram.
 */
static void nxt_test_brick_info(struct kunit *test)
{
	static const u8 versions[] = { 0x01, 0x88 };
	static const u8 v129[] = { 0x02, 0x88, 0x00, 0x7c, 0x01, 0x1d, 0x01 };
	static const u8 device[] = { 0x01, 0x9b };
	static const u8 info_reply[33] = {
		0x02, 0x9b, 0x00, 'N', 'X', 'T', 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
		0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x00, 0, 0, 0, 0,
		0x00, 0x80, 0x01, 0x00 };
	static const u8 battery[] = { 0x00, 0x0b };
	static const u8 battery_reply[] = { 0x02, 0x0b, 0x00, 0x28, 0x23 };
	static const u8 battery_error[] = { 0x02, 0x0b, 0xbd, 0x00, 0x00 };
	static const u8 keep_alive[] = { 0x00, 0x0d };
	static const u8 keep_alive_reply[] = { 0x02, 0x0d, 0x00, 0x28, 0x23, 0, 0 };
	static const u8 rename[] = { 0x01, 0x98, 'R', 0 };
	static const u8 rename_noreply[] = { 0x81, 0x98, 'R', 0 };
	static const u8 write[] = { 0x01, 0x83, 0x42, 'x' };
	static const u8 read[] = { 0x01, 0x82, 0x42, 0x07, 0x00 };
	struct nxt_brick_info info = { };

	nxt_info_note_reply(&info, battery, 2, battery_error, sizeof(battery_error));
	nxt_info_note_reply(&info, keep_alive, 2, keep_alive_reply, sizeof(keep_alive_reply));
	/* A reply to GetBatteryLevel that came for another command. */
	nxt_info_note_reply(&info, keep_alive, 2, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_FALSE(test, info.have_battery);
	KUNIT_EXPECT_FALSE(test, info.have_versions);
	KUNIT_EXPECT_FALSE(test, info.have_device);

	nxt_info_note_reply(&info, battery, 2, battery_reply, sizeof(battery_reply));
	KUNIT_EXPECT_TRUE(test, info.have_battery);
	KUNIT_EXPECT_EQ(test, info.battery_mv, 9000);
	/* An error reply later keeps the last reading. */
	nxt_info_note_reply(&info, battery, 2, battery_error, sizeof(battery_error));
	KUNIT_EXPECT_EQ(test, info.battery_mv, 9000);

	nxt_info_note_reply(&info, versions, 2, v129, 6);
	KUNIT_EXPECT_FALSE(test, info.have_versions);
	nxt_info_note_reply(&info, versions, 2, v129, sizeof(v129));
	KUNIT_EXPECT_TRUE(test, info.have_versions);
	KUNIT_EXPECT_EQ(test, info.firmware[0], 1);
	KUNIT_EXPECT_EQ(test, info.firmware[1], 29);
	KUNIT_EXPECT_EQ(test, info.protocol[1], 124);

	nxt_info_note_reply(&info, device, 2, info_reply, sizeof(info_reply));
	KUNIT_EXPECT_TRUE(test, info.have_device);
	KUNIT_EXPECT_STREQ(test, info.device.name, "NXT");
	KUNIT_EXPECT_EQ(test, info.device.free_flash, 0x18000U);

	/* Commands that change the name or the free flash make them unknown. */
	nxt_info_note_sent(&info, read, sizeof(read));
	KUNIT_EXPECT_TRUE(test, info.have_device);
	nxt_info_note_sent(&info, write, sizeof(write));
	KUNIT_EXPECT_FALSE(test, info.have_device);
	nxt_info_note_reply(&info, device, 2, info_reply, sizeof(info_reply));
	nxt_info_note_sent(&info, rename, sizeof(rename));
	KUNIT_EXPECT_FALSE(test, info.have_device);
	nxt_info_note_reply(&info, device, 2, info_reply, sizeof(info_reply));
	nxt_info_note_sent(&info, rename_noreply, sizeof(rename_noreply));
	KUNIT_EXPECT_FALSE(test, info.have_device);
	/* The rest stays. */
	KUNIT_EXPECT_TRUE(test, info.have_battery);
	KUNIT_EXPECT_TRUE(test, info.have_versions);
}

static void nxt_test_reply_lengths(struct kunit *test)
{
	static const u8 versions[] = { 0x01, 0x88 };
	static const u8 device_info[] = { 0x01, 0x9b };
	/* Read 7 bytes, 100 bytes (capped to fit 64), and a stale count. */
	static const u8 read7[] = { 0x01, 0x82, 0x42, 0x07, 0x00 };
	static const u8 read100[] = { 0x01, 0x82, 0x42, 0x64, 0x00 };
	static const u8 read_short[] = { 0x01, 0x82, 0x42 };
	static const u8 iomap[] = { 0x01, 0x94, 0x01, 0x02, 0x03, 0x04, 0x31, 0x32, 0x07, 0x00 };
	static const u8 poll[] = { 0x01, 0xa2, 0x01, 0x09 };
	static const u8 sleep_prop[] = { 0x00, 0x20, 0x02 };
	static const u8 volume_prop[] = { 0x00, 0x20, 0x01 };
	static const u8 unknown_direct[] = { 0x00, 0x12 };
	static const u8 unknown_system[] = { 0x01, 0xa3 };
	static const u8 noreply[] = { 0x80, 0x0b };

	KUNIT_EXPECT_EQ(test, nxt_reply_length(versions, 2), 7U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(device_info, 2), 33U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(read7, sizeof(read7)), 13U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(read100, sizeof(read100)), 64U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(read_short, sizeof(read_short)), 0U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(iomap, sizeof(iomap)), 16U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(poll, sizeof(poll)), 14U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(sleep_prop, sizeof(sleep_prop)), 7U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(volume_prop, sizeof(volume_prop)), 4U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(unknown_direct, 2), 0U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(unknown_system, 2), 0U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(noreply, 2), 0U);
}

/* nxt-python's bad replies, and the firmware's odd but valid ones. */
static void nxt_test_reply_check(struct kunit *test)
{
	static const u8 boot[] = { 0x01, 0x97 };
	static const u8 not_reply[] = { 0x01, 0x97, 0x00, 'Y', 'e', 's', 0 };
	static const u8 wrong_opcode[] = { 0x02, 0x99, 0x00, 'Y', 'e', 's', 0 };
	static const u8 odd_status[] = { 0x02, 0x97, 0x99, 'Y', 'e', 's', 0 };
	static const u8 battery[] = { 0x00, 0x0b };
	static const u8 battery_ok[] = { 0x02, 0x0b, 0x00, 0x84, 0x1c };
	static const u8 battery_short[] = { 0x02, 0x0b, 0x00, 0x84 };
	static const u8 battery_two[] = { 0x02, 0x0b };
	u8 battery_long[64] = { 0x02, 0x0b, 0x00, 0x84, 0x1c };
	static const u8 ls_status[] = { 0x00, 0x0e, 0x07 };
	static const u8 ls_bad_port[] = { 0x02, 0x0e, 0xc0 };
	static const u8 get_button[] = { 0x00, 0x12 };
	static const u8 unknown_op[] = { 0x02, 0x12, 0xbe };
	static const u8 get_output[] = { 0x00, 0x06, 0x05 };
	u8 bad_port_full[25] = { 0x02, 0x06, 0xc0 };
	static const u8 rename[] = { 0x01, 0xa3, 0x41, 0x42 };
	static const u8 rename_stale[] = { 0x02, 0xa3, 0x00, 0x11, 0x22, 0x33 };

	KUNIT_EXPECT_EQ(test, nxt_reply_check(boot, 2, not_reply, sizeof(not_reply)), -ENOMSG);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(boot, 2, wrong_opcode, sizeof(wrong_opcode)),
			-ENOMSG);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(boot, 2, odd_status, sizeof(odd_status)), 0x99);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(battery, 2, battery_ok, sizeof(battery_ok)), 0);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(battery, 2, battery_short, sizeof(battery_short)),
			-EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(battery, 2, battery_two, sizeof(battery_two)),
			-EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(battery, 2, battery_long, sizeof(battery_long)),
			-EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(ls_status, 3, ls_bad_port, 3), 0xc0);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_button, 2, unknown_op, 3), 0xbe);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_output, 3, bad_port_full,
					      sizeof(bad_port_full)), 0xc0);
	/* An error reply longer than the command's replies is still wrong. */
	bad_port_full[2] = 0x00;
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_output, 3, bad_port_full, 24), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(rename, sizeof(rename), rename_stale,
					      sizeof(rename_stale)), 0);
}

/*
 * A successful reply to a command that echoes a port or an inbox answers
 * only the telegram that asked for that port or inbox: a stale reply to the
 * same command for another one is not taken for it.
 */
static void nxt_test_reply_echo(struct kunit *test)
{
	static const u8 get_output1[] = { 0x00, 0x06, 0x01 };
	u8 output[25] = { 0x02, 0x06, 0x00, 0x01 };
	static const u8 get_input2[] = { 0x00, 0x07, 0x02 };
	u8 input[16] = { 0x02, 0x07, 0x00, 0x02 };
	u8 output_error[25] = { 0x02, 0x06, 0xc0 };
	/* MessageRead: remote inbox 12, local inbox 3, remove. */
	static const u8 read3[] = { 0x00, 0x13, 0x0c, 0x03, 0x01 };
	u8 msg[64] = { 0x02, 0x13, 0x00, 0x03, 0x02, 'x', 0 };

	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_output1, 3, output, sizeof(output)), 0);
	output[3] = 0x02;
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_output1, 3, output, sizeof(output)), -ENOMSG);
	/* An error reply has zeros where the port would be. */
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_output1, 3, output_error,
					      sizeof(output_error)), 0xc0);

	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_input2, 3, input, sizeof(input)), 0);
	input[3] = 0x00;
	KUNIT_EXPECT_EQ(test, nxt_reply_check(get_input2, 3, input, sizeof(input)), -ENOMSG);

	KUNIT_EXPECT_EQ(test, nxt_reply_check(read3, sizeof(read3), msg, sizeof(msg)), 0);
	msg[3] = 0x04;
	KUNIT_EXPECT_EQ(test, nxt_reply_check(read3, sizeof(read3), msg, sizeof(msg)), -ENOMSG);
	/* Mailbox empty: the status comes back for the caller, whatever the inbox. */
	msg[2] = 0x40;
	KUNIT_EXPECT_EQ(test, nxt_reply_check(read3, sizeof(read3), msg, sizeof(msg)), 0x40);
}

/* How long a lost reply is waited for: DeleteUserFlash takes seconds. */
static void nxt_test_late_replies(struct kunit *test)
{
	static const u8 erase[] = { 0x01, 0xa0 };
	static const u8 erase_noreply[] = { 0x81, 0xa0 };
	static const u8 battery[] = { 0x00, 0x0b };
	static const u8 direct_a0[] = { 0x00, 0xa0 };

	KUNIT_EXPECT_EQ(test, nxt_reply_late_ms(erase, sizeof(erase)), NXT_SLOW_REPLY_MS);
	KUNIT_EXPECT_GE(test, NXT_SLOW_REPLY_MS, 3000);
	KUNIT_EXPECT_EQ(test, nxt_reply_late_ms(erase_noreply, 2), NXT_LATE_REPLY_MS);
	KUNIT_EXPECT_EQ(test, nxt_reply_late_ms(battery, 2), NXT_LATE_REPLY_MS);
	KUNIT_EXPECT_EQ(test, nxt_reply_late_ms(direct_a0, 2), NXT_LATE_REPLY_MS);
}

/*
 * The drain and the sysfs cache on a clock that does not wrap. The values
 * are those a 32-bit jiffies makes wrong: a point 2^31 + 1 ticks in the
 * past (24.9 days at HZ=1000) looked 2^31 - 1 ticks in the future to
 * time_before(), and a write() slept that long.
 */
static void nxt_test_time(struct kunit *test)
{
	const u64 start = 0xfffb6c20ULL;	/* INITIAL_JIFFIES on 32 bits */
	const u64 weeks = (1ULL << 31) + 1;
	const u64 max = 3000;

	KUNIT_EXPECT_EQ(test, nxt_time_left(start + weeks, start, max), 0ULL);
	KUNIT_EXPECT_EQ(test, nxt_time_left(start + 2 * weeks, start + 20, max), 0ULL);
	KUNIT_EXPECT_EQ(test, nxt_time_left(start, start, max), 0ULL);
	KUNIT_EXPECT_EQ(test, nxt_time_left(start, start + 20, max), 20ULL);
	KUNIT_EXPECT_EQ(test, nxt_time_left(U32_MAX - 5ULL, U32_MAX + 15ULL, max), 20ULL);
	/* Never longer than the cap, whatever is stored. */
	KUNIT_EXPECT_EQ(test, nxt_time_left(start, start + weeks, max), max);
}

/*
 * A permanently stalling endpoint: the first stall is cleared at once, the
 * following ones after a wait that doubles up to a second, never 0 again.
 */
static void nxt_test_stall_backoff(struct kunit *test)
{
	unsigned int n, prev = 0, ms;

	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(0), 0U);
	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(1), 0U);
	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(2), NXT_STALL_BACKOFF_MIN_MS);
	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(3), 2 * NXT_STALL_BACKOFF_MIN_MS);
	for (n = 2; n <= 300; n++) {
		ms = nxt_stall_backoff_ms(n);
		KUNIT_EXPECT_GE(test, ms, prev);
		KUNIT_EXPECT_GT(test, ms, 0U);
		KUNIT_EXPECT_LE(test, ms, NXT_STALL_BACKOFF_MAX_MS);
		prev = ms;
	}
	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(255), NXT_STALL_BACKOFF_MAX_MS);
	KUNIT_EXPECT_EQ(test, nxt_stall_backoff_ms(U32_MAX), NXT_STALL_BACKOFF_MAX_MS);
}

static void nxt_test_versions_and_device_info(struct kunit *test)
{
	static const u8 v129[] = { 0x02, 0x88, 0x00, 0x7c, 0x01, 0x1d, 0x01 };
	static const u8 vpython[] = { 0x02, 0x88, 0x00, 0x01, 0x02, 0x03, 0x04 };
	static const u8 info[33] = {
		0x02, 0x9b, 0x00, 'N', 'X', 'T', 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
		0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x00, 0x11, 0x12, 0x13, 0x14,
		0x21, 0x22, 0x23, 0x24 };
	static const u8 mac[] = { 0x01, 0x02, 0x03, 0x04, 0x05, 0x06 };
	u8 odd_name[33];
	struct nxt_device_info di;
	u8 prot[2], fw[2];

	KUNIT_EXPECT_EQ(test, nxt_decode_versions(v129, sizeof(v129), prot, fw), 0);
	KUNIT_EXPECT_EQ(test, prot[0], 1);
	KUNIT_EXPECT_EQ(test, prot[1], 124);
	KUNIT_EXPECT_EQ(test, fw[0], 1);
	KUNIT_EXPECT_EQ(test, fw[1], 29);
	/* nxt-python: protocol (2, 1), firmware (4, 3). */
	KUNIT_EXPECT_EQ(test, nxt_decode_versions(vpython, sizeof(vpython), prot, fw), 0);
	KUNIT_EXPECT_EQ(test, prot[0], 2);
	KUNIT_EXPECT_EQ(test, prot[1], 1);
	KUNIT_EXPECT_EQ(test, fw[0], 4);
	KUNIT_EXPECT_EQ(test, fw[1], 3);
	KUNIT_EXPECT_EQ(test, nxt_decode_versions(v129, 6, prot, fw), -EPROTO);

	KUNIT_EXPECT_EQ(test, nxt_decode_device_info(info, sizeof(info), &di), 0);
	KUNIT_EXPECT_STREQ(test, di.name, "NXT");
	KUNIT_EXPECT_MEMEQ(test, di.bt_address, mac, sizeof(mac));
	KUNIT_EXPECT_EQ(test, di.free_flash, 0x24232221U);
	KUNIT_EXPECT_EQ(test, nxt_decode_device_info(info, 32, &di), -EPROTO);

	/* A name of 15 bytes with no NUL and a control character. */
	memcpy(odd_name, info, sizeof(odd_name));
	memset(odd_name + 3, 'A', 15);
	odd_name[4] = 0x07;
	KUNIT_EXPECT_EQ(test, nxt_decode_device_info(odd_name, sizeof(odd_name), &di), 0);
	KUNIT_EXPECT_STREQ(test, di.name, "A?AAAAAAAAAAAAA");
}

/* Feeds @len bytes @chunk at a time; collects the replies into @out. */
static unsigned int nxt_bt_feed_all(struct nxt_bt_rx *rx, const u8 *data,
				    size_t len, size_t chunk, u8 *out,
				    unsigned int *lens, unsigned int max)
{
	unsigned int n = 0, at = 0;

	while (len) {
		size_t step = min(len, chunk);

		while (step) {
			const u8 *reply;
			unsigned int rlen;
			size_t used = nxt_bt_rx_feed(rx, data, step, &reply, &rlen);

			data += used;
			len -= used;
			step -= used;
			if (reply && n < max) {
				memcpy(out + at, reply, rlen);
				lens[n++] = rlen;
				at += rlen;
			}
		}
	}
	return n;
}

static void nxt_test_bt_frames(struct kunit *test)
{
	/* GetBatteryLevel's reply (7.8 V), then KeepAlive's (sleep 600000 ms). */
	static const u8 stream[] = {
		0x05, 0x00, 0x02, 0x0b, 0x00, 0x78, 0x1e,
		0x07, 0x00, 0x02, 0x0d, 0x00, 0xc0, 0x27, 0x09, 0x00,
	};
	static const u8 battery[] = { 0x00, 0x0b };
	u8 frame[NXT_BT_FRAME_MAX], out[32];
	unsigned int lens[4], n;
	struct nxt_bt_rx rx;
	size_t chunk;

	KUNIT_EXPECT_EQ(test, nxt_bt_frame(frame, battery, sizeof(battery)), 4U);
	KUNIT_EXPECT_EQ(test, frame[0], 2);
	KUNIT_EXPECT_EQ(test, frame[1], 0);
	KUNIT_EXPECT_EQ(test, frame[2], 0x00);
	KUNIT_EXPECT_EQ(test, frame[3], 0x0b);

	/* Whatever the link's chunks, the same two replies and nothing dropped. */
	for (chunk = 1; chunk <= sizeof(stream); chunk++) {
		memset(&rx, 0, sizeof(rx));
		n = nxt_bt_feed_all(&rx, stream, sizeof(stream), chunk, out, lens, 4);
		KUNIT_ASSERT_EQ(test, n, 2U);
		KUNIT_EXPECT_EQ(test, lens[0], 5U);
		KUNIT_EXPECT_EQ(test, lens[1], 7U);
		KUNIT_EXPECT_MEMEQ(test, out, stream + 2, 5);
		KUNIT_EXPECT_MEMEQ(test, out + 5, stream + 9, 7);
		KUNIT_EXPECT_EQ(test, rx.dropped, 0U);
		KUNIT_EXPECT_EQ(test, rx.have, 0U);
	}

	/* The largest reply the ABI carries; one byte more is a lie. */
	memset(out, 0, sizeof(out));
	memset(&rx, 0, sizeof(rx));
	frame[0] = NXT_TELEGRAM_MAX;
	frame[1] = 0;
	frame[2] = NXT_REPLY;
	memset(frame + 3, 0x5a, NXT_TELEGRAM_MAX - 1);
	n = nxt_bt_feed_all(&rx, frame, NXT_BT_FRAME_MAX, 7, frame, lens, 1);
	KUNIT_EXPECT_EQ(test, n, 1U);
	KUNIT_EXPECT_EQ(test, lens[0], (unsigned int)NXT_TELEGRAM_MAX);
}

static void nxt_test_bt_lying_prefixes(struct kunit *test)
{
	static const u8 good[] = { 0x05, 0x00, 0x02, 0x0b, 0x00, 0x78, 0x1e };
	static const struct {
		const char *what;
		u8 bytes[8];
		u8 len;
	} lies[] = {
		{ "zero length", { 0x00, 0x00 }, 2 },
		{ "shorter than a reply", { 0x02, 0x00, 0x02, 0x0b }, 4 },
		{ "longer than a telegram", { 0x41, 0x00, 0x02 }, 3 },
		{ "a high byte", { 0x05, 0x01, 0x02 }, 3 },
		{ "not a reply's type", { 0x05, 0x00, 0x01, 0x0b, 0x00 }, 5 },
		{ "line noise", { 0xff, 0xff, 0x00, 0xff, 0x80, 0x00 }, 6 },
	};
	u8 stream[sizeof(good) + 8], out[64];
	unsigned int lens[4], n, i;
	struct nxt_bt_rx rx;

	/* Garbage before a frame is skipped, byte by byte, whatever it is. */
	for (i = 0; i < ARRAY_SIZE(lies); i++) {
		memcpy(stream, lies[i].bytes, lies[i].len);
		memcpy(stream + lies[i].len, good, sizeof(good));
		memset(&rx, 0, sizeof(rx));
		n = nxt_bt_feed_all(&rx, stream, lies[i].len + sizeof(good), 1,
				    out, lens, 4);
		KUNIT_EXPECT_EQ_MSG(test, n, 1U, "%s", lies[i].what);
		KUNIT_EXPECT_EQ_MSG(test, lens[0], 5U, "%s", lies[i].what);
		KUNIT_EXPECT_EQ_MSG(test, memcmp(out, good + 2, 5), 0, "%s",
				    lies[i].what);
		KUNIT_EXPECT_EQ_MSG(test, rx.dropped, (unsigned int)lies[i].len,
				    "%s", lies[i].what);
	}

	/*
	 * A prefix that promised more than came takes the next frame's bytes:
	 * the reply is wrong (the engine's check refuses it), and the reset
	 * before the next telegram drops what is left.
	 */
	memset(&rx, 0, sizeof(rx));
	stream[0] = 0x06;
	stream[1] = 0x00;
	stream[2] = 0x02;
	memcpy(stream + 3, good, sizeof(good));
	n = nxt_bt_feed_all(&rx, stream, 3 + sizeof(good), 1, out, lens, 4);
	KUNIT_EXPECT_EQ(test, n, 1U);
	KUNIT_EXPECT_EQ(test, lens[0], 6U);
	/* 78 1e is no length: 0x78 is dropped, 0x1e may start one. */
	KUNIT_EXPECT_EQ(test, rx.have, 1U);
	KUNIT_EXPECT_EQ(test, rx.dropped, 1U);
	nxt_bt_rx_reset(&rx);
	KUNIT_EXPECT_EQ(test, rx.have, 0U);
	KUNIT_EXPECT_EQ(test, rx.dropped, 2U);
	n = nxt_bt_feed_all(&rx, good, sizeof(good), 3, out, lens, 4);
	KUNIT_EXPECT_EQ(test, n, 1U);
	KUNIT_EXPECT_MEMEQ(test, out, good + 2, 5);

	/* One that promised fewer: the rest is skipped as garbage. */
	memset(&rx, 0, sizeof(rx));
	memcpy(stream, good, sizeof(good));
	stream[0] = 0x03;
	memcpy(stream + sizeof(good), good, sizeof(good));
	n = nxt_bt_feed_all(&rx, stream, 2 * sizeof(good), 2, out, lens, 4);
	KUNIT_EXPECT_EQ(test, n, 2U);
	KUNIT_EXPECT_EQ(test, lens[0], 3U);
	KUNIT_EXPECT_EQ(test, lens[1], 5U);
	KUNIT_EXPECT_MEMEQ(test, out + 3, good + 2, 5);
	KUNIT_EXPECT_EQ(test, rx.dropped, 2U);
}

/* The low-speed (I2C) telegrams of the adapters, and their replies. */
static void nxt_test_ls_telegrams(struct kunit *test)
{
	static const u8 wr[] = { 0x42, 0x01, 0x02 };
	u8 tg[NXT_LS_TG_MAX + 4], big[NXT_LS_MAX];

	memset(big, 0x5a, sizeof(big));
	KUNIT_EXPECT_EQ(test, nxt_ls_mode_tg(tg, 3), 5U);
	KUNIT_EXPECT_MEMEQ(test, tg, ((u8[]){ 0x00, 0x05, 0x03, 0x0b, 0x00 }), 5);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(tg, 5), 1);

	/* The ultrasonic sensor at 0x01 is 0x02 on the brick's bus. */
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 3, 0x01, wr, 1, 1), 7);
	KUNIT_EXPECT_MEMEQ(test, tg, ((u8[]){ 0x00, 0x0f, 0x03, 0x02, 0x01, 0x02, 0x42 }), 7);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(tg, 7), 1);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(tg, 7), 3U);
	/* A quick write: the address alone, nothing read. */
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 0, 0x7f, NULL, 0, 0), 6);
	KUNIT_EXPECT_MEMEQ(test, tg, ((u8[]){ 0x00, 0x0f, 0x00, 0x01, 0x00, 0xfe }), 6);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(tg, 6), 1);
	/* The most: 15 bytes and the address, and 16 read; the telegram is whole. */
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 1, 0x08, big, NXT_LS_WRITE_MAX, NXT_LS_MAX),
			NXT_LS_TG_MAX);
	KUNIT_EXPECT_EQ(test, tg[3], NXT_LS_MAX);
	KUNIT_EXPECT_EQ(test, tg[4], NXT_LS_MAX);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(tg, NXT_LS_TG_MAX), 1);
	KUNIT_EXPECT_TRUE(test, nxt_request_complete(tg, NXT_LS_TG_MAX));
	KUNIT_EXPECT_FALSE(test, nxt_request_complete(tg, NXT_LS_TG_MAX - 1));
	/* What one LSWrite cannot carry. */
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 1, 0x08, big, NXT_LS_MAX, 0), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 1, 0x08, big, 1, NXT_LS_MAX + 1), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 4, 0x08, big, 1, 1), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_ls_write_tg(tg, 0, 0x80, big, 1, 1), -EINVAL);

	KUNIT_EXPECT_EQ(test, nxt_ls_port_tg(tg, NXT_LS_GET_STATUS, 2), 3U);
	KUNIT_EXPECT_MEMEQ(test, tg, ((u8[]){ 0x00, 0x0e, 0x02 }), 3);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(tg, 3), 4U);
	KUNIT_EXPECT_EQ(test, nxt_ls_port_tg(tg, NXT_LS_READ, 2), 3U);
	KUNIT_EXPECT_EQ(test, nxt_reply_length(tg, 3), 20U);
}

static void nxt_test_ls_replies(struct kunit *test)
{
	u8 reply[20] = { 0x02, 0x10, 0x00, 4, 'L', 'E', 'G', 'O' };
	u8 buf[NXT_LS_MAX + 1];

	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0x00), 0);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0x20), -EINPROGRESS);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0xe0), -EAGAIN);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0xdd), -ENXIO);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0xc0), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0xed), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_ls_errno(0xde), -EIO);

	KUNIT_EXPECT_EQ(test, nxt_ls_status((u8[]){ 0x02, 0x0f, 0xe0 }, 3, NXT_LS_WRITE), 0xe0);
	KUNIT_EXPECT_EQ(test, nxt_ls_status((u8[]){ 0x02, 0x0e, 0x00 }, 3, NXT_LS_WRITE), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_ls_status((u8[]){ 0x01, 0x0f, 0x00 }, 3, NXT_LS_WRITE), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_ls_status((u8[]){ 0x02, 0x0f }, 2, NXT_LS_WRITE), -EPROTO);

	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0x00, 0x07 }, 4), 7);
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0x00, 0x10 }, 4), 16);
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0x00, 0x11 }, 4), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0x00 }, 3), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0x20, 0x00 }, 4), -EINPROGRESS);
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0xdd, 0x00 }, 4), -ENXIO);
	/* A bad port: three bytes, no count. */
	KUNIT_EXPECT_EQ(test, nxt_ls_ready((u8[]){ 0x02, 0x0e, 0xc0 }, 3), -EINVAL);

	memset(buf, 0xa5, sizeof(buf));
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply), buf, 4), 0);
	KUNIT_EXPECT_MEMEQ(test, buf, "LEGO", 4);
	KUNIT_EXPECT_EQ(test, buf[4], 0xa5);
	/* The count must be what was asked for, and the reply whole. */
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply), buf, 3), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply) - 1, buf, 4), -EPROTO);
	reply[3] = NXT_LS_MAX + 1;
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply), buf, NXT_LS_MAX + 1),
			-EPROTO);
	reply[2] = 0xdd;
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply), buf, 4), -ENXIO);
	reply[1] = 0x0e;
	KUNIT_EXPECT_EQ(test, nxt_ls_read_data(reply, sizeof(reply), buf, 4), -EPROTO);
}

static struct kunit_case nxt_proto_cases[] = {
	KUNIT_CASE(nxt_test_telegram_types),
	KUNIT_CASE(nxt_test_telegram_lengths),
	KUNIT_CASE(nxt_test_request_lengths),
	KUNIT_CASE(nxt_test_request_strings_and_counts),
	KUNIT_CASE(nxt_test_brick_info),
	KUNIT_CASE(nxt_test_reply_lengths),
	KUNIT_CASE(nxt_test_reply_check),
	KUNIT_CASE(nxt_test_reply_echo),
	KUNIT_CASE(nxt_test_late_replies),
	KUNIT_CASE(nxt_test_time),
	KUNIT_CASE(nxt_test_stall_backoff),
	KUNIT_CASE(nxt_test_versions_and_device_info),
	KUNIT_CASE(nxt_test_bt_frames),
	KUNIT_CASE(nxt_test_bt_lying_prefixes),
	KUNIT_CASE(nxt_test_ls_telegrams),
	KUNIT_CASE(nxt_test_ls_replies),
	{}
};

static struct kunit_suite nxt_proto_suite = {
	.name = "lego_nxt_proto",
	.test_cases = nxt_proto_cases,
};

kunit_test_suite(nxt_proto_suite);

MODULE_DESCRIPTION("KUnit tests for the LEGO NXT telegram core");
MODULE_LICENSE("GPL");
LEGO_IMPORT_KUNIT_NS();
