// SPDX-License-Identifier: GPL-2.0
/*
 * KUnit tests for the EV3 UART sensor protocol core.
 *
 * The byte sequences are taken from captures of real LEGO sensors.
 */
#include <kunit/test.h>
#include <linux/module.h>

#include "lego_compat.h"
#include "ev3_uart_proto.h"

static void ev3_uart_test_checksum_real_messages(struct kunit *test)
{
	/* TYPE 33 (infrared sensor): 40 21 9E */
	static const u8 type_ir[] = { 0x40, 0x21, 0x9e };
	/* MODES of the infrared sensor: 6 modes, 3 shown: 49 05 02 B1 */
	static const u8 modes_ir[] = { 0x49, 0x05, 0x02, 0xb1 };
	/* SPEED 57600 baud: 52 00 E1 00 00 4C */
	static const u8 speed[] = { 0x52, 0x00, 0xe1, 0x00, 0x00, 0x4c };

	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(type_ir, 2), type_ir[2]);
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(modes_ir, 3), modes_ir[3]);
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(speed, 5), speed[5]);
}

static void ev3_uart_test_checksum_empty(struct kunit *test)
{
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(NULL, 0), 0xff);
}

static void ev3_uart_test_msg_len(struct kunit *test)
{
	/* System messages are a single byte, whatever the size bits say. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x00), 1U);	/* SYNC */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x02), 1U);	/* NACK */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x04), 1U);	/* ACK */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x3a), 1U);	/* ESC-like */
	/* Commands: header + payload + checksum. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x40), 3U);	/* TYPE */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x49), 4U);	/* MODES */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x52), 6U);	/* SPEED */
	/* INFO carries the info type byte too. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x98), 11U);	/* NAME, 8 bytes */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xa5), 19U);	/* NAME, 16 bytes */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xa8), 35U);	/* 32-byte payload */
	/* DATA */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xc0), 3U);
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xdc), 10U);	/* RGB-RAW */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xe8), 34U);
	/* The largest header-encodable message exceeds what we accept. */
	KUNIT_EXPECT_GT(test, ev3_uart_msg_len(0xf8), (unsigned int)EV3_UART_MAX_MSG_LEN);
	KUNIT_EXPECT_EQ(test, ev3_uart_payload_len(0xf8), 128U);
}

static struct kunit_case ev3_uart_proto_cases[] = {
	KUNIT_CASE(ev3_uart_test_checksum_real_messages),
	KUNIT_CASE(ev3_uart_test_checksum_empty),
	KUNIT_CASE(ev3_uart_test_msg_len),
	{}
};

static struct kunit_suite ev3_uart_proto_suite = {
	.name = "lego_ev3_uart_proto",
	.test_cases = ev3_uart_proto_cases,
};

kunit_test_suite(ev3_uart_proto_suite);

MODULE_DESCRIPTION("KUnit tests for the LEGO EV3 UART sensor protocol core");
MODULE_LICENSE("GPL");
LEGO_IMPORT_KUNIT_NS();
