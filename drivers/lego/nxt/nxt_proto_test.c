// SPDX-License-Identifier: GPL-2.0
/*
 * KUnit tests for the NXT telegram core.
 */
#include <kunit/test.h>
#include <linux/module.h>

#include "lego_compat.h"
#include "nxt_proto.h"

static void nxt_test_telegram_types(struct kunit *test)
{
	/* GetBatteryLevel, with and without a reply. */
	static const u8 battery[] = { 0x00, 0x0b };
	static const u8 battery_noreply[] = { 0x80, 0x0b };
	/* GetFirmwareVersion (system command). */
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
	u8 buf[NXT_TELEGRAM_MAX + 1] = { NXT_DIRECT_CMD, 0x09 };

	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 0), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 1), -EINVAL);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, 2), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, NXT_TELEGRAM_MAX), 1);
	KUNIT_EXPECT_EQ(test, nxt_telegram_check(buf, NXT_TELEGRAM_MAX + 1), -EMSGSIZE);
}

static void nxt_test_reply_check(struct kunit *test)
{
	/* GetBatteryLevel reply: 02 0B 00, then 7.3 V little endian. */
	static const u8 ok[] = { 0x02, 0x0b, 0x00, 0x84, 0x1c };
	/* Unknown opcode: the brick answers 02 op BE. */
	static const u8 bad_opcode[] = { 0x02, 0x77, 0xbe };
	static const u8 not_reply[] = { 0x00, 0x0b, 0x00 };
	static const u8 short_reply[] = { 0x02, 0x0b };

	KUNIT_EXPECT_EQ(test, nxt_reply_check(ok, sizeof(ok), 0x0b), 0);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(ok, sizeof(ok), 0x0c), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(bad_opcode, sizeof(bad_opcode), 0x77), 0xbe);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(not_reply, sizeof(not_reply), 0x0b), -EPROTO);
	KUNIT_EXPECT_EQ(test, nxt_reply_check(short_reply, sizeof(short_reply), 0x0b), -EPROTO);
}

static struct kunit_case nxt_proto_cases[] = {
	KUNIT_CASE(nxt_test_telegram_types),
	KUNIT_CASE(nxt_test_telegram_lengths),
	KUNIT_CASE(nxt_test_reply_check),
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
