// SPDX-License-Identifier: GPL-2.0
/*
 * KUnit tests for the EV3 UART sensor protocol core.
 *
 * The handshakes of the real LEGO sensors are rebuilt from their mode tables
 * with the encoding rules the sensors follow (names padded to 8 or 16 bytes,
 * 8-byte ranges and units, 4-byte FORMAT, modes from highest to lowest); the
 * bytes that captures of real sensors give literally are checked against the
 * encoder first.
 */
#include <kunit/test.h>
#include <linux/module.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "ev3_uart_chan.h"
#include "ev3_uart_proto.h"

/* IEEE 754 single-precision bit patterns. */
#define F0		0x00000000
#define F1		0x3f800000
#define F8		0x41000000
#define F10		0x41200000
#define F100		0x42c80000
#define F255		0x437f0000
#define F1000		0x447a0000
#define F1020_1875	0x447f0c00
#define F2550		0x451f6000
#define F65535		0x477fff00
#define FM100		0xc2c80000
#define FM180		0xc3340000
#define F180		0x43340000
#define FM440		0xc3dc0000
#define F440		0x43dc0000
#define FM500		0xc3fa0000
#define F500		0x43fa0000
#define FM2000		0xc4fa0000
#define F2000		0x44fa0000
#define FM32768		0xc7000000
#define F32767		0x46fffe00
#define FNAN		0x7fc00000

#define BUF_SIZE	1024

struct tmode {
	const char *name;
	u32 raw[2];
	u32 si[2];
	const char *units;	/* NULL: no UNITS message */
	u8 n, t, fig, dec;
};

struct tsensor {
	u8 type;
	u8 modes;		/* number of modes */
	u8 views;
	const struct tmode *mode;
};

static const struct tmode color_modes[] = {
	{ "COL-REFLECT", { F0, F100 }, { F0, F100 }, "pct", 1, 0, 3, 0 },
	{ "COL-AMBIENT", { F0, F100 }, { F0, F100 }, "pct", 1, 0, 3, 0 },
	{ "COL-COLOR", { F0, F8 }, { F0, F8 }, "col", 1, 0, 2, 0 },
	{ "REF-RAW", { F0, F1020_1875 }, { F0, F1020_1875 }, NULL, 2, 1, 4, 0 },
	{ "RGB-RAW", { F0, F1020_1875 }, { F0, F1020_1875 }, NULL, 3, 1, 4, 0 },
	{ "COL-CAL", { F0, F65535 }, { F0, F65535 }, NULL, 4, 1, 5, 0 },
};

static const struct tmode us_modes[] = {
	{ "US-DIST-CM", { F0, F2550 }, { F0, F255 }, "cm", 1, 1, 5, 1 },
	{ "US-DIST-IN", { F0, F1000 }, { F0, F100 }, "inch", 1, 1, 5, 1 },
	{ "US-LISTEN", { F0, F1 }, { F0, F1 }, NULL, 1, 0, 1, 0 },
	{ "US-SI-CM", { F0, F2550 }, { F0, F255 }, "cm", 1, 1, 5, 1 },
	{ "US-SI-IN", { F0, F1000 }, { F0, F100 }, "inch", 1, 1, 5, 1 },
	{ "US-DC-CM", { F0, F2550 }, { F0, F255 }, "cm", 1, 1, 5, 1 },
	{ "US-DC-IN", { F0, F1000 }, { F0, F100 }, "inch", 1, 1, 5, 1 },
};

static const struct tmode gyro_old_modes[] = {
	{ "GYRO-ANG", { FM180, F180 }, { FM180, F180 }, "deg", 1, 1, 4, 0 },
	{ "GYRO-RATE", { FM440, F440 }, { FM440, F440 }, "d/s", 1, 1, 3, 0 },
	{ "GYRO-FAS", { FM2000, F2000 }, { FM2000, F2000 }, NULL, 1, 1, 4, 0 },
	{ "GYRO-G&A", { FM180, F180 }, { FM180, F180 }, NULL, 2, 1, 5, 0 },
	{ "GYRO-CAL", { F0, F65535 }, { F0, F65535 }, NULL, 4, 1, 5, 0 },
};

static const struct tmode gyro_new_modes[] = {
	{ "GYRO-ANG", { FM180, F180 }, { FM180, F180 }, "deg", 1, 1, 4, 0 },
	{ "GYRO-RATE", { FM500, F500 }, { FM500, F500 }, "d/s", 1, 1, 3, 0 },
	{ "GYRO-FAS", { FM2000, F2000 }, { FM2000, F2000 }, NULL, 1, 1, 4, 0 },
	{ "GYRO-G&A", { FM180, F180 }, { FM180, F180 }, NULL, 2, 1, 5, 0 },
	{ "GYRO-CAL", { FM32768, F32767 }, { FM32768, F32767 }, NULL, 4, 1, 5, 0 },
	{ "TILT-RATE", { FM500, F500 }, { FM500, F500 }, "d/s", 1, 1, 3, 0 },
	{ "TILT-ANG", { FM180, F180 }, { FM180, F180 }, "deg", 1, 1, 3, 0 },
};

static const struct tmode ir_modes[] = {
	{ "IR-PROX", { F0, F100 }, { F0, F100 }, "pct", 1, 0, 3, 0 },
	{ "IR-SEEK", { FM100, F100 }, { FM100, F100 }, "pct", 8, 0, 3, 0 },
	{ "IR-REMOTE", { F0, F10 }, { F0, F10 }, "btn", 4, 0, 3, 0 },
	{ "IR-REM-A", { F0, F65535 }, { F0, F65535 }, NULL, 1, 1, 6, 0 },
	{ "IR-S-ALT", { F0, F100 }, { F0, F100 }, "pct", 4, 0, 3, 0 },
	{ "IR-CAL", { F0, F65535 }, { F0, F65535 }, NULL, 2, 1, 5, 0 },
};

static const struct tsensor sensors[] = {
	{ EV3_UART_TYPE_COLOR, 6, 3, color_modes },
	{ EV3_UART_TYPE_US, 7, 3, us_modes },
	{ EV3_UART_TYPE_GYRO, 5, 2, gyro_old_modes },
	{ EV3_UART_TYPE_GYRO, 7, 2, gyro_new_modes },
	{ EV3_UART_TYPE_IR, 6, 3, ir_modes },
};

/* ---- an encoder following the sensors' rules ---- */

static unsigned int size_code(unsigned int plen)
{
	unsigned int code = 0;

	while ((1U << code) < plen)
		code++;
	return code;
}

/* One message: header, the INFO type byte if @itype >= 0, payload, checksum. */
static size_t enc(u8 *buf, u8 type, u8 low, int itype, const u8 *payload,
		  unsigned int plen)
{
	size_t n = 0;

	buf[n++] = type | size_code(plen) << 3 | low;
	if (itype >= 0)
		buf[n++] = itype;
	memcpy(buf + n, payload, plen);
	n += plen;
	buf[n] = ev3_uart_checksum(buf, n);
	return n + 1;
}

static size_t enc_cmd(u8 *buf, u8 cmd, const u8 *payload, unsigned int plen)
{
	return enc(buf, EV3_UART_MSG_CMD, cmd, -1, payload, plen);
}

static size_t enc_info(u8 *buf, u8 mode, u8 itype, const u8 *payload,
		       unsigned int plen)
{
	return enc(buf, EV3_UART_MSG_INFO, mode, itype, payload, plen);
}

static size_t enc_data(u8 *buf, u8 mode, const u8 *payload, unsigned int plen)
{
	return enc(buf, EV3_UART_MSG_DATA, mode, -1, payload, plen);
}

static size_t enc_range(u8 *buf, u8 mode, u8 itype, const u32 *range)
{
	u8 payload[8];

	put_unaligned_le32(range[0], payload);
	put_unaligned_le32(range[1], payload + 4);
	return enc_info(buf, mode, itype, payload, 8);
}

static size_t enc_string(u8 *buf, u8 mode, u8 itype, const char *s)
{
	u8 payload[16] = { };
	size_t n = strlen(s);

	memcpy(payload, s, n);
	/* <= 7 chars + NUL: 8 bytes; exactly 8 chars: 8 bytes, no NUL. */
	return enc_info(buf, mode, itype, payload, n <= 8 ? 8 : 16);
}

static size_t enc_mode(u8 *buf, u8 type, u8 mode, const struct tmode *m)
{
	u8 format[4] = { m->n, m->t, m->fig, m->dec };
	size_t len = 0;

	len += enc_string(buf + len, mode, EV3_UART_INFO_NAME, m->name);
	len += enc_range(buf + len, mode, EV3_UART_INFO_RAW, m->raw);
	len += enc_range(buf + len, mode, EV3_UART_INFO_SI, m->si);
	if (m->units) {
		len += enc_string(buf + len, mode, EV3_UART_INFO_UNITS, m->units);
	} else if (type == EV3_UART_TYPE_IR) {
		/* Quirk: the IR sensor sends 00 ff instead of nothing. */
		buf[len++] = 0x00;
		buf[len++] = 0xff;
	}
	len += enc_info(buf + len, mode, EV3_UART_INFO_FORMAT, format, 4);
	return len;
}

static size_t enc_handshake(u8 *buf, const struct tsensor *s)
{
	u8 modes[2] = { s->modes - 1, s->views - 1 };
	u8 speed[4];
	size_t len = 0;
	int m;

	len += enc_cmd(buf + len, EV3_UART_CMD_TYPE, &s->type, 1);
	len += enc_cmd(buf + len, EV3_UART_CMD_MODES, modes, 2);
	put_unaligned_le32(57600, speed);
	len += enc_cmd(buf + len, EV3_UART_CMD_SPEED, speed, 4);
	for (m = s->modes - 1; m >= 0; m--)
		len += enc_mode(buf + len, s->type, m, &s->mode[m]);
	buf[len++] = EV3_UART_SYS_ACK;
	return len;
}

/* ---- helpers to run the parser ---- */

#define MAX_EVENTS	64

struct run {
	struct ev3_uart_event ev[MAX_EVENTS];
	u8 data[MAX_EVENTS][EV3_UART_MAX_PAYLOAD];
	unsigned int n;
};

/* Feed @len bytes in chunks of @chunk, recording every event. */
static void feed(struct ev3_uart_parser *p, const u8 *buf, size_t len,
		 size_t chunk, struct run *r)
{
	struct ev3_uart_event ev;
	size_t off = 0, n, used;

	while (off < len) {
		n = min(chunk, len - off);
		do {
			used = ev3_uart_parser_feed(p, buf + off, n, &ev);
			off += used;
			n -= used;
			if (ev.type != EV3_UART_EV_NONE && r->n < MAX_EVENTS) {
				if (ev.type == EV3_UART_EV_DATA)
					memcpy(r->data[r->n], p->data, ev.len);
				r->ev[r->n++] = ev;
			}
		} while (ev.type != EV3_UART_EV_NONE);
	}
}

static unsigned int count(const struct run *r, enum ev3_uart_event_type t)
{
	unsigned int i, c = 0;

	for (i = 0; i < r->n; i++)
		c += r->ev[i].type == t;
	return c;
}

static const struct ev3_uart_event *last(const struct run *r)
{
	static const struct ev3_uart_event none;

	return r->n ? &r->ev[r->n - 1] : &none;
}

struct ctx {
	struct ev3_uart_parser p;
	struct run r;
	u8 buf[BUF_SIZE];
};

static struct ctx *new_ctx(struct kunit *test)
{
	struct ctx *c = kunit_kzalloc(test, sizeof(*c), GFP_KERNEL);

	KUNIT_ASSERT_NOT_NULL(test, c);
	ev3_uart_parser_init(&c->p);
	return c;
}

/* Bring a parser into the data phase with a real sensor's handshake. */
static void connect(struct kunit *test, struct ctx *c, const struct tsensor *s)
{
	size_t len = enc_handshake(c->buf, s);

	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	ev3_uart_parser_start_data(&c->p);
	c->r.n = 0;
}

/* ---- reconnects of a device that keeps failing ---- */

/* Issue 28: register, one good DATA, seven bad ones, lost, again. */
static void test_backoff(struct kunit *test)
{
	static const unsigned int want[] = {
		0, 0, 0, 1000, 2000, 4000, 8000, 16000, 32000, 32000, 32000,
	};
	struct ev3_uart_backoff b = { };
	unsigned int i;

	for (i = 0; i < ARRAY_SIZE(want); i++)
		KUNIT_EXPECT_EQ_MSG(test, ev3_uart_backoff_lost(&b, 60), want[i],
				    "failure %u", i + 1);
	/* A sensor that lived long enough ends the run... */
	KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, EV3_UART_SHORT_LIFE_MS), 0U);
	KUNIT_EXPECT_EQ(test, b.failures, 0U);
	/* ...so failures far apart never back off. */
	for (i = 0; i < 20; i++) {
		KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, 0), 0U);
		KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, 499), 0U);
		KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, 3000), 0U);
	}
	/* An unplugged sensor is noticed after 700 ms of silence: no failure. */
	KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, 700), 0U);
	KUNIT_EXPECT_EQ(test, b.failures, 0U);
	/* The count stops where the wait does: it never wraps. */
	for (i = 0; i < 1000; i++)
		ev3_uart_backoff_lost(&b, 0);
	KUNIT_EXPECT_EQ(test, b.failures, EV3_UART_FREE_RETRIES + EV3_UART_BACKOFF_MAX_SHIFT + 1U);
	KUNIT_EXPECT_EQ(test, ev3_uart_backoff_lost(&b, 0), (unsigned int)EV3_UART_BACKOFF_MAX_MS);
}

/* ---- framing ---- */

static void test_checksum_real_messages(struct kunit *test)
{
	static const u8 type_ir[] = { 0x40, 0x21, 0x9e };
	static const u8 modes_ir[] = { 0x49, 0x05, 0x02, 0xb1 };
	static const u8 speed[] = { 0x52, 0x00, 0xe1, 0x00, 0x00, 0x4c };

	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(type_ir, 2), type_ir[2]);
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(modes_ir, 3), modes_ir[3]);
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(speed, 5), speed[5]);
	KUNIT_EXPECT_EQ(test, ev3_uart_checksum(NULL, 0), 0xff);
}

static void test_msg_len(struct kunit *test)
{
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x00), 1U);	/* SYNC */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x02), 1U);	/* NACK */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x04), 1U);	/* ACK */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x3a), 1U);	/* ESC-like */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x40), 3U);	/* TYPE */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x49), 4U);	/* MODES */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x52), 6U);	/* SPEED */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0x98), 11U);	/* NAME, 8 bytes */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xa5), 19U);	/* NAME, 16 bytes */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xa8), 35U);	/* 32-byte payload */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xc0), 3U);
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(0xdc), 10U);	/* RGB-RAW */
	KUNIT_EXPECT_GT(test, ev3_uart_msg_len(0xf8), (unsigned int)EV3_UART_MAX_MSG_LEN);
	KUNIT_EXPECT_EQ(test, ev3_uart_payload_len(0xf8), 128U);
}

static void test_msg_time(struct kunit *test)
{
	const s64 b = 173611;		/* ns a byte at 57600 baud, 8N1 */
	const s64 now = 5000000000LL;
	s64 t1, t2, t3, t;
	int i;

	/* Three 4-byte messages handled in one batch: dated back to the wire. */
	t1 = ev3_uart_msg_time(now, 8, 4, 57600, 0);
	KUNIT_EXPECT_EQ(test, t1, now - 8 * b);
	t2 = ev3_uart_msg_time(now, 4, 4, 57600, t1);
	KUNIT_EXPECT_EQ(test, t2, now - 4 * b);
	t3 = ev3_uart_msg_time(now, 0, 4, 57600, t2);
	KUNIT_EXPECT_EQ(test, t3, now);

	/* A coarse clock that has not moved: one wire time after the last. */
	t = ev3_uart_msg_time(now, 0, 4, 57600, t3);
	KUNIT_EXPECT_EQ(test, t, now + 4 * b);
	/* A batch handled late, the next one early: never out of order. */
	t = ev3_uart_msg_time(now + 2 * b, 4, 4, 57600, t);
	KUNIT_EXPECT_EQ(test, t, now + 8 * b);

	/* After a pause the clock rules again. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_time(now + 1000000, 0, 4, 57600, now),
			now + 1000000);
	/* Set back by more than a second: followed; by less: not. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_time(now - 2000000000LL, 0, 4, 57600, now),
			now - 2000000000LL);
	/* (and then 1 ns after the last: not a wire time, 0.5 s ahead) */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_time(now - 500000000, 0, 4, 57600, now),
			now + 1);

	/*
	 * More bytes in one batch than the line could carry since the last
	 * message (a pty at 2400 baud): dated after the last one all the same.
	 */
	t = ev3_uart_msg_time(now, 500, 34, 2400, now - 1000000);
	KUNIT_EXPECT_EQ(test, t, now + EV3_UART_MSG_AHEAD_NS);	/* not 90 ms ahead */
	t = ev3_uart_msg_time(now, 500, 34, 2400, now - 100000000);
	KUNIT_EXPECT_EQ(test, t, now - 100000000 + 34 * 4166666LL);
	/* ...and a batch of 16 such messages stays within 50 ms of the clock. */
	for (i = 0, t2 = 0; i < 16; i++) {
		t = ev3_uart_msg_time(now, (15 - i) * 34, 34, 2400, t2);
		KUNIT_EXPECT_GT(test, t, t2);
		KUNIT_EXPECT_LE(test, t, now + EV3_UART_MSG_AHEAD_NS);
		t2 = t;
	}
	t = ev3_uart_msg_time(now + 10000000, 0, 34, 2400, t2);
	KUNIT_EXPECT_GT(test, t, t2);

	/* 2400 baud: 4.17 ms a byte; a bad speed counts as 2400. */
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_time(now, 3, 3, 2400, 0), now - 3 * 4166666LL);
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_time(now, 3, 3, 0, 0), now - 3 * 4166666LL);
}

static void test_encoder_matches_captures(struct kunit *test)
{
	/* Literal first bytes of the colour and gyro captures. */
	static const u8 color[] = { 0x40, 0x1d, 0xa2, 0x49, 0x05, 0x02, 0xb1,
				    0x52, 0x00, 0xe1, 0x00, 0x00, 0x4c };
	static const u8 gyro_old[] = { 0x40, 0x20, 0x9f, 0x49, 0x04, 0x01, 0xb3 };
	static const u8 gyro_new_modes[] = { 0x49, 0x06, 0x01, 0xb1 };
	struct ctx *c = new_ctx(test);
	size_t len;

	len = enc_handshake(c->buf, &sensors[0]);
	KUNIT_EXPECT_MEMEQ(test, c->buf, color, sizeof(color));
	/* The last mode sent is mode 0 and the last byte the sensor's ACK. */
	KUNIT_EXPECT_EQ(test, c->buf[len - 1], EV3_UART_SYS_ACK);
	enc_handshake(c->buf, &sensors[2]);
	KUNIT_EXPECT_MEMEQ(test, c->buf, gyro_old, sizeof(gyro_old));
	enc_handshake(c->buf, &sensors[3]);
	KUNIT_EXPECT_MEMEQ(test, c->buf + 3, gyro_new_modes, sizeof(gyro_new_modes));
	/* The 9-character TILT-RATE name travels in a 16-byte payload: A5. */
	KUNIT_EXPECT_EQ(test, enc_string(c->buf, 5, 0, "TILT-RATE"), (size_t)19);
	KUNIT_EXPECT_EQ(test, c->buf[0], 0xa5);
}

/* ---- each real sensor's handshake ---- */

static void check_sensor(struct kunit *test, const struct tsensor *s, size_t chunk)
{
	struct ctx *c = new_ctx(test);
	size_t len = enc_handshake(c->buf, s);
	const struct ev3_uart_sensor *got = &c->p.sensor;
	int i;

	feed(&c->p, c->buf, len, chunk, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_SYNC), 1U);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_ACKED);
	KUNIT_EXPECT_EQ(test, got->type, s->type);
	KUNIT_EXPECT_EQ(test, got->num_modes, s->modes);
	KUNIT_EXPECT_EQ(test, got->num_view_modes, s->views);
	KUNIT_EXPECT_EQ(test, got->speed, 57600U);

	for (i = 0; i < s->modes; i++) {
		const struct tmode *want = &s->mode[i];
		const struct ev3_uart_mode *m = &got->modes[i];
		s32 si_max;

		KUNIT_EXPECT_STREQ(test, m->name, want->name);
		KUNIT_EXPECT_STREQ(test, m->units, want->units ?: "");
		KUNIT_EXPECT_EQ(test, m->data_type, want->t);
		KUNIT_EXPECT_EQ(test, m->figures, want->fig);
		KUNIT_EXPECT_EQ(test, m->decimals, want->dec);
		KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(want->si[1], want->dec, &si_max), 0);
		KUNIT_EXPECT_EQ(test, m->si_max, si_max);
		/* RGB-RAW shows its hidden fourth value. */
		if (s->type == EV3_UART_TYPE_COLOR && i == 4)
			KUNIT_EXPECT_EQ(test, m->num_values, 4);
		else
			KUNIT_EXPECT_EQ(test, m->num_values, want->n);
	}
}

static void test_handshake_color(struct kunit *test)
{
	check_sensor(test, &sensors[0], BUF_SIZE);
	KUNIT_EXPECT_STREQ(test, ev3_uart_driver_name(29), "lego-ev3-color");
}

static void test_handshake_us(struct kunit *test)
{
	check_sensor(test, &sensors[1], BUF_SIZE);
	KUNIT_EXPECT_STREQ(test, ev3_uart_driver_name(30), "lego-ev3-us");
}

static void test_handshake_gyro_old(struct kunit *test)
{
	check_sensor(test, &sensors[2], BUF_SIZE);
	KUNIT_EXPECT_STREQ(test, ev3_uart_driver_name(32), "lego-ev3-gyro");
}

static void test_handshake_gyro_new(struct kunit *test)
{
	check_sensor(test, &sensors[3], BUF_SIZE);
}

static void test_handshake_ir_with_00ff(struct kunit *test)
{
	check_sensor(test, &sensors[4], BUF_SIZE);
	KUNIT_EXPECT_STREQ(test, ev3_uart_driver_name(33), "lego-ev3-ir");
	KUNIT_EXPECT_NULL(test, ev3_uart_driver_name(99));
}

static void test_handshake_byte_by_byte(struct kunit *test)
{
	int i;

	for (i = 0; i < ARRAY_SIZE(sensors); i++)
		check_sensor(test, &sensors[i], 1);
	check_sensor(test, &sensors[0], 7);
}

/*
 * With @report_msgs (set while the driver traces ev3_uart_rx), each CMD and
 * INFO message of a handshake is an EV3_UART_EV_MSG carrying its header
 * and length; the handshake comes out the same.
 */
static void test_report_msgs(struct kunit *test)
{
	const struct tsensor *s;
	unsigned int want, i, m;
	size_t chunk, len;
	struct ctx *c;

	for (i = 0; i < ARRAY_SIZE(sensors); i++) {
		for (chunk = 1; chunk <= BUF_SIZE; chunk += BUF_SIZE - 1) {
			s = &sensors[i];
			c = new_ctx(test);
			c->p.report_msgs = true;
			len = enc_handshake(c->buf, s);
			feed(&c->p, c->buf, len, chunk, &c->r);
			/* MODES and SPEED, then NAME, RAW, SI, FORMAT (and UNITS). */
			want = 2;
			for (m = 0; m < s->modes; m++)
				want += 4 + !!s->mode[m].units;
			KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_MSG), want);
			KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_SYNC), 1U);
			KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
			KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
			KUNIT_EXPECT_EQ(test, c->p.sensor.num_modes, s->modes);
			/* The second message is MODES: 0x49, 4 bytes long. */
			KUNIT_EXPECT_EQ(test, c->r.ev[1].type, EV3_UART_EV_MSG);
			KUNIT_EXPECT_EQ(test, c->r.ev[1].mode, 0x49);
			KUNIT_EXPECT_EQ(test, c->r.ev[1].len, 4);
			/* The last before ACK is mode 0's FORMAT. */
			KUNIT_EXPECT_EQ(test, c->r.ev[c->r.n - 2].mode, 0x90);
			KUNIT_EXPECT_EQ(test, c->p.msg_info, EV3_UART_INFO_FORMAT);
		}
	}
}

static void test_sync_after_garbage(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	/* A false 0x40 right before the real TYPE, and a bad TYPE checksum. */
	static const u8 junk[] = { 0x12, 0x40, 0x40, 0x1d, 0x00, 0x55, 0x40 };
	size_t len = sizeof(junk);

	memcpy(c->buf, junk, len);
	len += enc_handshake(c->buf + len, &sensors[0]);
	feed(&c->p, c->buf, len, 1, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.type, 29);
}

static void test_sync_rejects_bad_types(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	/* Type 0 and 102 are out of range, even with a good checksum. */
	static const u8 bad[] = { 0x40, 0x00, 0xbf, 0x40, 0x66, 0xd9 };

	feed(&c->p, bad, sizeof(bad), sizeof(bad), &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 0U);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
}

/* Optional MODES and SPEED: one mode at 2400 baud. */
static void test_minimal_sensor(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	static const struct tmode m = { "TEST", { F0, F100 }, { F0, F100 }, NULL, 1, 0, 2, 0 };
	u8 type = 99;
	size_t len = 0;

	len += enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_mode(c->buf + len, type, 0, &m);
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_modes, 1);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_view_modes, 1);
	KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 2400U);
}

/* The Arduino emulator's handshake: NAME and FORMAT only, defaults elsewhere. */
static void test_defaults_without_ranges(struct kunit *test)
{
	static const u8 law[] = {
		0x40, 0x63, 0xdc, 0x49, 0x00, 0x00, 0xb6,
		0x52, 0x00, 0x96, 0x00, 0x00, 0x3b,
		0x90, 0x00, 0x54, 0x45, 0x53, 0x54, 0x79,
		0x90, 0x80, 0x01, 0x00, 0x02, 0x00, 0xec, 0x04,
	};
	struct ctx *c = new_ctx(test);
	const struct ev3_uart_mode *m = &c->p.sensor.modes[0];

	feed(&c->p, law, sizeof(law), sizeof(law), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 38400U);
	KUNIT_EXPECT_STREQ(test, m->name, "TEST");
	KUNIT_EXPECT_EQ(test, m->raw_min, 0);
	KUNIT_EXPECT_EQ(test, m->raw_max, 1023);
	KUNIT_EXPECT_EQ(test, m->pct_max, 100);
	KUNIT_EXPECT_EQ(test, m->si_max, 1);
	/* ev3dev's rule: value scaled from 0..1023 onto 0..1. */
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(m, 1023), 1);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(m, 1022), 0);
}

/* ---- malformed handshakes ---- */

struct bad_case {
	const char *what;
	u8 bytes[40];
	u8 len;
};

/*
 * Each case follows a valid TYPE 99 message; each must end in an error
 * and leave the parser hunting for TYPE again. Checksums are right unless
 * the case is about the checksum.
 */
static const struct bad_case bad_cases[] = {
	{ "oversized payload (64 bytes)", { 0xb0, 0x00 }, 2 },
	{ "bad checksum", { 0x49, 0x00, 0x00, 0x00 }, 4 },
	{ "modes out of range", { 0x49, 0x08, 0x00, 0xbe }, 4 },
	{ "duplicate MODES", { 0x41, 0x00, 0xbe, 0x41, 0x00, 0xbe }, 6 },
	{ "duplicate SPEED", { 0x52, 0x80, 0x25, 0x00, 0x00, 0x08,
			       0x52, 0x80, 0x25, 0x00, 0x00, 0x08 }, 12 },
	{ "speed out of range", { 0x52, 0x00, 0x00, 0x00, 0x01, 0xac }, 6 },
	{ "DATA before ACK", { 0xc0, 0x05, 0x3a }, 3 },
	{ "duplicate TYPE", { 0x40, 0x63, 0xdc }, 3 },
	{ "SELECT from a sensor", { 0x43, 0x00, 0xbc }, 3 },
	{ "INFO for a mode out of range", { 0x91, 0x00, 'A', 'B', 0, 0, 0x6d }, 7 },
	{ "MODE_PLUS_8 INFO for a mode out of range", { 0x90, 0x20, 'A', 'B', 0, 0, 0x4c }, 7 },
	{ "4-byte MODES with 17 modes", { 0x51, 0x07, 0x07, 0x10, 0x07, 0xb9 }, 6 },
	{ "short VERSION", { 0x57, 0x00, 0x00, 0x00, 0x10, 0xb8 }, 6 },
	{ "unknown INFO type", { 0x90, 0x0d, 0, 0, 0, 0, 0x62 }, 7 },
	{ "FORMAT before NAME", { 0x90, 0x80, 1, 0, 2, 0, 0xec }, 7 },
	{ "ACK with no mode described", { 0x04 }, 1 },
	{ "NAME not starting with a letter", { 0x90, 0x00, '1', 'A', 0, 0, 0x1f }, 7 },
	{ "NAME with a control character", { 0x90, 0x00, 'A', 0x07, 0, 0, 0x29 }, 7 },
	{ "NAME without NUL", { 0xa0, 0x00, 'A', 'B', 'C', 'D', 'E', 'F', 'G', 'H',
				'I', 'J', 'K', 'L', 'M', 'N', 'O', 'P', 0x4f }, 19 },
};

static void test_malformed_handshakes(struct kunit *test)
{
	static const u8 type99[] = { 0x40, 0x63, 0xdc };
	int i;

	for (i = 0; i < ARRAY_SIZE(bad_cases); i++) {
		const struct bad_case *bc = &bad_cases[i];
		struct ctx *c = new_ctx(test);
		u8 *b = c->buf;
		size_t len;

		memcpy(b, type99, 3);
		memcpy(b + 3, bc->bytes, bc->len);
		len = 3 + bc->len;
		feed(&c->p, b, len, 1, &c->r);
		KUNIT_EXPECT_EQ_MSG(test, last(&c->r)->type, EV3_UART_EV_ERROR,
				    "case: %s", bc->what);
		KUNIT_EXPECT_EQ_MSG(test, c->p.state, EV3_UART_STATE_SYNC,
				    "case: %s", bc->what);
	}
}

/* Build a one-mode handshake whose only mode has FORMAT @fmt and ranges @si. */
static size_t enc_one_mode(u8 *buf, const u8 *fmt, const u32 *si)
{
	static const u32 raw[2] = { F0, F100 };
	u8 type = 99;
	size_t len = 0;

	len += enc_cmd(buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_string(buf + len, 0, EV3_UART_INFO_NAME, "M");
	len += enc_range(buf + len, 0, EV3_UART_INFO_RAW, raw);
	len += enc_range(buf + len, 0, EV3_UART_INFO_SI, si);
	len += enc_info(buf + len, 0, EV3_UART_INFO_FORMAT, fmt, 4);
	buf[len++] = EV3_UART_SYS_ACK;
	return len;
}

static void test_format_limits(struct kunit *test)
{
	static const u32 si[2] = { F0, F100 };
	static const u32 nan_si[2] = { F0, FNAN };
	static const struct {
		u8 fmt[4];
		bool ok;
	} cases[] = {
		{ { 32, EV3_UART_DATA_S8, 4, 0 }, true },
		{ { 33, EV3_UART_DATA_S8, 4, 0 }, false },	/* count overflow */
		{ { 16, EV3_UART_DATA_S16, 4, 0 }, true },
		{ { 17, EV3_UART_DATA_S16, 4, 0 }, false },
		{ { 8, EV3_UART_DATA_S32, 4, 0 }, true },
		{ { 9, EV3_UART_DATA_S32, 4, 0 }, false },
		{ { 8, EV3_UART_DATA_FLOAT, 4, 0 }, true },
		{ { 9, EV3_UART_DATA_FLOAT, 4, 0 }, false },
		{ { 0, EV3_UART_DATA_S8, 4, 0 }, false },	/* no values */
		{ { 1, 4, 4, 0 }, false },			/* data type */
		{ { 1, EV3_UART_DATA_S8, 16, 0 }, false },	/* figures */
		{ { 1, EV3_UART_DATA_S8, 4, 10 }, false },	/* decimals */
		{ { 1, EV3_UART_DATA_S8, 4, 9 }, false },	/* 100 * 10^9 overflows */
		{ { 1, EV3_UART_DATA_S8, 4, 7 }, true },
	};
	int i;

	for (i = 0; i < ARRAY_SIZE(cases); i++) {
		struct ctx *c = new_ctx(test);
		size_t len = enc_one_mode(c->buf, cases[i].fmt, si);
		enum ev3_uart_event_type want = EV3_UART_EV_ERROR;

		if (cases[i].ok)
			want = EV3_UART_EV_HANDSHAKE;
		feed(&c->p, c->buf, len, len, &c->r);
		KUNIT_EXPECT_EQ_MSG(test, last(&c->r)->type, want, "FORMAT case %d", i);
	}

	/* A NaN range is refused too. */
	{
		static const u8 fmt[4] = { 1, EV3_UART_DATA_S8, 4, 0 };
		struct ctx *c = new_ctx(test);
		size_t len = enc_one_mode(c->buf, fmt, nan_si);

		feed(&c->p, c->buf, len, len, &c->r);
		KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);
	}
}

static void test_incomplete_and_duplicate_modes(struct kunit *test)
{
	static const struct tmode m = { "A", { F0, F100 }, { F0, F100 }, NULL, 1, 0, 2, 0 };
	u8 modes[2] = { 1, 1 };
	u8 type = 99;
	struct ctx *c;
	size_t len;

	/* Two modes announced, one described, then ACK. */
	c = new_ctx(test);
	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 2);
	len += enc_mode(c->buf + len, type, 1, &m);
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);

	/* The same mode described twice. */
	c = new_ctx(test);
	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 2);
	len += enc_mode(c->buf + len, type, 1, &m);
	len += enc_mode(c->buf + len, type, 1, &m);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);

	/* A range INFO after FORMAT, and a duplicate range. */
	c = new_ctx(test);
	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_mode(c->buf + len, type, 0, &m);
	len += enc_range(c->buf + len, 0, EV3_UART_INFO_RAW, m.raw);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);

	c = new_ctx(test);
	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_string(c->buf + len, 0, EV3_UART_INFO_NAME, "A");
	len += enc_range(c->buf + len, 0, EV3_UART_INFO_SI, m.si);
	len += enc_range(c->buf + len, 0, EV3_UART_INFO_SI, m.si);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);

	/* MODES after the first INFO. */
	c = new_ctx(test);
	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_string(c->buf + len, 0, EV3_UART_INFO_NAME, "A");
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 2);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);
}

/* 256 views (0xff) are all the modes there are, not 0 (found by fuzz_ev3). */
static void test_views_clamped(struct kunit *test)
{
	static const struct tmode m = { "A", { F0, F100 }, { F0, F100 }, NULL, 1, 0, 2, 0 };
	u8 modes[2] = { 0, 0xff };
	u8 type = 99;
	struct ctx *c = new_ctx(test);
	size_t len;

	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 2);
	len += enc_mode(c->buf + len, type, 0, &m);
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_modes, 1);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_view_modes, 1);
}

/* Powered Up extras in an otherwise EV3-like handshake: kept, not fatal. */
static void test_powered_up_extras(struct kunit *test)
{
	static const struct tmode m = { "A", { F0, F100 }, { F0, F100 }, NULL, 1, 0, 2, 0 };
	static const u8 mapping[2] = { 0x10, 0x00 };
	static const u8 version[8] = { 0x01, 0, 0, 0x10, 0x02, 0, 0, 0x10 };
	static const u8 format[4] = { 1, 0, 2, 0 };
	static const u8 combos[4] = { 0x01, 0x00, 0x00, 0x00 };
	static const u8 unk[16] = { 1, 2, 3, 4 };
	u8 type = 99, zero = 0;
	struct ctx *c = new_ctx(test);
	size_t len;

	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_VERSION, version, 8);
	/* EXT_MODE in the handshake: meant for the data phase, skipped. */
	len += enc_cmd(c->buf + len, EV3_UART_CMD_EXT_MODE, &zero, 1);
	len += enc_string(c->buf + len, 0, EV3_UART_INFO_NAME, m.name);
	len += enc_range(c->buf + len, 0, EV3_UART_INFO_RAW, m.raw);
	len += enc_range(c->buf + len, 0, EV3_UART_INFO_SI, m.si);
	len += enc_info(c->buf + len, 0, EV3_UART_INFO_MAPPING, mapping, 2);
	len += enc_info(c->buf + len, 0, 0x09, unk, 16);
	len += enc_info(c->buf + len, 0, EV3_UART_INFO_FORMAT, format, 4);
	/* MODE_COMBOS after mode 0's FORMAT, as real devices send it. */
	len += enc_info(c->buf + len, 0, EV3_UART_INFO_MODE_COMBOS, combos, 4);
	len += enc_info(c->buf + len, 0, 0x0c, unk, 1);
	/* For modes the device lacks (3, and 3 + 8): skipped, not fatal. */
	len += enc_info(c->buf + len, 3, EV3_UART_INFO_MAPPING, mapping, 2);
	len += enc_info(c->buf + len, 3, EV3_UART_INFO_MAPPING | EV3_UART_INFO_MODE_PLUS_8,
			mapping, 2);
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_TRUE(test, c->p.sensor.lump);
	KUNIT_EXPECT_EQ(test, c->p.sensor.fw_version, 0x10000001U);
	KUNIT_EXPECT_EQ(test, c->p.sensor.hw_version, 0x10000002U);
	KUNIT_EXPECT_EQ(test, c->p.sensor.modes[0].mapping_in, 0x10);
	KUNIT_EXPECT_EQ(test, c->p.sensor.modes[0].mapping_out, 0x00);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_combos, 1);
	KUNIT_EXPECT_EQ(test, c->p.sensor.combos[0], 0x0001);
}

/*
 * The BOOST colour and distance sensor's handshake as a logic analyser
 * recorded it (type 37): a 4-byte MODES with 11 modes and 8 views, SPEED
 * 115200, VERSION, modes 10 to 8 with the MODE_PLUS_8 flag, names with
 * spaces ("IR Tx", "RGB I", "COL O", "SPEC 1"), a 4-character name with no
 * NUL ("AMBI"), MAPPING for every mode, MODE_COMBOS after the last FORMAT.
 */
static const u8 boost_cds_handshake[] = {
	0x40, 0x25, 0x9a,
	0x51, 0x07, 0x07, 0x0a, 0x07, 0xa3,
	0x52, 0x00, 0xc2, 0x01, 0x00, 0x6e,
	0x5f, 0x00, 0x00, 0x00, 0x10, 0x00, 0x00, 0x00, 0x10, 0xa0,
	0x9a, 0x20, 0x43, 0x41, 0x4c, 0x49, 0x42, 0x00, 0x00, 0x00, 0x00,
	0x9a, 0x21, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0x83,
	0x9a, 0x22, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xcd,
	0x9a, 0x23, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0x81,
	0x92, 0x24, 0x4e, 0x2f, 0x41, 0x00, 0x69,
	0x8a, 0x25, 0x10, 0x00, 0x40,
	0x92, 0xa0, 0x08, 0x01, 0x05, 0x00, 0xc1,
	0x99, 0x20, 0x44, 0x45, 0x42, 0x55, 0x47, 0x00, 0x00, 0x00, 0x17,
	0x99, 0x21, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc0, 0x7f, 0x44, 0xbc,
	0x99, 0x22, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xce,
	0x99, 0x23, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x24,
	0x91, 0x24, 0x4e, 0x2f, 0x41, 0x00, 0x6a,
	0x89, 0x25, 0x10, 0x00, 0x43,
	0x91, 0xa0, 0x02, 0x01, 0x05, 0x00, 0xc8,
	0x98, 0x20, 0x53, 0x50, 0x45, 0x43, 0x20, 0x31, 0x00, 0x00, 0x53,
	0x98, 0x21, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x7f, 0x43, 0x7a,
	0x98, 0x22, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xcf,
	0x98, 0x23, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x7f, 0x43, 0x78,
	0x90, 0x24, 0x4e, 0x2f, 0x41, 0x00, 0x6b,
	0x88, 0x25, 0x00, 0x00, 0x52,
	0x90, 0xa0, 0x04, 0x00, 0x03, 0x00, 0xc8,
	0x9f, 0x00, 0x49, 0x52, 0x20, 0x54, 0x78, 0x00, 0x00, 0x00, 0x77,
	0x9f, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0xa6,
	0x9f, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xe8,
	0x9f, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0xa4,
	0x97, 0x04, 0x4e, 0x2f, 0x41, 0x00, 0x4c,
	0x8f, 0x05, 0x00, 0x04, 0x71,
	0x97, 0x80, 0x01, 0x01, 0x05, 0x00, 0xed,
	0x9e, 0x00, 0x52, 0x47, 0x42, 0x20, 0x49, 0x00, 0x00, 0x00, 0x5f,
	0x9e, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc0, 0x7f, 0x44, 0x9b,
	0x9e, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xe9,
	0x9e, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc0, 0x7f, 0x44, 0x99,
	0x96, 0x04, 0x52, 0x41, 0x57, 0x00, 0x29,
	0x8e, 0x05, 0x10, 0x00, 0x64,
	0x96, 0x80, 0x03, 0x01, 0x05, 0x00, 0xee,
	0x9d, 0x00, 0x43, 0x4f, 0x4c, 0x20, 0x4f, 0x00, 0x00, 0x00, 0x4d,
	0x9d, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x02,
	0x9d, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xea,
	0x9d, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x00,
	0x95, 0x04, 0x49, 0x44, 0x58, 0x00, 0x3b,
	0x8d, 0x05, 0x00, 0x04, 0x73,
	0x95, 0x80, 0x01, 0x00, 0x03, 0x00, 0xe8,
	0x94, 0x00, 0x41, 0x4d, 0x42, 0x49, 0x6c,
	0x9c, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xe8,
	0x9c, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xeb,
	0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xea,
	0x94, 0x04, 0x50, 0x43, 0x54, 0x00, 0x28,
	0x8c, 0x05, 0x10, 0x00, 0x66,
	0x94, 0x80, 0x01, 0x00, 0x03, 0x00, 0xe9,
	0x9b, 0x00, 0x52, 0x45, 0x46, 0x4c, 0x54, 0x00, 0x00, 0x00, 0x2d,
	0x9b, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xef,
	0x9b, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xec,
	0x9b, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xed,
	0x93, 0x04, 0x50, 0x43, 0x54, 0x00, 0x2f,
	0x8b, 0x05, 0x10, 0x00, 0x61,
	0x93, 0x80, 0x01, 0x00, 0x03, 0x00, 0xee,
	0x9a, 0x00, 0x43, 0x4f, 0x55, 0x4e, 0x54, 0x00, 0x00, 0x00, 0x26,
	0x9a, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xee,
	0x9a, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xed,
	0x9a, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xec,
	0x92, 0x04, 0x43, 0x4e, 0x54, 0x00, 0x30,
	0x8a, 0x05, 0x08, 0x00, 0x78,
	0x92, 0x80, 0x01, 0x02, 0x04, 0x00, 0xea,
	0x91, 0x00, 0x50, 0x52, 0x4f, 0x58, 0x7b,
	0x99, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x06,
	0x99, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xee,
	0x99, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x04,
	0x91, 0x04, 0x44, 0x49, 0x53, 0x00, 0x34,
	0x89, 0x05, 0x50, 0x00, 0x23,
	0x91, 0x80, 0x01, 0x00, 0x03, 0x00, 0xec,
	0x98, 0x00, 0x43, 0x4f, 0x4c, 0x4f, 0x52, 0x00, 0x00, 0x00, 0x3a,
	0x98, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x07,
	0x98, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xef,
	0x98, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x05,
	0x90, 0x04, 0x49, 0x44, 0x58, 0x00, 0x3e,
	0x88, 0x05, 0xc4, 0x00, 0xb6,
	0x90, 0x80, 0x01, 0x00, 0x03, 0x00, 0xed,
	0x88, 0x06, 0x4f, 0x00, 0x3e,
	0x04,
};

static void check_boost_cds(struct kunit *test, size_t chunk)
{
	struct ctx *c = new_ctx(test);
	const struct ev3_uart_sensor *s = &c->p.sensor;

	feed(&c->p, boost_cds_handshake, sizeof(boost_cds_handshake), chunk, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, s->type, 37);
	KUNIT_EXPECT_EQ(test, s->num_modes, 11);
	KUNIT_EXPECT_EQ(test, s->num_view_modes, 8);
	KUNIT_EXPECT_EQ(test, s->speed, 115200U);
	KUNIT_EXPECT_TRUE(test, s->lump);
	KUNIT_EXPECT_EQ(test, s->fw_version, 0x10000000U);
	KUNIT_EXPECT_EQ(test, s->hw_version, 0x10000000U);
	KUNIT_EXPECT_STREQ(test, s->modes[0].name, "COLOR");
	KUNIT_EXPECT_STREQ(test, s->modes[0].units, "IDX");
	KUNIT_EXPECT_EQ(test, s->modes[0].mapping_in, 0xc4);
	KUNIT_EXPECT_STREQ(test, s->modes[4].name, "AMBI");
	KUNIT_EXPECT_STREQ(test, s->modes[5].name, "COL O");
	KUNIT_EXPECT_EQ(test, s->modes[5].mapping_out, 0x04);
	KUNIT_EXPECT_STREQ(test, s->modes[6].name, "RGB I");
	KUNIT_EXPECT_EQ(test, s->modes[6].num_values, 3);
	KUNIT_EXPECT_EQ(test, s->modes[6].data_type, EV3_UART_DATA_S16);
	KUNIT_EXPECT_EQ(test, s->modes[6].raw_max, 1023);
	KUNIT_EXPECT_STREQ(test, s->modes[7].name, "IR Tx");
	KUNIT_EXPECT_EQ(test, s->modes[7].raw_max, 65535);
	KUNIT_EXPECT_STREQ(test, s->modes[8].name, "SPEC 1");
	KUNIT_EXPECT_EQ(test, s->modes[8].num_values, 4);
	KUNIT_EXPECT_EQ(test, s->modes[8].data_type, EV3_UART_DATA_S8);
	KUNIT_EXPECT_STREQ(test, s->modes[8].units, "N/A");
	KUNIT_EXPECT_STREQ(test, s->modes[9].name, "DEBUG");
	KUNIT_EXPECT_EQ(test, s->modes[9].num_values, 2);
	KUNIT_EXPECT_EQ(test, s->modes[9].raw_max, 1023);
	KUNIT_EXPECT_STREQ(test, s->modes[10].name, "CALIB");
	KUNIT_EXPECT_EQ(test, s->modes[10].num_values, 8);
	KUNIT_EXPECT_EQ(test, s->modes[10].data_type, EV3_UART_DATA_S16);
	KUNIT_EXPECT_EQ(test, s->modes[10].raw_max, 65535);
	KUNIT_EXPECT_EQ(test, s->num_combos, 1);
	KUNIT_EXPECT_EQ(test, s->combos[0], 0x004f);
	KUNIT_EXPECT_STREQ(test, ev3_uart_lump_driver_name(s->type), "lego-boost-color-dist");
	KUNIT_EXPECT_STREQ(test, ev3_uart_lump_driver_name(75), "lego-technic-m-angular-motor");
	KUNIT_EXPECT_STREQ(test, ev3_uart_driver_name(75), "fcl-ir");
	KUNIT_EXPECT_NULL(test, ev3_uart_lump_driver_name(29));
}

/* Every driver name fits the sensor's copy (a long one was cut once). */
static void test_driver_names_fit(struct kunit *test)
{
	char fallback[EV3_UART_DRIVER_NAME_LEN];
	const char *name;
	unsigned int t;

	for (t = 0; t < 256; t++) {
		name = ev3_uart_driver_name(t);
		if (name)
			KUNIT_EXPECT_LT_MSG(test, strlen(name), EV3_UART_DRIVER_NAME_LEN,
					    "type %u", t);
		name = ev3_uart_lump_driver_name(t);
		if (name)
			KUNIT_EXPECT_LT_MSG(test, strlen(name), EV3_UART_DRIVER_NAME_LEN,
					    "type %u", t);
	}
	KUNIT_EXPECT_LT(test, snprintf(fallback, sizeof(fallback), "lump-uart-%u", 255U),
			EV3_UART_DRIVER_NAME_LEN);
}

static void test_handshake_boost_color_distance(struct kunit *test)
{
	check_boost_cds(test, sizeof(boost_cds_handshake));
	check_boost_cds(test, 1);
	check_boost_cds(test, 7);
}

/*
 * The BOOST colour and distance sensor's IIO channels: every mode's values,
 * modes 8 to 10 too; RGB I as red, green and blue intensities; PROX a
 * proximity; tokens with "_" for the spaces.
 */
static void test_boost_cds_channels(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_chan *chans;
	unsigned int n, i, per_mode[EV3_UART_MAX_MODES] = { };
	char tok[EV3_UART_TOKEN_LEN + 1];
	static const u8 rgb[] = { IIO_MOD_LIGHT_RED, IIO_MOD_LIGHT_GREEN, IIO_MOD_LIGHT_BLUE };

	chans = kunit_kzalloc(test, sizeof(*chans) * (EV3_UART_MAX_CHANS + 1), GFP_KERNEL);
	KUNIT_ASSERT_NOT_NULL(test, chans);
	feed(&c->p, boost_cds_handshake, sizeof(boost_cds_handshake),
	     sizeof(boost_cds_handshake), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	n = ev3_uart_chans_build(&c->p.sensor, chans, EV3_UART_MAX_CHANS);
	/*
	 * The values with an IIO type: PROX, COUNT, REFLT, AMBI, RGB I (3).
	 * The others' units (IDX, N/A...) say nothing IIO has a type for.
	 */
	KUNIT_EXPECT_EQ(test, n, 7U);
	for (i = 0; i < n && i < EV3_UART_MAX_CHANS; i++) {
		per_mode[chans[i].mode]++;
		if (chans[i].mode == 6) {
			KUNIT_EXPECT_EQ(test, chans[i].type, IIO_INTENSITY);
			KUNIT_EXPECT_EQ(test, chans[i].modifier, rgb[chans[i].index]);
		}
		if (chans[i].mode == 1)
			KUNIT_EXPECT_EQ(test, chans[i].type, IIO_PROXIMITY);
		if (chans[i].mode == 2)
			KUNIT_EXPECT_EQ(test, chans[i].type, IIO_COUNT);
	}
	KUNIT_EXPECT_EQ(test, per_mode[6], 3U);
	KUNIT_EXPECT_EQ(test, per_mode[10], 0U);
	KUNIT_ASSERT_GT(test, ev3_uart_mode_token(&c->p.sensor, 5, tok, sizeof(tok)), 0);
	KUNIT_EXPECT_STREQ(test, tok, "COL_O");
	KUNIT_EXPECT_EQ(test, ev3_uart_find_mode(&c->p.sensor, "CALIB"), 10);
	KUNIT_EXPECT_EQ(test, ev3_uart_find_mode(&c->p.sensor, "IR_Tx"), 7);
	KUNIT_EXPECT_EQ(test, ev3_uart_find_mode(&c->p.sensor, "#9"), 9);
}

/*
 * The data phase of a Powered Up device: EXT_MODE before DATA gives the
 * mode (header's + 0 or 8), and lasts until the next EXT_MODE.
 */
static void check_ext_mode(struct kunit *test, size_t chunk)
{
	/* Recorded bytes: mode 6 after EXT_MODE 0, mode 8 after EXT_MODE 8. */
	static const u8 mode6[] = { 0x46, 0x00, 0xb9, 0xde, 0x00, 0x00, 0x00, 0x00,
				    0x00, 0x00, 0x00, 0x00, 0x21 };
	static const u8 mode8[] = { 0x46, 0x08, 0xb1, 0xd0, 0x00, 0x00, 0x00, 0x00, 0x2f };
	static const u8 spec[4] = { 1, 2, 3, 0xfc };
	static const u8 one[1] = { 5 };
	struct ctx *c = new_ctx(test);
	size_t len;
	s32 v;

	feed(&c->p, boost_cds_handshake, sizeof(boost_cds_handshake),
	     sizeof(boost_cds_handshake), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	ev3_uart_parser_start_data(&c->p);
	c->r.n = 0;

	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 6), 0);
	feed(&c->p, mode6, sizeof(mode6), chunk, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 1U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 6);
	KUNIT_EXPECT_TRUE(test, last(&c->r)->mode_changed);

	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 8), 0);
	feed(&c->p, mode8, sizeof(mode8), chunk, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 2U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 8);
	KUNIT_EXPECT_TRUE(test, last(&c->r)->mode_changed);

	/* No EXT_MODE before them: still mode 8. */
	len = enc_data(c->buf, 0, spec, 4);
	len += enc_data(c->buf + len, 0, spec, 4);
	feed(&c->p, c->buf, len, chunk, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 4U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 8);
	KUNIT_EXPECT_FALSE(test, last(&c->r)->mode_changed);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[8], c->p.data, 4, 3, &v), 0);
	KUNIT_EXPECT_EQ(test, v, -4);

	/* EXT_MODE 0 then mode 0's header: a stale mode 0 message, dropped. */
	len = enc_cmd(c->buf, EV3_UART_CMD_EXT_MODE, (const u8 *)"\0", 1);
	len += enc_data(c->buf + len, 0, one, 1);
	feed(&c->p, c->buf, len, chunk, &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 4U);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 0UL);

	/* An EXT_MODE other than 0 or 8, or with a bad checksum: a bad frame. */
	len = enc_cmd(c->buf, EV3_UART_CMD_EXT_MODE, (const u8 *)"\4", 1);
	feed(&c->p, c->buf, len, chunk, &c->r);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 1UL);
	KUNIT_EXPECT_EQ(test, c->p.ext_mode, 0);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_DATA);

	/* SELECT of mode 10 with EXT_MODE 8: 8 values. */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 10), 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_select(&c->p, 11), -EINVAL);
	len = enc_cmd(c->buf, EV3_UART_CMD_EXT_MODE, (const u8 *)"\10", 1);
	len += enc_data(c->buf + len, 2, (const u8 *)"0123456789abcdef", 16);
	feed(&c->p, c->buf, len, chunk, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 5U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 10);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[10], c->p.data, 16, 7, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 'e' | 'f' << 8);
}

/* Values for a Powered Up mode: EXT_MODE, then DATA; as Pybricks sends them. */
static void test_build_lump_data(struct kunit *test)
{
	/* Recorded form: EXT_MODE 0, then a 1-byte DATA of mode 5 (COL O). */
	static const u8 col_o[] = { 0x46, 0x00, 0xb9, 0xc5, 0x00, 0x3a };
	u8 buf[EV3_UART_MAX_PAYLOAD + 5], v = 0, three[3] = { 1, 2, 3 };

	KUNIT_ASSERT_EQ(test, ev3_uart_build_lump_data(buf, 5, &v, 1), 6);
	KUNIT_EXPECT_MEMEQ(test, buf, col_o, sizeof(col_o));
	/* Mode 9: EXT_MODE 8, header mode 1; 3 bytes padded to 4. */
	KUNIT_ASSERT_EQ(test, ev3_uart_build_lump_data(buf, 9, three, 3), 9);
	KUNIT_EXPECT_EQ(test, buf[1], 8);
	KUNIT_EXPECT_EQ(test, buf[2], ev3_uart_checksum(buf, 2));
	KUNIT_EXPECT_EQ(test, buf[3], 0xd1);
	KUNIT_EXPECT_EQ(test, buf[7], 0);
	KUNIT_EXPECT_EQ(test, buf[8], ev3_uart_checksum(buf + 3, 5));
	KUNIT_EXPECT_EQ(test, ev3_uart_build_lump_data(buf, 16, three, 3), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_lump_data(buf, 0, three, 0), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_lump_data(buf, 0, buf, 33), -EINVAL);
}

/*
 * Powered Up lights: the values of a mode "LIGHT" that takes values, one
 * s8 per light (the SPIKE colour sensor's mode 3, 3 lights; the
 * ultrasonic sensor's mode 5, 4 lights); which modes take values at all.
 */
static void test_lump_lights(struct kunit *test)
{
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	struct ctx *c = new_ctx(test);
	u8 mode = 0xee;

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->lump = true;
	s->num_modes = 6;
	strscpy(s->modes[3].name, "LIGHT", sizeof(s->modes[3].name));
	s->modes[3].num_values = 3;
	s->modes[3].data_type = EV3_UART_DATA_S8;
	s->modes[3].mapping_out = 0x04;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 3U);
	KUNIT_EXPECT_EQ(test, mode, 3);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 3), 3);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 2), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 6), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 0xff), -EINVAL);

	/* Too many values, another type, no MAPPING out, an EV3 sensor: none. */
	s->modes[3].num_values = EV3_UART_MAX_LIGHTS + 1;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 0U);
	s->modes[3].num_values = 4;
	s->modes[3].data_type = EV3_UART_DATA_S16;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 0U);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 3), 8);
	s->modes[3].data_type = EV3_UART_DATA_S8;
	s->modes[3].mapping_out = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 0U);
	s->modes[3].mapping_out = 0x04;
	s->lump = false;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 0U);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(s, 3), -EINVAL);
	s->lump = true;
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(s, &mode), 4U);

	/* The BOOST sensor: COL O (1 byte) and IR Tx (s16) take values. */
	feed(&c->p, boost_cds_handshake, sizeof(boost_cds_handshake),
	     sizeof(boost_cds_handshake), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_lights(&c->p.sensor, &mode), 0U);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(&c->p.sensor, 5), 1);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(&c->p.sensor, 7), 2);
	KUNIT_EXPECT_EQ(test, ev3_uart_lump_data_len(&c->p.sensor, 0), -EINVAL);
}

/* Values for a mode that takes them, packed as its FORMAT says. */
static void test_pack_values(struct kunit *test)
{
	static const s32 ir[] = { -2 }, light[] = { 100, -128, 127 };
	static const s32 big[] = { 32768 }, wide[] = { 128, 0, 0 };
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	u8 buf[EV3_UART_MAX_PAYLOAD];

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->lump = true;
	s->num_modes = 3;
	s->modes[0].num_values = 1;
	s->modes[0].data_type = EV3_UART_DATA_S16;
	s->modes[0].mapping_out = 0x04;
	s->modes[1].num_values = 3;
	s->modes[1].data_type = EV3_UART_DATA_S8;
	s->modes[1].mapping_out = 0x04;
	s->modes[2].num_values = 1;
	s->modes[2].data_type = EV3_UART_DATA_FLOAT;
	s->modes[2].mapping_out = 0x04;
	KUNIT_ASSERT_EQ(test, ev3_uart_pack_values(s, 0, ir, 1, buf), 2);
	KUNIT_EXPECT_EQ(test, buf[0], 0xfe);
	KUNIT_EXPECT_EQ(test, buf[1], 0xff);
	KUNIT_ASSERT_EQ(test, ev3_uart_pack_values(s, 1, light, 3, buf), 3);
	KUNIT_EXPECT_EQ(test, buf[0], 100);
	KUNIT_EXPECT_EQ(test, buf[1], 0x80);
	KUNIT_EXPECT_EQ(test, buf[2], 0x7f);
	KUNIT_EXPECT_EQ(test, ev3_uart_pack_values(s, 0, big, 1, buf), -ERANGE);
	KUNIT_EXPECT_EQ(test, ev3_uart_pack_values(s, 1, wide, 3, buf), -ERANGE);
	KUNIT_EXPECT_EQ(test, ev3_uart_pack_values(s, 1, light, 2, buf), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_pack_values(s, 2, ir, 1, buf), -EINVAL);
	s->modes[0].mapping_out = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_pack_values(s, 0, ir, 1, buf), -EINVAL);
}

/*
 * A Technic Large motor's handshake (type 46) as a logic analyser recorded
 * it (Pybricks, lib/pbio/test/src/uartdev.c before commit ae927acbd):
 * POWER, SPEED, POS, APOS, CALIB, STATS; MODE_COMBOS 0x000e (SPEED, POS,
 * APOS); INFO types 0x08 to 0x0c for mode 0.
 */
static const u8 technic_l_handshake[] = {
	0x40, 0x2e, 0x91,
	0x49, 0x05, 0x03, 0xb0,
	0x52, 0x00, 0xc2, 0x01, 0x00, 0x6e,
	0x5f, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0xb4,
	0xa5, 0x00, 0x53, 0x54, 0x41, 0x54, 0x53, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x1a,
	0x9d, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0xa4,
	0x9d, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xea,
	0x9d, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0x7f, 0x47, 0xa6,
	0x95, 0x04, 0x4d, 0x49, 0x4e, 0x00, 0x24,
	0x8d, 0x05, 0x00, 0x00, 0x77,
	0x95, 0x80, 0x0e, 0x01, 0x05, 0x00, 0xe0,
	0xa4, 0x00, 0x43, 0x41, 0x4c, 0x49, 0x42, 0x00, 0x22, 0x40, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x7d,
	0x9c, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x61, 0x45, 0x46,
	0x9c, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc8, 0x42, 0xeb,
	0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x61, 0x45, 0x44,
	0x94, 0x04, 0x43, 0x41, 0x4c, 0x00, 0x21,
	0x8c, 0x05, 0x00, 0x00, 0x76,
	0x94, 0x80, 0x02, 0x01, 0x05, 0x00, 0xed,
	0xa3, 0x00, 0x41, 0x50, 0x4f, 0x53, 0x00, 0x00, 0x22, 0x00, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x72,
	0x9b, 0x01, 0x00, 0x00, 0x34, 0xc3, 0x00, 0x00, 0x33, 0x43, 0xe2,
	0x9b, 0x02, 0x00, 0x00, 0x48, 0xc3, 0x00, 0x00, 0x48, 0x43, 0xe6,
	0x9b, 0x03, 0x00, 0x00, 0x34, 0xc3, 0x00, 0x00, 0x33, 0x43, 0xe0,
	0x93, 0x04, 0x44, 0x45, 0x47, 0x00, 0x2e,
	0x8b, 0x05, 0x32, 0x32, 0x71,
	0x93, 0x80, 0x01, 0x01, 0x03, 0x00, 0xef,
	0xa2, 0x00, 0x50, 0x4f, 0x53, 0x00, 0x00, 0x00, 0x24, 0x00, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x34,
	0x9a, 0x01, 0x00, 0x00, 0xb4, 0xc3, 0x00, 0x00, 0xb4, 0x43, 0xe4,
	0x9a, 0x02, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe7,
	0x9a, 0x03, 0x00, 0x00, 0xb4, 0xc3, 0x00, 0x00, 0xb4, 0x43, 0xe6,
	0x92, 0x04, 0x44, 0x45, 0x47, 0x00, 0x2f,
	0x8a, 0x05, 0x28, 0x68, 0x30,
	0x92, 0x80, 0x01, 0x02, 0x0b, 0x00, 0xe5,
	0xa1, 0x00, 0x53, 0x50, 0x45, 0x45, 0x44, 0x00, 0x21, 0x00, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x39,
	0x99, 0x01, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe7,
	0x99, 0x02, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe4,
	0x99, 0x03, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe5,
	0x91, 0x04, 0x50, 0x43, 0x54, 0x00, 0x2d,
	0x89, 0x05, 0x30, 0x70, 0x33,
	0x91, 0x80, 0x01, 0x00, 0x04, 0x00, 0xeb,
	0xa0, 0x00, 0x50, 0x4f, 0x57, 0x45, 0x52, 0x00, 0x30, 0x00, 0x00, 0x00,
	0x05, 0x04, 0x00, 0x00, 0x00, 0x00, 0x31,
	0x98, 0x01, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe6,
	0x98, 0x02, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe5,
	0x98, 0x03, 0x00, 0x00, 0xc8, 0xc2, 0x00, 0x00, 0xc8, 0x42, 0xe4,
	0x90, 0x04, 0x50, 0x43, 0x54, 0x00, 0x2c,
	0x88, 0x05, 0x00, 0x50, 0x22,
	0x90, 0x80, 0x01, 0x00, 0x04, 0x00, 0xea,
	0x88, 0x06, 0x0e, 0x00, 0x7f,
	0xa0, 0x08, 0x00, 0x40, 0x00, 0x2e, 0x09, 0x47, 0x38, 0x33, 0x36, 0x36,
	0x36, 0x30, 0x00, 0x00, 0x00, 0x00, 0x7a,
	0xa0, 0x09, 0x88, 0x13, 0x00, 0x00, 0xfa, 0x00, 0x00, 0x00, 0x10, 0x27,
	0x00, 0x00, 0xbe, 0x05, 0x00, 0x00, 0xbb,
	0xa0, 0x0a, 0x98, 0x3a, 0x00, 0x00, 0x96, 0x00, 0x00, 0x00, 0x98, 0x3a,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xc3,
	0x98, 0x0b, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x6c,
	0x90, 0x0c, 0x00, 0x00, 0x00, 0x00, 0x63,
	0x04,
};

/*
 * Combined modes: the Technic Large motor's speed, position and absolute
 * position, set up with the WRITE Pybricks sent it and read from the DATA
 * message the motor answered with (both recorded).
 */
static void test_combo_technic_motor(struct kunit *test)
{
	static const u8 setup[] = { 0x5c, 0x23, 0x00, 0x10, 0x20, 0x30, 0x00,
				    0x00, 0x00, 0x80 };
	static const u8 combined[] = { 0xd8, 0x64, 0xff, 0xff, 0xff, 0xff, 0x17,
				       0x00, 0x00, 0x54 };
	static const struct ev3_uart_combo_entry e[] = {
		{ 1, 0 }, { 2, 0 }, { 3, 0 },
	};
	static const s32 want[] = { 100, -1, 23 };
	struct ctx *c = new_ctx(test);
	const struct ev3_uart_sensor *s = &c->p.sensor;
	u8 buf[EV3_UART_COMBO_MSG_LEN];
	unsigned int len = 0, j;
	int off;
	s32 v;

	feed(&c->p, technic_l_handshake, sizeof(technic_l_handshake),
	     sizeof(technic_l_handshake), &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, s->type, 46);
	KUNIT_EXPECT_EQ(test, s->num_modes, 6);
	KUNIT_EXPECT_STREQ(test, s->modes[1].name, "SPEED");
	KUNIT_EXPECT_STREQ(test, s->modes[3].name, "APOS");
	KUNIT_EXPECT_STREQ(test, s->modes[3].units, "DEG");
	KUNIT_EXPECT_EQ(test, s->num_combos, 1);
	KUNIT_EXPECT_EQ(test, s->combos[0], 0x000e);

	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 3, &len), 0);
	KUNIT_EXPECT_EQ(test, len, 7U);
	KUNIT_ASSERT_EQ(test, ev3_uart_build_combo(buf, 0, e, 3), (int)sizeof(setup));
	KUNIT_EXPECT_MEMEQ(test, buf, setup, sizeof(setup));

	/* The combined DATA comes with mode 0's header, 8 bytes. */
	ev3_uart_parser_start_data(&c->p);
	c->r.n = 0;
	feed(&c->p, combined, sizeof(combined), 3, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 1U);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 0);
	KUNIT_ASSERT_EQ(test, last(&c->r)->len, 8);
	for (j = 0; j < 3; j++) {
		off = ev3_uart_combo_offset(s, e, 3, j);
		KUNIT_ASSERT_GE(test, off, 0);
		KUNIT_ASSERT_EQ(test, ev3_uart_read_value(&s->modes[e[j].mode],
							  c->p.data + off, 8 - off, 0, &v), 0);
		KUNIT_EXPECT_EQ(test, v, want[j]);
	}
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_offset(s, e, 3, 3), -EINVAL);

	/* Two of them, in another order: the same combination. */
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, &e[1], 2, &len), 0);
	KUNIT_EXPECT_EQ(test, len, 6U);
	/* POWER is in no combination; CALIB's value 2 does not exist. */
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, (const struct ev3_uart_combo_entry[]){
		{ 0, 0 }, { 1, 0 } }, 2, &len), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, (const struct ev3_uart_combo_entry[]){
		{ 1, 0 }, { 4, 2 } }, 2, &len), -EINVAL);
}

/*
 * Combinations that cannot be: none offered, too many values, values that
 * could not be told from mode 0's own, an EV3 sensor; the BOOST motor's
 * recorded WRITE.
 */
static void test_combo_refused(struct kunit *test)
{
	static const u8 boost_motor[] = { 0x54, 0x22, 0x00, 0x10, 0x20, 0xb9 };
	struct ev3_uart_combo_entry e[EV3_UART_MAX_COMBO_ENTRIES + 1] = { };
	struct ctx *c = new_ctx(test);
	struct ev3_uart_sensor *s = &c->p.sensor;
	u8 buf[EV3_UART_COMBO_MSG_LEN];
	unsigned int len, i;

	e[0].mode = 1;
	e[1].mode = 2;
	KUNIT_ASSERT_EQ(test, ev3_uart_build_combo(buf, 0, e, 2), (int)sizeof(boost_motor));
	KUNIT_EXPECT_MEMEQ(test, buf, boost_motor, sizeof(boost_motor));
	KUNIT_EXPECT_EQ(test, ev3_uart_build_combo(buf, 8, e, 2), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_combo(buf, 0, e, 0), -EINVAL);

	feed(&c->p, boost_cds_handshake, sizeof(boost_cds_handshake),
	     sizeof(boost_cds_handshake), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	/* PROX and REFLT (0x004f has both): 2 bytes, longer than COLOR's 1. */
	e[0].mode = 1;
	e[1].mode = 3;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 2, &len), 0);
	KUNIT_EXPECT_EQ(test, len, 2U);
	/* RGB I's three values and COUNT. */
	for (i = 0; i < 3; i++) {
		e[i].mode = 6;
		e[i].index = i;
	}
	e[3].mode = 2;
	e[3].index = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 4, &len), 0);
	KUNIT_EXPECT_EQ(test, len, 10U);
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_offset(s, e, 4, 3), 6);
	/* IR Tx (mode 7) is in no combination. */
	e[0].mode = 7;
	e[0].index = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 2, &len), -EINVAL);
	/* Mode 0 alone: as long as mode 0's own DATA. */
	e[0].mode = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 1, &len), -EINVAL);
	/* Nine values: too many. */
	for (i = 0; i < EV3_UART_MAX_COMBO_ENTRIES + 1; i++) {
		e[i].mode = i & 1 ? 1 : 3;
		e[i].index = 0;
	}
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, EV3_UART_MAX_COMBO_ENTRIES, &len), 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, EV3_UART_MAX_COMBO_ENTRIES + 1, &len),
			-EINVAL);
	/* Not a Powered Up device; none offered. */
	s->lump = false;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 2, &len), -EINVAL);
	s->lump = true;
	s->num_combos = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_combo_find(s, e, 2, &len), -EINVAL);
}

/* The fast sync probe: SPEED 115200, as Pybricks sends it at 115200. */
static void test_build_speed(struct kunit *test)
{
	static const u8 fast[] = { 0x52, 0x00, 0xc2, 0x01, 0x00, 0x6e };
	/* The same message as the LEGO sensors' SPEED 57600. */
	static const u8 ev3[] = { 0x52, 0x00, 0xe1, 0x00, 0x00, 0x4c };
	u8 buf[EV3_UART_SPEED_MSG_LEN];

	KUNIT_ASSERT_EQ(test, ev3_uart_build_speed(buf, EV3_UART_SPEED_FAST),
			(size_t)EV3_UART_SPEED_MSG_LEN);
	KUNIT_EXPECT_MEMEQ(test, buf, fast, sizeof(fast));
	KUNIT_ASSERT_EQ(test, ev3_uart_build_speed(buf, 57600), sizeof(ev3));
	KUNIT_EXPECT_MEMEQ(test, buf, ev3, sizeof(ev3));
	KUNIT_EXPECT_EQ(test, ev3_uart_msg_len(buf[0]), sizeof(ev3));
}

/* A handshake with one mode and no SPEED (a device that omits it). */
static size_t enc_no_speed(u8 *buf)
{
	static const struct tmode m = { "TEST", { F0, F100 }, { F0, F100 }, NULL, 1, 0, 2, 0 };
	u8 type = 99;
	size_t len = 0;

	len += enc_cmd(buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_mode(buf + len, type, 0, &m);
	buf[len++] = EV3_UART_SYS_ACK;
	return len;
}

/* The probe answered: ACK, then the handshake at 115200, in any batches. */
static void test_fast_sync_answered(struct kunit *test)
{
	/*
	 * What a probe meets: garbled bytes, a broken TYPE, SYNC, NACK, 0xff
	 * (a whole TYPE starts a handshake at 2400: test_probe_meets_type).
	 */
	static const u8 junk[] = { 0x00, 0xff, 0x40, 0x3d, 0x83, 0x02, 0x52 };
	struct ev3_uart_event ev;
	size_t chunk, len;
	struct ctx *c;

	for (chunk = 1; chunk <= 64; chunk *= 4) {
		c = new_ctx(test);
		KUNIT_EXPECT_EQ(test, c->p.sync_speed, 2400U);
		KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_PROBE);
		KUNIT_EXPECT_EQ(test, c->p.sync_speed, EV3_UART_SPEED_FAST);
		/* Once at a time; nothing else takes the parser meanwhile. */
		KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), -EBUSY);
		KUNIT_EXPECT_EQ(test, ev3_uart_parser_select(&c->p, 0), -ENODEV);
		KUNIT_EXPECT_FALSE(test, ev3_uart_parser_tick(&c->p, &ev));
		ev3_uart_parser_start_data(&c->p);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_PROBE);

		/*
		 * Garbage and line errors are dropped: all but the last three
		 * bytes slid through the TYPE window, the line error emptied it.
		 */
		feed(&c->p, junk, sizeof(junk), chunk, &c->r);
		ev3_uart_parser_line_error(&c->p, &ev);
		KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_NONE);
		KUNIT_EXPECT_EQ(test, c->r.n, 0U);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_PROBE);
		KUNIT_EXPECT_EQ(test, c->p.garbage, (unsigned long)sizeof(junk) - 3);
		KUNIT_EXPECT_EQ(test, c->p.msg_len, 0);

		/* The ACK, and the handshake right behind it. */
		c->buf[0] = EV3_UART_SYS_ACK;
		len = 1 + enc_handshake(c->buf + 1, &sensors[0]);
		feed(&c->p, c->buf, len, chunk, &c->r);
		KUNIT_ASSERT_EQ(test, c->r.n, 3U);
		KUNIT_EXPECT_EQ(test, c->r.ev[0].type, EV3_UART_EV_FAST);
		KUNIT_EXPECT_EQ(test, c->r.ev[1].type, EV3_UART_EV_SYNC);
		KUNIT_EXPECT_EQ(test, c->r.ev[2].type, EV3_UART_EV_HANDSHAKE);
		KUNIT_EXPECT_EQ(test, c->p.sensor.type, 29);
		/* Its own SPEED counts. */
		KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 57600U);
		/* The host's wait ends after the ACK: the line stays fast. */
		KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), EV3_UART_SPEED_FAST);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_ACKED);
		ev3_uart_parser_start_data(&c->p);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_DATA);
	}

	/* No SPEED in a fast handshake: it stays at 115200. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	c->buf[0] = EV3_UART_SYS_ACK;
	len = 1 + enc_no_speed(c->buf + 1);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.speed, EV3_UART_SPEED_FAST);
}

/*
 * Issue 28: an EV3 sensor that starts its handshake (at 2400) while the host
 * probes, on a line that carries bytes whatever the speed (a pty): its TYPE
 * starts the handshake at 2400, in any batches, and its first handshake is
 * the one that connects.
 */
static void test_probe_meets_type(struct kunit *test)
{
	static const u8 type4[] = { 0x40, 0x04, 0xbb };
	struct ev3_uart_event ev;
	size_t chunk, len;
	struct ctx *c;

	for (chunk = 1; chunk <= 64; chunk *= 4) {
		c = new_ctx(test);
		len = enc_handshake(c->buf, &sensors[0]);
		/* Its first byte came before the probe, the rest during it. */
		feed(&c->p, c->buf, 1, 1, &c->r);
		KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
		feed(&c->p, c->buf + 1, 20, chunk, &c->r);
		KUNIT_ASSERT_EQ(test, c->r.n, 1U);
		KUNIT_EXPECT_EQ(test, c->r.ev[0].type, EV3_UART_EV_SYNC);
		KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_INFO);
		KUNIT_EXPECT_EQ(test, c->p.sync_speed, 2400U);
		/* The host's wait ends: back to 2400, where the rest comes. */
		KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), 2400U);
		feed(&c->p, c->buf + 21, len - 21, chunk, &c->r);
		KUNIT_ASSERT_EQ(test, c->r.n, 2U);
		KUNIT_EXPECT_EQ(test, c->r.ev[1].type, EV3_UART_EV_HANDSHAKE);
		KUNIT_EXPECT_EQ(test, c->p.sensor.type, 29);
		KUNIT_EXPECT_EQ(test, c->p.sensor.num_modes, 6);
		KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 57600U);
		KUNIT_EXPECT_EQ(test, c->p.garbage, 0UL);
	}

	/* All of it within the probe; without SPEED it stays at 2400. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	len = enc_no_speed(c->buf);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 2U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].type, EV3_UART_EV_SYNC);
	KUNIT_EXPECT_EQ(test, c->r.ev[1].type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 2400U);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), 2400U);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_ACKED);

	/* A TYPE of type 4: its 0x04 is no ACK to the probe. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	feed(&c->p, type4, sizeof(type4), 1, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].type, EV3_UART_EV_SYNC);
	KUNIT_EXPECT_EQ(test, c->p.sensor.type, 4);
	/* But an ACK after other bytes is one; a broken TYPE is not a TYPE. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	c->buf[0] = 0x40;
	c->buf[1] = 0x1d;
	c->buf[2] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, 3, 1, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].type, EV3_UART_EV_FAST);
	KUNIT_EXPECT_EQ(test, c->p.sync_speed, EV3_UART_SPEED_FAST);
	/* A line error in the probe empties the window. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	feed(&c->p, type4, 2, 2, &c->r);
	ev3_uart_parser_line_error(&c->p, &ev);
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_NONE);
	feed(&c->p, type4 + 2, 1, 1, &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 0U);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_PROBE);
}

/* The probe not answered, or a fast handshake that fails: 2400 again. */
static void test_fast_sync_unanswered(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	size_t len;

	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, 1200), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, 921600), -EINVAL);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	/*
	 * An EV3 sensor's handshake at 2400, read at 115200: each byte's low
	 * bits as 0x00 frames (mostly flagged as line errors too), never an
	 * ACK, whose one-bit pulse a slower line cannot make.
	 */
	len = enc_handshake(c->buf, &sensors[0]);
	memset(c->buf, 0x00, len / 2);
	memset(c->buf + len / 2, 0xff, len - len / 2);
	feed(&c->p, c->buf, len, 7, &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 0U);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), 2400U);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
	KUNIT_EXPECT_EQ(test, c->p.sync_speed, 2400U);
	/* Ending it again changes nothing. */
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), 2400U);
	/* Then the next handshake at 2400, without SPEED: 2400. */
	len = enc_no_speed(c->buf);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.speed, 2400U);
	/* Not while a handshake is under way. */
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), -EBUSY);

	/* A fast handshake broken by a line error: back to 2400. */
	c = new_ctx(test);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	c->buf[0] = EV3_UART_SYS_ACK;
	enc_handshake(c->buf + 1, &sensors[0]);
	feed(&c->p, c->buf, 10, 10, &c->r);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_INFO);
	/* A handshake under way cannot be probed. */
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), -EBUSY);
	ev3_uart_parser_line_error(&c->p, &ev);
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
	KUNIT_EXPECT_EQ(test, c->p.sync_speed, 2400U);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe_end(&c->p), 2400U);
	/* And a fast SYNC with no TYPE yet cannot be probed again. */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), 0);
	c->buf[0] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, 1, 1, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_FAST);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_probe(&c->p, EV3_UART_SPEED_FAST), -EBUSY);
	/* ev3_uart_parser_init() (the host's restart) returns to 2400. */
	ev3_uart_parser_init(&c->p);
	KUNIT_EXPECT_EQ(test, c->p.sync_speed, 2400U);
}

static void test_data_ext_mode(struct kunit *test)
{
	check_ext_mode(test, 64);
	check_ext_mode(test, 1);
	check_ext_mode(test, 5);
}

/* An EV3 sensor never sends EXT_MODE: its bytes stay garbage there. */
static void test_ext_mode_ignored_for_ev3(struct kunit *test)
{
	static const u8 ext8[] = { 0x46, 0x08, 0xb1 };
	struct ctx *c = new_ctx(test);
	unsigned long garbage;

	connect(test, c, &sensors[1]);
	garbage = c->p.garbage;
	feed(&c->p, ext8, sizeof(ext8), 1, &c->r);
	KUNIT_EXPECT_EQ(test, c->p.ext_mode, 0);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 0UL);
	KUNIT_EXPECT_EQ(test, c->p.garbage, garbage + 3);
}

/*
 * A Technic-motor-like device: 16 modes in the 4-byte MODES, NAME flags
 * after a short name, a mode of 14 values (like STATS), and mode 15.
 */
static void test_lump_16_modes_and_flags(struct kunit *test)
{
	static const u8 modes[4] = { 7, 7, 15, 3 };
	static const u8 fmt16[4] = { 14, 1, 5, 0 };
	static const u8 fmt8[4] = { 1, 0, 3, 0 };
	u8 name[16] = { 'P', 'O', 'S', 0, 0, 0, 0x62, 0x01, 0, 0, 0x05, 0x84 };
	u8 type = 46, data[32] = { };
	struct ctx *c = new_ctx(test);
	struct ev3_uart_chan chan;
	size_t len;
	int m;
	s32 v;

	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 4);
	for (m = 15; m >= 0; m--) {
		u8 plus8 = m >= 8 ? EV3_UART_INFO_MODE_PLUS_8 : 0;

		name[2] = 'A' + m;
		len += enc_info(c->buf + len, m & 7, EV3_UART_INFO_NAME | plus8, name, 16);
		if (m == 15)
			len += enc_string(c->buf + len, 7, EV3_UART_INFO_UNITS | plus8, "deg");
		len += enc_info(c->buf + len, m & 7, EV3_UART_INFO_FORMAT | plus8,
				m == 14 ? fmt16 : fmt8, 4);
	}
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, 3, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_modes, 16);
	KUNIT_EXPECT_EQ(test, c->p.sensor.num_view_modes, 4);
	KUNIT_EXPECT_STREQ(test, c->p.sensor.modes[15].name, "POP");
	KUNIT_EXPECT_STREQ(test, c->p.sensor.modes[0].name, "POA");
	KUNIT_EXPECT_EQ(test, c->p.sensor.modes[0].flags[0], 0x62);
	KUNIT_EXPECT_EQ(test, c->p.sensor.modes[15].flags[5], 0x84);
	KUNIT_EXPECT_EQ(test, c->p.sensor.modes[14].num_values, 14);
	/* Mode 15's value is an IIO channel like any other. */
	KUNIT_ASSERT_EQ(test, ev3_uart_chans_build(&c->p.sensor, &chan, 1), 1U);
	KUNIT_EXPECT_EQ(test, chan.mode, 15);
	KUNIT_EXPECT_EQ(test, chan.type, IIO_ANGL);

	ev3_uart_parser_start_data(&c->p);
	c->r.n = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 14), 0);
	data[26] = 0xfe;
	data[27] = 0xff;
	len = enc_cmd(c->buf, EV3_UART_CMD_EXT_MODE, (const u8 *)"\10", 1);
	len += enc_data(c->buf + len, 6, data, 32);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 14);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[14], c->p.data, 32, 13,
						  &v), 0);
	KUNIT_EXPECT_EQ(test, v, -2);
}

/* The same header means mode 0 or mode 8 by the last EXT_MODE. */
static void test_ext_mode_gives_the_header_its_mode(struct kunit *test)
{
	static const u8 modes[4] = { 7, 7, 8, 3 };
	static const u8 fmt8[4] = { 1, 0, 3, 0 };
	static const u8 ext0[] = { 0x46, 0x00, 0xb9 }, ext8[] = { 0x46, 0x08, 0xb1 };
	u8 type = 63, name[8] = { 'M', 0 }, v1 = 1;
	struct ctx *c = new_ctx(test);
	size_t len;
	int m, i;

	len = enc_cmd(c->buf, EV3_UART_CMD_TYPE, &type, 1);
	len += enc_cmd(c->buf + len, EV3_UART_CMD_MODES, modes, 4);
	for (m = 8; m >= 0; m--) {
		u8 plus8 = m >= 8 ? EV3_UART_INFO_MODE_PLUS_8 : 0;

		len += enc_info(c->buf + len, m & 7, EV3_UART_INFO_NAME | plus8, name, 8);
		len += enc_info(c->buf + len, m & 7, EV3_UART_INFO_FORMAT | plus8, fmt8, 4);
		name[0]++;
	}
	c->buf[len++] = EV3_UART_SYS_ACK;
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);
	ev3_uart_parser_start_data(&c->p);
	c->r.n = 0;

	/* Mode 0, header c0. */
	len = enc_data(c->buf, 0, &v1, 1);
	for (i = 0; i < 3; i++)
		feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 3U);

	/* EXT_MODE 8 without a SELECT: c0 is mode 8 now, old news, dropped. */
	feed(&c->p, ext8, sizeof(ext8), sizeof(ext8), &c->r);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 3U);

	/* SELECT 8: c0 after EXT_MODE 8 confirms it. */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 8), 0);
	for (i = 0; i < 3; i++)
		feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, c->r.n, 6U);
	KUNIT_EXPECT_EQ(test, c->r.ev[3].mode, 8);
	KUNIT_EXPECT_TRUE(test, c->r.ev[3].mode_changed);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 8);

	/* EXT_MODE 0 in the same batch as c0: mode 0, not delivered as 8. */
	memcpy(c->buf + len, ext0, sizeof(ext0));
	memmove(c->buf + sizeof(ext0), c->buf, len);
	memcpy(c->buf, ext0, sizeof(ext0));
	feed(&c->p, c->buf, len + sizeof(ext0), len + sizeof(ext0), &c->r);
	KUNIT_EXPECT_EQ(test, c->r.n, 6U);
	KUNIT_EXPECT_EQ(test, c->p.mode, 8);
	KUNIT_EXPECT_EQ(test, c->p.ext_mode, 0);
}

/* ---- data phase ---- */

static void test_data_decode_real_frames(struct kunit *test)
{
	/* Ultrasonic: C8 07 01 31 is 26.3 cm. */
	static const u8 us[] = { 0xc8, 0x07, 0x01, 0x31 };
	/* Gyro G&A: -41 deg, -86 deg/s. */
	static const u8 gyro_ga[] = { 0xd3, 0xd7, 0xff, 0xaa, 0xff, 0x51 };
	struct ctx *c = new_ctx(test);
	s32 v;

	connect(test, c, &sensors[1]);
	feed(&c->p, us, sizeof(us), sizeof(us), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->p.data, 2, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 263);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&c->p.sensor.modes[0], v), 263);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->p.data, 2, 1, &v),
			-ENXIO);

	c = new_ctx(test);
	connect(test, c, &sensors[2]);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 3), 0);
	feed(&c->p, gyro_ga, sizeof(gyro_ga), 1, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_TRUE(test, last(&c->r)->mode_changed);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[3], c->p.data, 4, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, -41);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[3], c->p.data, 4, 1, &v), 0);
	KUNIT_EXPECT_EQ(test, v, -86);
}

static void test_rgb_raw_checksum_quirk(struct kunit *test)
{
	/* Four values (R, G, B, LED off) and a checksum that is wrong. */
	u8 frame[10] = { 0xdc, 0x10, 0x00, 0x20, 0x00, 0x30, 0x00, 0x05, 0x00, 0x00 };
	struct ctx *c = new_ctx(test);
	s32 v;

	connect(test, c, &sensors[0]);
	ev3_uart_parser_select(&c->p, 4);
	frame[9] = ev3_uart_checksum(frame, 9) ^ 0x5a;
	feed(&c->p, frame, sizeof(frame), sizeof(frame), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 4);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[4], c->p.data, 8, 3, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 5);

	/* The same frame from any other sensor is a bad frame. */
	c = new_ctx(test);
	connect(test, c, &sensors[3]);	/* new gyro: mode 4 is 4 x S16 */
	ev3_uart_parser_select(&c->p, 4);
	feed(&c->p, frame, sizeof(frame), sizeof(frame), &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 0U);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 1UL);
}

/* @n keep-alive ticks, none of which may lose the sensor. */
static void tick(struct kunit *test, struct ev3_uart_parser *p, unsigned int n)
{
	struct ev3_uart_event ev;

	while (n--)
		KUNIT_EXPECT_FALSE(test, ev3_uart_parser_tick(p, &ev));
}

static void test_us_dc_in_mode5_tags(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	u8 v5[2] = { 0x4c, 0x00 }, frames[8];
	size_t len;
	s32 v;

	connect(test, c, &sensors[1]);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 6), 0);
	/* Spontaneous frames come tagged mode 5, NACK replies mode 6. */
	len = enc_data(frames, 5, v5, 2);
	len += enc_data(frames + len, 6, v5, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 2U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 6);
	KUNIT_EXPECT_TRUE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_TRUE(test, c->r.ev[0].us_dc_in);
	KUNIT_EXPECT_EQ(test, c->r.ev[1].mode, 6);
	KUNIT_EXPECT_FALSE(test, c->r.ev[1].us_dc_in);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[6], c->p.data, 2, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 76);

	/*
	 * Selecting mode 5 from mode 6 still works, once the sensor has had
	 * time to switch (see test_us_dc_old_mode_during_select()).
	 */
	c->r.n = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 5), 0);
	tick(test, &c->p, 2);
	len = enc_data(frames, 5, v5, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 5);
	KUNIT_EXPECT_TRUE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_FALSE(test, c->r.ev[0].us_dc_in);
}

/*
 * Issue 29: a sensor goes on in the old mode until it has carried out a
 * SELECT. Between US-DC-CM (5) and US-DC-IN (6) a message tagged mode 5 may
 * then be of either mode: it must confirm neither, nor be shown as the
 * old mode's, until the switch is known to be done.
 */
static void test_us_dc_old_mode_during_select(struct kunit *test)
{
	u8 cm[2] = { 111, 0 }, in[2] = { 76, 0 }, frames[8];
	struct ctx *c = new_ctx(test);
	size_t len;
	s32 v;

	connect(test, c, &sensors[1]);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 5), 0);
	len = enc_data(frames, 5, cm, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 5);

	/* 5 to 6: mode 5's 11.1 cm, then mode 6's own 7.6 in tagged 5. */
	c->r.n = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 6), 0);
	len = enc_data(frames, 5, cm, 2);
	feed(&c->p, frames, len, len, &c->r);
	len = enc_data(frames, 5, in, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 0U);
	KUNIT_EXPECT_EQ(test, c->p.pending_mode, 6);
	/* A NACK reply, tagged 6, confirms it. */
	len = enc_data(frames, 6, in, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 6);
	KUNIT_EXPECT_TRUE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[6], c->p.data, 2, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 76);
	/* Then the messages tagged 5 are mode 6's. */
	len = enc_data(frames, 5, in, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 2U);
	KUNIT_EXPECT_EQ(test, c->r.ev[1].mode, 6);
	KUNIT_EXPECT_TRUE(test, c->r.ev[1].us_dc_in);

	/* 6 to 5: what is tagged 5 is of either mode for a while... */
	c->r.n = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 5), 0);
	len = enc_data(frames, 5, in, 2);
	feed(&c->p, frames, len, len, &c->r);
	tick(test, &c->p, 1);
	KUNIT_EXPECT_EQ(test, c->p.select_ticks, 1);
	/* ...a NACK reply tagged 6 is the old mode's, and counts again... */
	len = enc_data(frames, 6, in, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 6);
	KUNIT_EXPECT_FALSE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_EQ(test, c->p.select_ticks, 0);
	tick(test, &c->p, 1);
	/* ...a SELECT sent again goes on counting... */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 5), 0);
	KUNIT_EXPECT_EQ(test, c->p.select_ticks, 1);
	len = enc_data(frames, 5, cm, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	/* ...and from the second keep-alive tick on, they are mode 5's. */
	tick(test, &c->p, 1);
	len = enc_data(frames, 5, cm, 2);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 2U);
	KUNIT_EXPECT_EQ(test, c->r.ev[1].mode, 5);
	KUNIT_EXPECT_TRUE(test, c->r.ev[1].mode_changed);
	KUNIT_EXPECT_FALSE(test, c->r.ev[1].us_dc_in);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[5], c->p.data, 2, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 111);
	/* The sensor was heard all along: no silent tick. */
	KUNIT_EXPECT_EQ(test, c->p.silent_ticks, 0);
}

static void test_select_and_stale_frames(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	u8 v[1] = { 42 }, frames[16];
	size_t len;

	connect(test, c, &sensors[0]);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_select(&c->p, 6), -EINVAL);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 2), 0);
	/* Until the switch is confirmed, mode 0 is still current... */
	len = enc_data(frames, 0, v, 1);
	/* ...the first new-mode frame confirms it... */
	len += enc_data(frames + len, 2, v, 1);
	len += enc_data(frames + len, 2, v, 1);
	/* ...and a late old-mode frame after that is dropped quietly. */
	len += enc_data(frames + len, 0, v, 1);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 3U);
	KUNIT_EXPECT_EQ(test, c->r.ev[0].mode, 0);
	KUNIT_EXPECT_FALSE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_EQ(test, c->r.ev[1].mode, 2);
	KUNIT_EXPECT_TRUE(test, c->r.ev[1].mode_changed);
	KUNIT_EXPECT_FALSE(test, c->r.ev[2].mode_changed);
	KUNIT_EXPECT_EQ(test, c->p.mode, 2);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 0UL);

	/* Selecting the current mode is confirmed without a change. */
	c->r.n = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 2), 0);
	len = enc_data(frames, 2, v, 1);
	feed(&c->p, frames, len, len, &c->r);
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 1U);
	KUNIT_EXPECT_FALSE(test, c->r.ev[0].mode_changed);
	KUNIT_EXPECT_EQ(test, c->p.pending_mode, EV3_UART_NO_MODE);

	/* SELECT outside the data phase. */
	c = new_ctx(test);
	KUNIT_EXPECT_EQ(test, ev3_uart_parser_select(&c->p, 0), -ENODEV);
}

static void test_data_resync_after_garbage(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	u8 v[1] = { 7 }, b[64];
	size_t len = 0;

	connect(test, c, &sensors[4]);
	/* A glitch byte after the speed change, then two good frames. */
	b[len++] = 0xff;
	b[len++] = 0xfc;
	len += enc_data(b + len, 0, v, 1);
	/* Garbage, including a plausible header swallowing the next frame. */
	b[len++] = 0x13;
	b[len++] = 0xc1;
	len += enc_data(b + len, 0, v, 1);
	len += enc_data(b + len, 0, v, 1);
	feed(&c->p, b, len, 3, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	/* The frame after 0xc1 is recovered by re-parsing the bad frame. */
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 3U);
}

static void test_too_many_bad_frames(struct kunit *test)
{
	static const u8 good[] = { 0xc0, 0x07, 0x38 };
	struct ctx *c = new_ctx(test);
	u8 frame[3] = { 0xc0, 0x01, 0x00 };	/* wrong checksum */
	int i;

	connect(test, c, &sensors[0]);
	/* Before the first good message: garbage of the speed change. */
	for (i = 0; i < 3 * EV3_UART_MAX_DATA_ERR; i++)
		feed(&c->p, frame, 3, 3, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	feed(&c->p, good, 3, 3, &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	for (i = 0; i < EV3_UART_MAX_DATA_ERR; i++)
		feed(&c->p, frame, 3, 3, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	feed(&c->p, frame, 3, 3, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
}

static void test_keepalive_ticks(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	u8 v[1] = { 1 }, frame[3];
	int i;

	connect(test, c, &sensors[0]);
	enc_data(frame, 0, v, 1);
	/* Data every period: never lost. */
	for (i = 0; i < 20; i++) {
		feed(&c->p, frame, 3, 3, &c->r);
		KUNIT_EXPECT_FALSE(test, ev3_uart_parser_tick(&c->p, &ev));
	}
	/* Silence: lost on the seventh silent period (~700 ms). */
	for (i = 0; i < EV3_UART_MAX_DATA_ERR; i++)
		KUNIT_EXPECT_FALSE(test, ev3_uart_parser_tick(&c->p, &ev));
	KUNIT_EXPECT_TRUE(test, ev3_uart_parser_tick(&c->p, &ev));
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
	/* And the next handshake is accepted. */
	connect(test, c, &sensors[1]);
	KUNIT_EXPECT_EQ(test, c->p.sensor.type, 30);
}

static void test_bytes_dropped_while_acked(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	size_t len = enc_handshake(c->buf, &sensors[0]);
	u8 v[1] = { 1 };

	/* 57600-baud bytes seen at 2400 before the switch are junk. */
	len += enc_data(c->buf + len, 0, v, 1);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 0U);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_ACKED);
}

static void test_line_errors(struct kunit *test)
{
	static const u8 data[] = { 0xc0, 0x07, 0x38 };	/* COL-REFLECT 7 */
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	int i;
	size_t len = enc_handshake(c->buf, &sensors[0]);

	/* In the handshake: start over, and the whole handshake still works. */
	feed(&c->p, c->buf, 20, 20, &c->r);
	ev3_uart_parser_line_error(&c->p, &ev);
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
	feed(&c->p, c->buf, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_HANDSHAKE);

	/*
	 * In the data phase, before the first good message: garbage from the
	 * speed change, however much of it.
	 */
	c = new_ctx(test);
	connect(test, c, &sensors[0]);
	for (i = 0; i < 3 * EV3_UART_MAX_DATA_ERR; i++) {
		ev3_uart_parser_line_error(&c->p, &ev);
		KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_NONE);
	}
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_DATA);
	/* After it: counted, fatal only when repeated. */
	feed(&c->p, data, sizeof(data), sizeof(data), &c->r);
	KUNIT_ASSERT_EQ(test, last(&c->r)->type, EV3_UART_EV_DATA);
	for (i = 0; i < EV3_UART_MAX_DATA_ERR; i++) {
		ev3_uart_parser_line_error(&c->p, &ev);
		KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_NONE);
	}
	ev3_uart_parser_line_error(&c->p, &ev);
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
}

/* ---- the data phase, whole messages and parts of them in a batch ---- */

/* One GYRO-ANG message (mode 0, S16) of the value @v. */
static size_t enc_gyro_ang(u8 *buf, s16 v)
{
	u8 payload[2];

	put_unaligned_le16(v, payload);
	return enc_data(buf, 0, payload, 2);
}

/* Feed @len bytes in one call; the bytes it took, and the event in @ev. */
static size_t feed_once(struct ctx *c, const u8 *buf, size_t len,
			struct ev3_uart_event *ev)
{
	return ev3_uart_parser_feed(&c->p, buf, len, ev);
}

static void test_data_whole_messages(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	u8 b[8];
	size_t len;
	s32 v;
	int i;

	connect(test, c, &sensors[2]);
	/* Each message its own event, its value in @p->data. */
	for (i = 0; i < 3; i++) {
		len = enc_gyro_ang(b, -100 + i);
		KUNIT_ASSERT_EQ(test, feed_once(c, b, len, &ev), len);
		KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_DATA);
		KUNIT_EXPECT_EQ(test, ev.mode, 0);
		KUNIT_EXPECT_FALSE(test, ev.mode_changed);
		KUNIT_EXPECT_EQ(test, ev.len, 2);
		KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->p.data,
							  ev.len, 0, &v), 0);
		KUNIT_EXPECT_EQ(test, v, -100 + i);
	}
	KUNIT_EXPECT_EQ(test, c->p.frames, 3UL);
	KUNIT_EXPECT_EQ(test, c->p.msg_len, 0);
	KUNIT_EXPECT_TRUE(test, c->p.data_since_tick);
}

static void test_data_split_everywhere(struct kunit *test)
{
	/* IR-SEEK: eight S8 values, an 8-byte payload. */
	static const u8 seek[8] = { 1, 0xfe, 3, 0xfc, 5, 0xfa, 7, 0xf8 };
	struct ctx *c;
	struct ev3_uart_event ev;
	u8 b[16];
	size_t len, k;
	int warm;

	/* Split after every byte, in the SELECT's first message or a later one. */
	for (warm = 0; warm < 2; warm++) {
		for (k = 1; k < 10; k++) {
			c = new_ctx(test);
			connect(test, c, &sensors[4]);
			KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 1), 0);
			len = enc_data(b, 1, seek, 8);
			KUNIT_ASSERT_EQ(test, len, 10U);
			if (warm) {
				/* One confirms the SELECT, one more. */
				feed(&c->p, b, len, len, &c->r);
				feed(&c->p, b, len, len, &c->r);
				KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 2U);
			}
			KUNIT_EXPECT_EQ(test, feed_once(c, b, k, &ev), k);
			KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_NONE);
			KUNIT_EXPECT_EQ(test, c->p.msg_len, k);
			KUNIT_EXPECT_EQ(test, feed_once(c, b + k, len - k, &ev), len - k);
			KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_DATA);
			KUNIT_EXPECT_EQ(test, ev.mode, 1);
			KUNIT_EXPECT_EQ(test, ev.mode_changed, !warm);
			KUNIT_EXPECT_EQ(test, ev.len, 8);
			KUNIT_EXPECT_MEMEQ(test, c->p.data, seek, 8);
			KUNIT_EXPECT_EQ(test, c->p.msg_len, 0);
			KUNIT_EXPECT_EQ(test, c->p.bad_frames, 0UL);
		}
	}
}

static void test_data_back_to_back(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	u8 b[16];
	size_t len, off, used;
	s32 v;

	connect(test, c, &sensors[2]);
	len = enc_gyro_ang(b, 10);
	len += enc_gyro_ang(b + len, 20);
	len += enc_gyro_ang(b + len, 30);
	/* One event a call, each right after its message's last byte. */
	for (off = 0, v = 10; off < len; off += used, v += 10) {
		s32 got;

		used = feed_once(c, b + off, len - off, &ev);
		KUNIT_ASSERT_EQ(test, used, 4U);
		KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_DATA);
		KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->p.data,
							  ev.len, 0, &got), 0);
		KUNIT_EXPECT_EQ(test, got, v);
	}
	KUNIT_EXPECT_EQ(test, c->p.frames, 3UL);
}

static void test_data_bad_checksum_mid_batch(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	u8 b[16];
	size_t len, bad;
	s32 v;

	connect(test, c, &sensors[2]);
	len = enc_gyro_ang(b, 1);
	bad = len;
	len += enc_gyro_ang(b + len, 2);
	b[bad + 3] ^= 0x5a;
	len += enc_gyro_ang(b + len, 3);
	feed(&c->p, b, len, len, &c->r);
	/* The bad one is dropped and counted; the good one after it is read. */
	KUNIT_ASSERT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 2U);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_ERROR), 0U);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 1UL);
	KUNIT_EXPECT_EQ(test, c->p.data_err, 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->r.data[1], 2, 0,
						  &v), 0);
	KUNIT_EXPECT_EQ(test, v, 3);
	KUNIT_EXPECT_EQ(test, c->p.replay_pos, c->p.replay_len);

	/* Bad frames in a row end the connection. */
	for (bad = 0; bad <= EV3_UART_MAX_DATA_ERR; bad++) {
		len = enc_gyro_ang(b, 4);
		b[3] ^= 0x5a;
		feed(&c->p, b, len, len, &c->r);
	}
	KUNIT_EXPECT_EQ(test, last(&c->r)->type, EV3_UART_EV_ERROR);
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
}

static void test_data_rgb_raw_in_batches(struct kunit *test)
{
	static const u8 rgb[8] = { 0x10, 0x00, 0x20, 0x00, 0x30, 0x00, 0x05, 0x00 };
	struct ctx *c = new_ctx(test);
	u8 b[64];
	size_t len = 0, chunk;
	int i;

	connect(test, c, &sensors[0]);
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 4), 0);
	/* Five RGB-RAW messages, all but the third with a wrong checksum. */
	for (i = 0; i < 5; i++) {
		len += enc_data(b + len, 4, rgb, 8);
		if (i != 2)
			b[len - 1] ^= 0x5a;
	}
	for (chunk = 1; chunk <= len; chunk++) {
		c->r.n = 0;
		feed(&c->p, b, len, chunk, &c->r);
		KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 5U);
		KUNIT_EXPECT_EQ(test, last(&c->r)->mode, 4);
		KUNIT_EXPECT_MEMEQ(test, c->r.data[4], rgb, 8);
	}
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 0UL);

	/* Another mode of the colour sensor: a wrong checksum is wrong. */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 3), 0);
	len = enc_data(b, 3, rgb, 4);
	feed(&c->p, b, len, len, &c->r);
	len = enc_data(b, 3, rgb, 4);
	b[len - 1] ^= 0x5a;
	c->r.n = 0;
	feed(&c->p, b, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, count(&c->r, EV3_UART_EV_DATA), 0U);
	KUNIT_EXPECT_EQ(test, c->p.bad_frames, 1UL);
}

static void test_data_straddling_batch_end(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	u8 b[16];
	size_t len;
	s32 v;

	connect(test, c, &sensors[2]);
	len = enc_gyro_ang(b, 5);
	len += enc_gyro_ang(b + len, 6);
	len += enc_gyro_ang(b + len, 7);
	/* First batch: a message and half the next... */
	KUNIT_ASSERT_EQ(test, feed_once(c, b, 6, &ev), 4U);
	KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_DATA);
	KUNIT_ASSERT_EQ(test, feed_once(c, b + 4, 2, &ev), 2U);
	KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_NONE);
	KUNIT_EXPECT_EQ(test, c->p.msg_len, 2);
	/* ...a SELECT in between... */
	KUNIT_ASSERT_EQ(test, ev3_uart_parser_select(&c->p, 1), 0);
	/* ...second batch: its rest, then the last message. */
	KUNIT_ASSERT_EQ(test, feed_once(c, b + 6, len - 6, &ev), 2U);
	KUNIT_ASSERT_EQ(test, ev.type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, ev.mode, 0);	/* an old-mode message: not news */
	KUNIT_EXPECT_FALSE(test, ev.mode_changed);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&c->p.sensor.modes[0], c->p.data, 2, 0, &v),
			0);
	KUNIT_EXPECT_EQ(test, v, 6);
	KUNIT_ASSERT_EQ(test, feed_once(c, b + 8, len - 8, &ev), 4U);
	KUNIT_EXPECT_EQ(test, ev.type, EV3_UART_EV_DATA);
	KUNIT_EXPECT_EQ(test, c->p.pending_mode, 1);
}

static void test_data_err_after_line_error(struct kunit *test)
{
	struct ctx *c = new_ctx(test);
	struct ev3_uart_event ev;
	u8 b[8];
	size_t len;

	connect(test, c, &sensors[2]);
	len = enc_gyro_ang(b, 1);
	feed(&c->p, b, len, len, &c->r);
	/* A line error puts a bad frame on the count; a good frame takes it off. */
	ev3_uart_parser_line_error(&c->p, &ev);
	KUNIT_EXPECT_EQ(test, c->p.data_err, 1);
	feed(&c->p, b, len, len, &c->r);
	KUNIT_EXPECT_EQ(test, c->p.data_err, 0);
	/* The sensor lost: a new handshake, a new data phase. */
	while (!ev3_uart_parser_tick(&c->p, &ev))
		;
	KUNIT_EXPECT_EQ(test, c->p.state, EV3_UART_STATE_SYNC);
}

static void test_handshake_every_batch_size(struct kunit *test)
{
	int chunk;

	/* The old gyro, and the infrared sensor with its 00 ff. */
	for (chunk = 1; chunk <= 40; chunk++) {
		check_sensor(test, &sensors[2], chunk);
		check_sensor(test, &sensors[4], chunk);
	}
}

/* ---- values ---- */

static void test_f32_to_fixed(struct kunit *test)
{
	s32 v;

	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(F1020_1875, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 1020);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(F1020_1875, 4, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 10201875);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(F255, 1, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 2550);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(FM180, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, -180);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(FM32768, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, -32768);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x3f000000, 0, &v), 0);	/* 0.5 */
	KUNIT_EXPECT_EQ(test, v, 1);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0xbf000000, 0, &v), 0);	/* -0.5 */
	KUNIT_EXPECT_EQ(test, v, -1);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x3dcccccd, 1, &v), 0);	/* 0.1 */
	KUNIT_EXPECT_EQ(test, v, 1);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x00000001, 9, &v), 0);	/* subnormal */
	KUNIT_EXPECT_EQ(test, v, 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x4f000000, 0, &v), -ERANGE); /* 2^31 */
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0xcf000000, 0, &v), 0);	/* -2^31 */
	KUNIT_EXPECT_EQ(test, v, S32_MIN);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(FNAN, 0, &v), -ERANGE);
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x7f800000, 0, &v), -ERANGE); /* +inf */
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(0x7f7fffff, 0, &v), -ERANGE); /* FLT_MAX */
	KUNIT_EXPECT_EQ(test, ev3_uart_f32_to_fixed(F1, 10, &v), -EINVAL);
}

static void test_scale_value(struct kunit *test)
{
	struct ev3_uart_mode m = {
		.raw_min = 0, .raw_max = 1000, .si_min = -500, .si_max = 500,
	};

	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, 0), -500);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, 1000), 500);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, 501), 1);
	/* A zero raw span cannot scale: the value is shown as it is. */
	m.raw_max = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, 77), 77);
	/* Extreme spans saturate rather than overflow. */
	m.raw_min = S32_MIN;
	m.raw_max = S32_MAX;
	m.si_min = S32_MIN;
	m.si_max = S32_MAX - 1;
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, S32_MAX), S32_MAX - 1);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, S32_MIN), S32_MIN);
	/*
	 * A value far outside a one-wide RAW range, on the widest SI range
	 * (all as a sensor can send them in f32): 2^31 + 2^24 times the SI
	 * span overflows 64 bits even after dividing (found by fuzzing).
	 */
	m.raw_min = -16777216;
	m.raw_max = -16777215;
	m.si_min = S32_MIN;
	m.si_max = 2147483520;
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, S32_MAX), S32_MAX);
	m.raw_max = -16777217;
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, S32_MAX), S32_MIN);
	/*
	 * Found by the whole-driver fuzzer: RAW -2e9..0 onto SI
	 * -2e9..2147483520, raw 1e9. The product needs 66 bits; dividing
	 * first gave 1 * span - 2e9 = 2147483520, the exact value is
	 * 4221225280, saturated.
	 */
	m.raw_min = -2000000000;
	m.raw_max = 0;
	m.si_min = -2000000000;
	m.si_max = 2147483520;
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, 1000000000), S32_MAX);
	KUNIT_EXPECT_EQ(test, ev3_uart_scale_value(&m, -1000000000), 73741760);
}

static void test_float_values(struct kunit *test)
{
	struct ev3_uart_mode m = {
		.num_values = 2, .data_type = EV3_UART_DATA_FLOAT, .decimals = 2,
	};
	/* 12.5 and NaN, little endian. */
	static const u8 data[8] = { 0x00, 0x00, 0x48, 0x41, 0x00, 0x00, 0xc0, 0x7f };
	s32 v;

	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&m, data, 8, 0, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 1250);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&m, data, 8, 1, &v), -ERANGE);
	KUNIT_EXPECT_EQ(test, ev3_uart_read_value(&m, data, 6, 1, &v), -EINVAL);
}

/* ---- host messages ---- */

static void test_build_messages(struct kunit *test)
{
	static const u8 gyro_reset[] = { 0x44, 0x11, 0xaa };
	static const u8 fac_cal[] = { 0x64, 'L', 'E', 'G', 'O', '-', 'F', 'A', 'C', '-',
				      'C', 'A', 'L', '-', '1', 0x00, 0x00, 0x8c };
	static const u8 select2[] = { 0x43, 0x02, 0xbe };
	u8 buf[EV3_UART_MAX_PAYLOAD + 2], data[33] = { 1, 2, 3 };

	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, (const u8 *)"\x11", 1), 3);
	KUNIT_EXPECT_MEMEQ(test, buf, gyro_reset, sizeof(gyro_reset));
	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, (const u8 *)"LEGO-FAC-CAL-1", 14), 18);
	KUNIT_EXPECT_MEMEQ(test, buf, fac_cal, sizeof(fac_cal));
	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, data, 3), 6);
	KUNIT_EXPECT_EQ(test, buf[0], 0x54);
	KUNIT_EXPECT_EQ(test, buf[4], 0);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, data, 32), 34);
	KUNIT_EXPECT_EQ(test, buf[0], 0x6c);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, data, 0), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_write(buf, data, 33), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_select(buf, 2), (size_t)3);
	KUNIT_EXPECT_MEMEQ(test, buf, select2, sizeof(select2));
	KUNIT_EXPECT_EQ(test, ev3_uart_build_ack(buf), (size_t)1);
	KUNIT_EXPECT_EQ(test, buf[0], 0x04);
	KUNIT_EXPECT_EQ(test, ev3_uart_build_nack(buf), (size_t)1);
	KUNIT_EXPECT_EQ(test, buf[0], 0x02);
}

/* ---- IIO channels and mode names (ev3_uart_chan.c) ---- */

static void test_mul_div(struct kunit *test)
{
	u64 q;

	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(10, 3, 4, true, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 8ULL);			/* 7.5 rounds up */
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(7, 1, 4, true, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 2ULL);			/* 1.75 */
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(7, 1, 4, false, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 1ULL);			/* truncated */
	/* 3e9 * 4147483520 / 2e9: 66 bits, then exactly 6221225280. */
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(3000000000ULL, 4147483520ULL, 2000000000ULL,
					       false, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 6221225280ULL);
	/* Products beyond 64 bits are exact. */
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(1ULL << 40, 1ULL << 40, 1ULL << 30, true, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 1ULL << 50);
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(U64_MAX, U64_MAX, U64_MAX, true, &q), -EOVERFLOW);
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(1ULL << 62, 4, 2, true, &q), -EOVERFLOW);
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(1ULL << 62, 2, 2, true, &q), 0);
	KUNIT_EXPECT_EQ(test, q, 1ULL << 62);
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(1, 1, 0, true, &q), -EOVERFLOW);
	/* The quotient the divide error came from: 2e7 C over a 1-wide range. */
	KUNIT_EXPECT_EQ(test, ev3_uart_mul_div(20000000, 1000000000000ULL, 1, true, &q),
			-EOVERFLOW);
}

static void test_chan_scale(struct kunit *test)
{
	struct ev3_uart_mode m = {
		.raw_min = 0, .raw_max = 2550, .si_min = 0, .si_max = 2550,
		.num_values = 1, .data_type = EV3_UART_DATA_S16, .decimals = 1,
	};
	struct ev3_uart_chan c;

	/* US-DIST-CM: 0.1 cm per raw unit, in metres. */
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_scale(&m, 10000000, &c), 0);
	KUNIT_EXPECT_EQ(test, c.scale_val, 0);
	KUNIT_EXPECT_EQ(test, c.scale_val2, 1000000);
	KUNIT_EXPECT_EQ(test, c.offset_val, 0);
	KUNIT_EXPECT_EQ(test, c.offset_val2, 0);

	/* A temperature: raw 0..1000 is -40.0..85.0 C, shown in m°C. */
	m.raw_min = 0;
	m.raw_max = 1000;
	m.si_min = -400;
	m.si_max = 850;
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_scale(&m, 1000000000000ULL, &c), 0);
	KUNIT_EXPECT_EQ(test, c.scale_val, 125);	/* 0.125 C = 125 m°C */
	KUNIT_EXPECT_EQ(test, c.scale_val2, 0);
	KUNIT_EXPECT_EQ(test, c.offset_val, -320);	/* (0 - 320) * 125 = -40000 */
	KUNIT_EXPECT_EQ(test, c.offset_val2, 0);

	/* Inverted: raw 0..100 is 100..0. */
	m.si_min = 100;
	m.si_max = 0;
	m.raw_max = 100;
	m.decimals = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_scale(&m, 1000000000, &c), 0);
	KUNIT_EXPECT_EQ(test, c.scale_val, -1);
	KUNIT_EXPECT_EQ(test, c.scale_val2, 0);
	KUNIT_EXPECT_EQ(test, c.offset_val, -100);	/* (raw - 100) * -1 */

	/* Issue 17: RAW 0..1, SI 0..2e7 in C: too large a scale, no trap. */
	m.raw_min = 0;
	m.raw_max = 1;
	m.si_min = 0;
	m.si_max = 20000000;
	KUNIT_EXPECT_EQ(test, ev3_uart_chan_scale(&m, 1000000000000ULL, &c), -ERANGE);
	/* The widest spans the parser lets through, both ways round. */
	m.raw_min = S32_MIN;
	m.raw_max = S32_MAX;
	m.si_min = S32_MAX;
	m.si_max = S32_MIN;
	KUNIT_EXPECT_EQ(test, ev3_uart_chan_scale(&m, 1000000000000ULL, &c), 0);
	KUNIT_EXPECT_EQ(test, c.scale_val, -1000);
	m.si_min = S32_MIN;
	m.si_max = S32_MIN + 1;
	m.decimals = 9;
	/* 1e-9 of a unit over 2^32 raw units: too small to show. */
	KUNIT_EXPECT_EQ(test, ev3_uart_chan_scale(&m, 1000000000, &c), -ERANGE);
	/* An offset beyond an int: SI 2^31-1..2^31 over raw 0..1. */
	m.raw_min = 0;
	m.raw_max = 1;
	m.si_min = S32_MAX - 1;
	m.si_max = S32_MAX;
	m.decimals = 0;
	KUNIT_EXPECT_EQ(test, ev3_uart_chan_scale(&m, 1000000000, &c), 0);
	KUNIT_EXPECT_EQ(test, c.offset_val, S32_MAX - 1);
	m.raw_min = -2;
	KUNIT_EXPECT_EQ(test, ev3_uart_chan_scale(&m, 1000000000, &c), -ERANGE);
}

static void test_chan_scale_floats(struct kunit *test)
{
	struct ev3_uart_mode m = {
		.raw_min = 0, .raw_max = 1023, .si_min = 0, .si_max = 1000000000,
		.num_values = 1, .data_type = EV3_UART_DATA_FLOAT, .decimals = 9,
	};
	struct ev3_uart_chan c;
	u8 data[4] = { 0x00, 0x00, 0x34, 0x43 };	/* 180.0 */
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	s32 v;

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->num_modes = 1;

	/* Degrees with 9 decimals would be 1.7e-11 rad: keep 4 decimals. */
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_scale(&m, 17453293, &c), 0);
	KUNIT_EXPECT_EQ(test, c.decimals, 4);
	KUNIT_EXPECT_EQ(test, c.scale_val, 0);
	KUNIT_EXPECT_EQ(test, c.scale_val2, 1745);
	KUNIT_EXPECT_EQ(test, c.offset_val, 0);
	s->modes[0] = m;
	c.mode = 0;
	c.index = 0;
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_read(s, &c, data, 4, &v), 0);
	KUNIT_EXPECT_EQ(test, v, 1800000);
	/* In m°C nine decimals keep their precision. */
	KUNIT_ASSERT_EQ(test, ev3_uart_chan_scale(&m, 1000000000000ULL, &c), 0);
	KUNIT_EXPECT_EQ(test, c.decimals, 9);
	KUNIT_EXPECT_EQ(test, c.scale_val2, 1000);
}

/* Issue 17: 8 modes of 32 s8 values in degrees: 256 channels. */
static void test_chans_bounded(struct kunit *test)
{
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	struct ev3_uart_chan *chans;
	unsigned int i, n;

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->type = 88;
	s->num_modes = EV3_UART_MAX_MODES;
	for (i = 0; i < EV3_UART_MAX_MODES; i++) {
		struct ev3_uart_mode *m = &s->modes[i];

		snprintf(m->name, sizeof(m->name), "M%u", i);
		strscpy(m->units, i % 2 ? "deg" : "cm", sizeof(m->units));
		m->raw_max = 1023;
		m->si_max = 1023;
		m->num_values = EV3_UART_MAX_PAYLOAD;
		m->data_type = EV3_UART_DATA_S8;
		m->figures = 4;
	}
	n = ev3_uart_chans_build(s, NULL, 0);
	KUNIT_EXPECT_EQ(test, n, (unsigned int)EV3_UART_MAX_CHANS);

	/* Never more than the room given; a guard after it stays intact. */
	chans = kunit_kzalloc(test, 11 * sizeof(*chans), GFP_KERNEL);
	KUNIT_ASSERT_NOT_NULL(test, chans);
	memset(&chans[10], 0xa5, sizeof(chans[10]));
	KUNIT_EXPECT_EQ(test, ev3_uart_chans_build(s, chans, 10), n);
	KUNIT_EXPECT_EQ(test, chans[10].mode, 0xa5);
	KUNIT_EXPECT_EQ(test, chans[9].mode, 0);
	KUNIT_EXPECT_EQ(test, chans[9].index, 9);
	KUNIT_EXPECT_EQ(test, chans[9].channel, 9);

	/* A num_values the parser would refuse is still bounded. */
	s->modes[0].num_values = 200;
	KUNIT_EXPECT_EQ(test, ev3_uart_chans_build(s, NULL, 0), n);
	/* Units without an IIO type: no channel. */
	for (i = 0; i < EV3_UART_MAX_MODES; i++)
		strscpy(s->modes[i].units, "pct", sizeof(s->modes[i].units));
	KUNIT_EXPECT_EQ(test, ev3_uart_chans_build(s, NULL, 0), 0U);
}

/*
 * Every channel's IIO name (type, modifier or index) is unique: the IIO
 * core refuses a device with two attributes of one name.
 */
static void expect_unique_chans(struct kunit *test, const struct ev3_uart_sensor *s,
				unsigned int want)
{
	struct ev3_uart_chan *chans;
	unsigned int i, j, n;

	n = ev3_uart_chans_build(s, NULL, 0);
	KUNIT_EXPECT_EQ(test, n, want);
	chans = kunit_kzalloc(test, (n ?: 1) * sizeof(*chans), GFP_KERNEL);
	KUNIT_ASSERT_NOT_NULL(test, chans);
	KUNIT_ASSERT_EQ(test, ev3_uart_chans_build(s, chans, n), n);
	for (i = 0; i < n; i++) {
		for (j = i + 1; j < n; j++) {
			bool same = chans[i].type == chans[j].type &&
				    chans[i].modifier == chans[j].modifier &&
				    (chans[i].modifier ||
				     chans[i].channel == chans[j].channel);

			KUNIT_EXPECT_EQ_MSG(test, same, false,
					    "type %u: channels %u and %u (modes %u and %u) share a name",
					    s->type, i, j, chans[i].mode, chans[j].mode);
		}
	}
}

/* Issue 28: a colour sensor (or Powered Up one) with two RGB modes of one name. */
static void test_chans_twin_rgb_modes(struct kunit *test)
{
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	struct ev3_uart_chan chans[8];
	unsigned int i;

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->type = EV3_UART_TYPE_COLOR;
	s->num_modes = 3;
	for (i = 0; i < s->num_modes; i++) {
		struct ev3_uart_mode *m = &s->modes[i];

		strscpy(m->name, "RGB-RAW", sizeof(m->name));
		m->raw_max = 1020;
		m->si_max = 1020;
		m->num_values = 4;
		m->data_type = EV3_UART_DATA_S16;
		m->figures = 4;
	}
	/* One mode: red, green, blue, then the fourth value indexed. */
	s->num_modes = 1;
	expect_unique_chans(test, s, 4);
	s->num_modes = 3;
	expect_unique_chans(test, s, 12);
	/* The first mode keeps the modifiers; the twins' values are indexed. */
	KUNIT_ASSERT_EQ(test, ev3_uart_chans_build(s, chans, ARRAY_SIZE(chans)), 12U);
	KUNIT_EXPECT_EQ(test, chans[0].modifier, IIO_MOD_LIGHT_RED);
	KUNIT_EXPECT_EQ(test, chans[2].modifier, IIO_MOD_LIGHT_BLUE);
	KUNIT_EXPECT_EQ(test, chans[3].modifier, 0);
	KUNIT_EXPECT_EQ(test, chans[3].channel, 0);
	KUNIT_EXPECT_EQ(test, chans[4].mode, 1);
	KUNIT_EXPECT_EQ(test, chans[4].modifier, 0);
	KUNIT_EXPECT_EQ(test, chans[4].channel, 1);
	KUNIT_EXPECT_EQ(test, chans[7].channel, 4);

	/* Twin RGB I on the Powered Up colour sensors, after another mode. */
	s->lump = true;
	s->type = EV3_UART_TYPE_SPIKE_COLOR;
	strscpy(s->modes[0].name, "REFLT", sizeof(s->modes[0].name));
	s->modes[0].num_values = 1;
	for (i = 1; i < s->num_modes; i++)
		strscpy(s->modes[i].name, "RGB I", sizeof(s->modes[i].name));
	expect_unique_chans(test, s, 9);
	s->type = EV3_UART_TYPE_BOOST_CDS;
	expect_unique_chans(test, s, 9);
}

static void test_version_string(struct kunit *test)
{
	char buf[EV3_UART_VERSION_LEN + 1];

	/* As the BOOST colour and distance sensor sends it. */
	KUNIT_EXPECT_EQ(test, ev3_uart_version_string(0x10000000, buf, sizeof(buf)), 11);
	KUNIT_EXPECT_STREQ(test, buf, "1.0.00.0000");
	KUNIT_EXPECT_EQ(test, ev3_uart_version_string(0x42171234, buf, sizeof(buf)), 11);
	KUNIT_EXPECT_STREQ(test, buf, "4.2.17.1234");
	/* Not BCD, and the top bit (not part of major): still 11 characters. */
	KUNIT_EXPECT_EQ(test, ev3_uart_version_string(0xffffffff, buf, sizeof(buf)), 11);
	KUNIT_EXPECT_STREQ(test, buf, "7.f.ff.ffff");
	KUNIT_EXPECT_EQ(test, ev3_uart_version_string(0, buf, EV3_UART_VERSION_LEN), -EINVAL);
}

/* What ev3_uart_find_mode() makes of a mode attribute's write. */
struct find_mode_case {
	const char *str;
	int mode;
};

static const struct find_mode_case seven_modes[] = {
	{ "COL_O\n", 0 },
	{ "COL O\n", 0 },		/* as sent */
	{ "B C", 5 },
	{ "B_C", 4 },
	{ "A", -EINVAL },		/* two */
	{ "#6", 6 },
	{ "#7", -EINVAL },
	{ "COL", -EINVAL },
	{ "", -EINVAL },
	{ "\n", -EINVAL },
	{ "#", -EINVAL },
	{ "#:", -EINVAL },		/* '0' + 10: not a digit, not mode 10 */
};

static const struct find_mode_case sixteen_modes[] = {
	{ "#10\n", 10 },
	{ "#15", 15 },
	{ "#7", 7 },
	{ "#16", -EINVAL },
	{ "#:", -EINVAL },
	{ "#07", -EINVAL },
	{ "#100", -EINVAL },
	{ "#1a", -EINVAL },
	{ "M12", 12 },
};

static void expect_find_mode(struct kunit *test, const struct ev3_uart_sensor *s,
			     const struct find_mode_case *c, size_t n)
{
	for (; n; n--, c++)
		KUNIT_EXPECT_EQ_MSG(test, ev3_uart_find_mode(s, c->str), c->mode,
				    "mode \"%s\"", c->str);
}

static void test_mode_tokens(struct kunit *test)
{
	static const char * const names[] = { "COL O", "IR Tx", "A", "A", "B_C", "B C",
					      "COL-REFLECT" };
	static const char * const want[] = { "COL_O", "IR_Tx", "#2", "#3", "#4", "#5",
					     "COL-REFLECT" };
	struct ev3_uart_sensor *s = kunit_kzalloc(test, sizeof(*s), GFP_KERNEL);
	char tok[EV3_UART_TOKEN_LEN + 1];
	unsigned int i;

	KUNIT_ASSERT_NOT_NULL(test, s);
	s->num_modes = ARRAY_SIZE(names);
	for (i = 0; i < ARRAY_SIZE(names); i++)
		strscpy(s->modes[i].name, names[i], sizeof(s->modes[i].name));

	/*
	 * Spaces shown as '_'; two modes of one name, and two names shown
	 * alike, by number. Every token, written back, selects its own mode.
	 */
	for (i = 0; i < ARRAY_SIZE(want); i++) {
		KUNIT_EXPECT_EQ(test, ev3_uart_mode_token(s, i, tok, sizeof(tok)),
				(int)strlen(want[i]));
		KUNIT_EXPECT_STREQ(test, tok, want[i]);
		KUNIT_EXPECT_EQ(test, ev3_uart_find_mode(s, want[i]), (int)i);
	}
	KUNIT_EXPECT_EQ(test, ev3_uart_mode_token(s, 7, tok, sizeof(tok)), -EINVAL);
	KUNIT_EXPECT_EQ(test, ev3_uart_mode_token(s, 0, tok, 4), -EINVAL);

	expect_find_mode(test, s, seven_modes, ARRAY_SIZE(seven_modes));

	/* A Powered Up device's 16 modes: two digits, no leading zero. */
	s->num_modes = EV3_UART_MAX_MODES;
	for (i = ARRAY_SIZE(names); i < EV3_UART_MAX_MODES; i++)
		snprintf(s->modes[i].name, sizeof(s->modes[i].name), "M%u", i);
	expect_find_mode(test, s, sixteen_modes, ARRAY_SIZE(sixteen_modes));
}

static struct kunit_case ev3_uart_proto_cases[] = {
	KUNIT_CASE(test_checksum_real_messages),
	KUNIT_CASE(test_msg_len),
	KUNIT_CASE(test_msg_time),
	KUNIT_CASE(test_encoder_matches_captures),
	KUNIT_CASE(test_handshake_color),
	KUNIT_CASE(test_handshake_us),
	KUNIT_CASE(test_handshake_gyro_old),
	KUNIT_CASE(test_handshake_gyro_new),
	KUNIT_CASE(test_handshake_ir_with_00ff),
	KUNIT_CASE(test_report_msgs),
	KUNIT_CASE(test_handshake_byte_by_byte),
	KUNIT_CASE(test_sync_after_garbage),
	KUNIT_CASE(test_sync_rejects_bad_types),
	KUNIT_CASE(test_minimal_sensor),
	KUNIT_CASE(test_defaults_without_ranges),
	KUNIT_CASE(test_malformed_handshakes),
	KUNIT_CASE(test_format_limits),
	KUNIT_CASE(test_incomplete_and_duplicate_modes),
	KUNIT_CASE(test_views_clamped),
	KUNIT_CASE(test_powered_up_extras),
	KUNIT_CASE(test_handshake_boost_color_distance),
	KUNIT_CASE(test_boost_cds_channels),
	KUNIT_CASE(test_data_ext_mode),
	KUNIT_CASE(test_build_lump_data),
	KUNIT_CASE(test_lump_lights),
	KUNIT_CASE(test_pack_values),
	KUNIT_CASE(test_combo_technic_motor),
	KUNIT_CASE(test_combo_refused),
	KUNIT_CASE(test_build_speed),
	KUNIT_CASE(test_fast_sync_answered),
	KUNIT_CASE(test_fast_sync_unanswered),
	KUNIT_CASE(test_probe_meets_type),
	KUNIT_CASE(test_ext_mode_ignored_for_ev3),
	KUNIT_CASE(test_lump_16_modes_and_flags),
	KUNIT_CASE(test_ext_mode_gives_the_header_its_mode),
	KUNIT_CASE(test_data_decode_real_frames),
	KUNIT_CASE(test_rgb_raw_checksum_quirk),
	KUNIT_CASE(test_us_dc_in_mode5_tags),
	KUNIT_CASE(test_us_dc_old_mode_during_select),
	KUNIT_CASE(test_select_and_stale_frames),
	KUNIT_CASE(test_data_resync_after_garbage),
	KUNIT_CASE(test_too_many_bad_frames),
	KUNIT_CASE(test_keepalive_ticks),
	KUNIT_CASE(test_bytes_dropped_while_acked),
	KUNIT_CASE(test_line_errors),
	KUNIT_CASE(test_data_whole_messages),
	KUNIT_CASE(test_data_split_everywhere),
	KUNIT_CASE(test_data_back_to_back),
	KUNIT_CASE(test_data_bad_checksum_mid_batch),
	KUNIT_CASE(test_data_rgb_raw_in_batches),
	KUNIT_CASE(test_data_straddling_batch_end),
	KUNIT_CASE(test_data_err_after_line_error),
	KUNIT_CASE(test_handshake_every_batch_size),
	KUNIT_CASE(test_f32_to_fixed),
	KUNIT_CASE(test_scale_value),
	KUNIT_CASE(test_float_values),
	KUNIT_CASE(test_build_messages),
	KUNIT_CASE(test_mul_div),
	KUNIT_CASE(test_chan_scale),
	KUNIT_CASE(test_chan_scale_floats),
	KUNIT_CASE(test_chans_bounded),
	KUNIT_CASE(test_chans_twin_rgb_modes),
	KUNIT_CASE(test_backoff),
	KUNIT_CASE(test_mode_tokens),
	KUNIT_CASE(test_version_string),
	KUNIT_CASE(test_driver_names_fit),
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
