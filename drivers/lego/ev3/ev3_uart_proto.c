// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensor protocol core.
 *
 * Framing: every message but the one-byte system messages ends in a
 * checksum, the XOR of 0xff with every byte before it. The payload length is
 * a power of two given by the header; INFO messages carry one more byte (the
 * info type) between the header and the payload. Multi-byte values are
 * little endian and are read only with get_unaligned_le16/32() (and written
 * with put_unaligned_le32()), so neither the host's byte order nor its
 * alignment rules matter.
 *
 * A connection goes SYNC -> INFO -> ACKED -> DATA (see enum ev3_uart_state),
 * or, when the host offers a Powered Up device a fast sync, SYNC -> PROBE
 * -> SYNC at 115200 baud -> INFO -> ACKED -> DATA.
 * Nothing a sensor sends is trusted: every length, mode number, count and
 * range is checked before use, and any error in the handshake sends the
 * parser back to SYNC, where only a valid TYPE message gets it out again.
 *
 * Real sensors do not follow the protocol to the letter; each deviation we
 * tolerate is marked "Quirk:" below.
 */
#include <linux/errno.h>
#include <linux/export.h>
#include <linux/kernel.h>
#include <linux/limits.h>
#include <linux/math64.h>
#include <linux/module.h>
#include <linux/overflow.h>
#include <linux/string.h>
#include <linux/time64.h>

#include "lego_compat.h"
#include "ev3_uart_proto.h"

/* Defaults for the ranges a sensor does not send (LEGO's firmware uses these). */
#define EV3_UART_F32_0		0x00000000	/* 0.0 */
#define EV3_UART_F32_1		0x3f800000	/* 1.0 */
#define EV3_UART_F32_100	0x42c80000	/* 100.0 */
#define EV3_UART_F32_1023	0x447fc000	/* 1023.0 */

enum { EV3_UART_STASH_RAW, EV3_UART_STASH_PCT, EV3_UART_STASH_SI };

/**
 * ev3_uart_checksum() - compute the checksum of a message
 * @msg: the message, starting with its header
 * @len: number of bytes to cover: the whole message less its checksum byte
 *
 * Return: 0xff XOR every byte of @msg[0..@len-1].
 */
u8 ev3_uart_checksum(const u8 *msg, size_t len)
{
	u8 x = 0xff;

	while (len--)
		x ^= *msg++;
	return x;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_checksum);

/**
 * ev3_uart_payload_len() - payload length announced by a message header
 * @hdr: the message header byte
 *
 * Return: 0 for a system message, else 2^L bytes (1 to 128). Callers must
 * reject lengths above %EV3_UART_MAX_PAYLOAD themselves.
 */
unsigned int ev3_uart_payload_len(u8 hdr)
{
	if ((hdr & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_SYS)
		return 0;
	return 1U << ((hdr & EV3_UART_MSG_SIZE_MASK) >> EV3_UART_MSG_SIZE_SHIFT);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_payload_len);

/**
 * ev3_uart_msg_len() - total length on the wire of the message a header starts
 * @hdr: the message header byte
 *
 * Return: 1 for a system message; header + payload + checksum for commands
 * and data; one more (the info type byte) for INFO messages.
 */
unsigned int ev3_uart_msg_len(u8 hdr)
{
	switch (hdr & EV3_UART_MSG_TYPE_MASK) {
	case EV3_UART_MSG_SYS:
		return 1;
	case EV3_UART_MSG_INFO:
		return ev3_uart_payload_len(hdr) + 3;
	default:
		return ev3_uart_payload_len(hdr) + 2;
	}
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_msg_len);

/**
 * ev3_uart_data_size() - size in bytes of one value of a data type
 * @type: an &enum ev3_uart_data_type
 *
 * Return: 1, 2 or 4; 0 for an unknown type.
 */
unsigned int ev3_uart_data_size(enum ev3_uart_data_type type)
{
	static const u8 sizes[] = {
		[EV3_UART_DATA_S8] = 1,
		[EV3_UART_DATA_S16] = 2,
		[EV3_UART_DATA_S32] = 4,
		[EV3_UART_DATA_FLOAT] = 4,
	};

	/* A table: the data phase asks for every message. */
	return (unsigned int)type < ARRAY_SIZE(sizes) ? sizes[type] : 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_data_size);

/**
 * ev3_uart_msg_time() - when the last byte of a received message arrived
 * @now: the time the batch of received bytes holding it is handled, in ns
 * @rest: bytes of that batch after the message
 * @msg_len: the message's length on the wire, in bytes
 * @speed: the line speed in baud (a lower one counts as %EV3_UART_SPEED_MIN)
 * @last: what this returned for the previous message, 0 for none
 *
 * A tty hands received bytes over in batches, late and several messages at
 * once, so @now is only right for the batch's last byte: the @rest bytes
 * after the message came in at the line speed (8N1: 10 bit times a byte),
 * so it ended that much earlier. And two messages cannot end closer together
 * than the second one's time on the wire, which keeps the times strictly
 * increasing where the clock is coarse. Nor can they run ahead of the clock
 * by more than %EV3_UART_MSG_AHEAD_NS: a batch may hold more bytes than the
 * line could carry since the previous one (a pty has no speed: 500 bytes
 * "at 2400 baud" would date the batch's first message two seconds back and
 * push the next ones two seconds ahead), and then its messages are 1 ns
 * apart. A clock set back by more than a second (@now itself that far
 * before @last) is followed.
 *
 * Return: the estimated time, in ns.
 */
s64 ev3_uart_msg_time(s64 now, size_t rest, unsigned int msg_len, u32 speed,
		      s64 last)
{
	s64 byte_ns = div_u64(10ULL * NSEC_PER_SEC,
			      max_t(u32, speed, EV3_UART_SPEED_MIN));
	s64 t = now - (s64)rest * byte_ns;
	s64 wire_ns = msg_len * byte_ns;

	if (last && t < last + wire_ns && now > last - NSEC_PER_SEC) {
		t = last + wire_ns;
		if (t > now + EV3_UART_MSG_AHEAD_NS)
			t = max(now + EV3_UART_MSG_AHEAD_NS, last + 1);
	}
	return t;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_msg_time);

/**
 * ev3_uart_mul_div() - @a * @b / @c, exactly
 * @a: first factor
 * @b: second factor
 * @c: divisor
 * @round: round to the nearest integer; else truncate (C's division)
 * @q: the quotient
 *
 * The product is formed in 128 bits from 32-bit halves and divided bit by
 * bit, so this is exact for any inputs, on 32-bit hosts too, and cannot
 * trap (mul_u64_u64_div_u64() raises a divide error on x86 when the
 * quotient does not fit).
 *
 * Return: 0, or -%EOVERFLOW if @c is 0 or the quotient exceeds %S64_MAX.
 */
int ev3_uart_mul_div(u64 a, u64 b, u64 c, bool round, u64 *q)
{
	u64 a_lo = (u32)a, a_hi = a >> 32, b_lo = (u32)b, b_hi = b >> 32;
	u64 p0 = a_lo * b_lo, p1 = a_lo * b_hi, p2 = a_hi * b_lo;
	u64 mid = (p0 >> 32) + (u32)p1 + (u32)p2;
	u64 hi = a_hi * b_hi + (p1 >> 32) + (p2 >> 32) + (mid >> 32);
	u64 lo = (mid << 32) | (u32)p0;
	u64 res = 0, carry;
	int i;

	if (!c)
		return -EOVERFLOW;
	/* Round: add c / 2 to the 128-bit product. */
	if (round) {
		lo += c / 2;
		if (lo < c / 2)
			hi++;
	}
	/* The quotient has more than 64 bits. */
	if (hi >= c)
		return -EOVERFLOW;
	for (i = 0; i < 64; i++) {
		carry = hi >> 63;
		hi = hi << 1 | lo >> 63;
		lo <<= 1;
		res <<= 1;
		if (carry || hi >= c) {
			hi -= c;
			res |= 1;
		}
	}
	if (res > S64_MAX)
		return -EOVERFLOW;
	*q = res;
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_mul_div);

static const u32 ev3_pow10[EV3_UART_MAX_DECIMALS + 1] = {
	1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000,
	1000000000,
};

/* ev3_uart_f32_to_fixed(), inline for the handshake's ranges. */
static __always_inline int __ev3_uart_f32_to_fixed(u32 bits,
						   unsigned int decimals,
						   s32 *out)
{
	bool neg = bits >> 31;
	int exp = (bits >> 23) & 0xff;
	u64 v = bits & 0x7fffff;
	int shift;

	if (decimals > EV3_UART_MAX_DECIMALS)
		return -EINVAL;
	if (exp == 0xff)
		return -ERANGE;
	if (exp == 0) {
		/* Zero and subnormals (below 1.2e-38) round to zero. */
		*out = 0;
		return 0;
	}

	/* value = (2^23 + fraction) * 2^(exp - 150); the product is < 2^54. */
	v = (v | 0x800000) * ev3_pow10[decimals];
	shift = exp - 150;
	if (shift >= 0) {
		/* v >= 2^23, so anything shifted by 9 or more exceeds 2^32. */
		if (shift > 8)
			return -ERANGE;
		v <<= shift;
	} else if (shift < -62) {
		v = 0;
	} else {
		v = (v + (1ULL << (-shift - 1))) >> -shift;
	}

	if (v > (u64)S32_MAX + neg)
		return -ERANGE;
	*out = neg ? (s32)-(s64)v : (s32)v;
	return 0;
}

/**
 * ev3_uart_f32_to_fixed() - convert an IEEE 754 single to fixed point
 * @bits: the float's bit pattern, as it came off the wire
 * @decimals: decimal places to keep, 0 to %EV3_UART_MAX_DECIMALS
 * @out: the value times 10^@decimals, rounded half away from zero
 *
 * The kernel does no floating point, so this works on the bits alone.
 *
 * Return: 0, -%ERANGE for NaN, infinities and values that do not fit an s32,
 * -%EINVAL for too many decimals.
 */
int ev3_uart_f32_to_fixed(u32 bits, unsigned int decimals, s32 *out)
{
	return __ev3_uart_f32_to_fixed(bits, decimals, out);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_f32_to_fixed);

/**
 * ev3_uart_read_value() - decode one value of a DATA payload
 * @mode: the mode the payload belongs to
 * @data: the payload
 * @len: its length
 * @index: which value, from 0
 * @out: the value; floats are scaled by 10^decimals of the mode
 *
 * Return: 0, -%ENXIO if the mode has no value @index, -%EINVAL if the payload
 * is too short, -%ERANGE for a float that is not a number or does not fit.
 */
int ev3_uart_read_value(const struct ev3_uart_mode *mode, const u8 *data,
			size_t len, unsigned int index, s32 *out)
{
	unsigned int size = ev3_uart_data_size(mode->data_type);
	const u8 *p;

	if (index >= mode->num_values || !size)
		return -ENXIO;
	if ((index + 1) * size > len)
		return -EINVAL;

	p = data + index * size;
	switch (mode->data_type) {
	case EV3_UART_DATA_S8:
		*out = (s8)p[0];
		return 0;
	case EV3_UART_DATA_S16:
		*out = (s16)get_unaligned_le16(p);
		return 0;
	case EV3_UART_DATA_S32:
		*out = (s32)get_unaligned_le32(p);
		return 0;
	default:
		return ev3_uart_f32_to_fixed(get_unaligned_le32(p), mode->decimals, out);
	}
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_read_value);

/**
 * ev3_uart_scale_value() - the value ev3dev's lego-sensor class shows
 * @mode: the mode the value belongs to
 * @raw: a value from ev3_uart_read_value()
 *
 * When the RAW and SI ranges differ, the value is mapped linearly from the
 * RAW range onto the SI range (SI times 10^decimals), with C's truncating
 * integer division, exactly as ev3dev does, so that programs written for
 * ev3dev read the same numbers. For the LEGO sensors both ranges agree and
 * the raw value is shown unchanged.
 *
 * Return: the scaled value, saturated to the s32 range.
 */
s32 ev3_uart_scale_value(const struct ev3_uart_mode *mode, s32 raw)
{
	s64 raw_span = (s64)mode->raw_max - mode->raw_min;
	s64 si_span = (s64)mode->si_max - mode->si_min;
	s64 off = (s64)raw - mode->raw_min;
	bool neg = (off < 0) != ((si_span < 0) != (raw_span < 0));
	u64 q;
	s64 v;

	if ((mode->raw_min == mode->si_min && mode->raw_max == mode->si_max) ||
	    !raw_span)
		return raw;

	/*
	 * off * si_span / raw_span, truncated towards zero as C does, exactly:
	 * both spans are below 2^33, so the product needs up to 66 bits. A
	 * quotient beyond 2^63 is far beyond the s32 range.
	 */
	if (ev3_uart_mul_div(ev3_uart_abs64(off), ev3_uart_abs64(si_span),
			     ev3_uart_abs64(raw_span), false, &q))
		return neg ? S32_MIN : S32_MAX;
	v = neg ? -(s64)q : (s64)q;
	if (check_add_overflow(v, (s64)mode->si_min, &v))
		return neg ? S32_MIN : S32_MAX;

	return clamp_t(s64, v, S32_MIN, S32_MAX);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_scale_value);

/* A driver name by sensor type: ev3_uart_names[], ev3_uart_lump_names[]. */
struct ev3_uart_type_name {
	u8 type;
	const char *name;
};

static const char *ev3_uart_find_name(const struct ev3_uart_type_name *names,
				      size_t n, u8 type)
{
	size_t i;

	for (i = 0; i < n; i++)
		if (names[i].type == type)
			return names[i].name;
	return NULL;
}

static const struct ev3_uart_type_name ev3_uart_names[] = {
	{ EV3_UART_TYPE_COLOR,	"lego-ev3-color" },
	{ EV3_UART_TYPE_US,	"lego-ev3-us" },
	{ EV3_UART_TYPE_GYRO,	"lego-ev3-gyro" },
	{ EV3_UART_TYPE_IR,	"lego-ev3-ir" },
	{ 71,			"fcl-adc" },
	{ 72,			"fcl-gesture" },
	{ 73,			"fcl-light" },
	{ 74,			"fcl-altitude" },
	{ 75,			"fcl-ir" },
	{ 76,			"fcl-9dof" },
	{ 77,			"fcl-humidity" },
};

/**
 * ev3_uart_driver_name() - the well-known driver name of a sensor type
 * @type: the sensor type id
 *
 * Return: the name ev3dev uses (e.g. "lego-ev3-color"), or NULL if the type
 * has none; callers then use "ev3-uart-<type>".
 */
const char *ev3_uart_driver_name(u8 type)
{
	return ev3_uart_find_name(ev3_uart_names, ARRAY_SIZE(ev3_uart_names),
				  type);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_driver_name);

/*
 * Powered Up (LUMP) devices: their type ids overlap third-party EV3 ones
 * (FatcatLab's 75 and 76), so they have a table of their own. The motors
 * register as sensors (their speed, position and power modes): there is
 * no motor control here.
 */
static const struct ev3_uart_type_name ev3_uart_lump_names[] = {
	{ 34, "lego-wedo2-tilt" },
	{ 35, "lego-wedo2-motion" },
	{ 37, "lego-boost-color-dist" },
	{ 38, "lego-boost-motor" },
	{ 46, "lego-technic-l-motor" },
	{ 47, "lego-technic-xl-motor" },
	{ 48, "lego-spike-m-motor" },
	{ 49, "lego-spike-l-motor" },
	{ 61, "lego-spike-color" },
	{ 62, "lego-spike-ultrasonic" },
	{ 63, "lego-spike-force" },
	{ 64, "lego-technic-color-matrix" },
	{ 65, "lego-spike-s-motor" },
	{ 75, "lego-technic-m-angular-motor" },
	{ 76, "lego-technic-l-angular-motor" },
};

/**
 * ev3_uart_lump_driver_name() - the driver name of a Powered Up device type
 * @type: the device type id
 *
 * Return: e.g. "lego-spike-color", or NULL if the type has none; callers
 * then use "lump-uart-<type>".
 */
const char *ev3_uart_lump_driver_name(u8 type)
{
	return ev3_uart_find_name(ev3_uart_lump_names,
				  ARRAY_SIZE(ev3_uart_lump_names), type);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_lump_driver_name);

/* ---- message builders (host to sensor) ---- */

/**
 * ev3_uart_build_ack() - the host's ACK
 * @buf: at least one byte
 *
 * Return: the message length, 1.
 */
size_t ev3_uart_build_ack(u8 *buf)
{
	buf[0] = EV3_UART_SYS_ACK;
	return 1;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_ack);

/**
 * ev3_uart_build_nack() - the host's keep-alive
 * @buf: at least one byte
 *
 * Return: the message length, 1.
 */
size_t ev3_uart_build_nack(u8 *buf)
{
	buf[0] = EV3_UART_SYS_NACK;
	return 1;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_nack);

/**
 * ev3_uart_build_select() - a SELECT message
 * @buf: at least 3 bytes
 * @mode: the mode to select, 0 to 15 (Powered Up devices take modes 8 to
 *	15 in SELECT as they are)
 *
 * Return: the message length, 3.
 */
size_t ev3_uart_build_select(u8 *buf, u8 mode)
{
	buf[0] = EV3_UART_MSG_CMD | EV3_UART_CMD_SELECT;
	buf[1] = mode;
	buf[2] = ev3_uart_checksum(buf, 2);
	return 3;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_select);

/**
 * ev3_uart_build_speed() - the host's SPEED message (the fast sync probe)
 * @buf: at least %EV3_UART_SPEED_MSG_LEN bytes
 * @speed: the baud rate offered, little endian in the message
 *
 * Sent at @speed itself: a Powered Up device that can send its handshake
 * at that speed answers ACK (see ev3_uart_parser_probe()). For 115200:
 * ``52 00 c2 01 00 6e``.
 *
 * Return: the message length, %EV3_UART_SPEED_MSG_LEN.
 */
size_t ev3_uart_build_speed(u8 *buf, u32 speed)
{
	buf[0] = EV3_UART_MSG_CMD | 2 << EV3_UART_MSG_SIZE_SHIFT |
		 EV3_UART_CMD_SPEED;
	put_unaligned_le32(speed, buf + 1);
	buf[5] = ev3_uart_checksum(buf, 5);
	return EV3_UART_SPEED_MSG_LEN;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_speed);

/**
 * ev3_uart_build_write() - a WRITE message, padded to a power of two
 * @buf: at least %EV3_UART_MAX_PAYLOAD + 2 bytes
 * @data: the bytes to send
 * @len: their number, 1 to %EV3_UART_MAX_PAYLOAD
 *
 * Return: the message length, or -%EINVAL if @len is out of range.
 */
int ev3_uart_build_write(u8 *buf, const u8 *data, size_t len)
{
	unsigned int size = 1, code = 0;

	if (!len || len > EV3_UART_MAX_PAYLOAD)
		return -EINVAL;
	while (size < len) {
		size <<= 1;
		code++;
	}
	buf[0] = EV3_UART_MSG_CMD | code << EV3_UART_MSG_SIZE_SHIFT |
		 EV3_UART_CMD_WRITE;
	memcpy(buf + 1, data, len);
	memset(buf + 1 + len, 0, size - len);
	buf[size + 1] = ev3_uart_checksum(buf, size + 1);
	return size + 2;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_write);

/**
 * ev3_uart_build_lump_data() - values for a Powered Up device's mode
 * @buf: at least %EV3_UART_MAX_PAYLOAD + 5 bytes
 * @mode: the mode, 0 to 15 (one whose MAPPING has output flags)
 * @data: the values, as the mode's FORMAT lays them out
 * @len: their size in bytes, 1 to %EV3_UART_MAX_PAYLOAD
 *
 * Powered Up devices take values (a light's brightness, an infrared
 * command) as a DATA message from the host, after an EXT_MODE message that
 * gives the part of the mode above the header's 3 bits.
 *
 * Return: the length of the two messages, or -%EINVAL if @mode or @len is
 * out of range.
 */
int ev3_uart_build_lump_data(u8 *buf, u8 mode, const u8 *data, size_t len)
{
	unsigned int size = 1, code = 0;

	if (mode >= EV3_UART_MAX_MODES || !len || len > EV3_UART_MAX_PAYLOAD)
		return -EINVAL;
	while (size < len) {
		size <<= 1;
		code++;
	}
	buf[0] = EV3_UART_EXT_MODE_HDR;
	buf[1] = mode & EV3_UART_MAX_EV3_MODES;
	buf[2] = ev3_uart_checksum(buf, 2);
	buf[3] = EV3_UART_MSG_DATA | code << EV3_UART_MSG_SIZE_SHIFT |
		 (mode & EV3_UART_MSG_CMD_MASK);
	memcpy(buf + 4, data, len);
	memset(buf + 4 + len, 0, size - len);
	buf[size + 4] = ev3_uart_checksum(buf + 3, size + 1);
	return size + 5;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_lump_data);

/**
 * ev3_uart_lump_data_len() - the size of the values a mode takes
 * @s: a Powered Up device's description
 * @mode: the mode
 *
 * A mode takes values from the host when its MAPPING INFO has output
 * flags (Pybricks, lib/pbio/src/port_lump.c: "writable"), and the host
 * sends exactly the mode's values, laid out as its FORMAT says (Pybricks
 * refuses any other size).
 *
 * Return: their size in bytes (1 to %EV3_UART_MAX_PAYLOAD), or -%EINVAL if
 * @mode takes no values (an EV3 sensor's modes take none).
 */
int ev3_uart_lump_data_len(const struct ev3_uart_sensor *s, u8 mode)
{
	const struct ev3_uart_mode *m;
	unsigned int len;

	if (!s->lump || mode >= s->num_modes || mode >= EV3_UART_MAX_MODES)
		return -EINVAL;
	m = &s->modes[mode];
	len = m->num_values * ev3_uart_data_size(m->data_type);
	if (!m->mapping_out || !len || len > EV3_UART_MAX_PAYLOAD)
		return -EINVAL;
	return len;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_lump_data_len);

/**
 * ev3_uart_lump_lights() - the lights of a Powered Up device
 * @s: the device's description
 * @mode: set to the mode that drives them, if there are any
 *
 * The SPIKE colour sensor's three lights and the SPIKE ultrasonic
 * sensor's four are the values of their mode "LIGHT" (mode 3 and mode 5:
 * Pybricks, lib/lego/lego/device.h), one signed byte each, a brightness in
 * percent (Pybricks, pybricks/common/pb_type_lightarray.c). Any device's
 * first mode of that name that takes 1 to %EV3_UART_MAX_LIGHTS such
 * values is taken as its lights.
 *
 * Return: the number of lights, 0 if the device has none.
 */
unsigned int ev3_uart_lump_lights(const struct ev3_uart_sensor *s, u8 *mode)
{
	unsigned int i, n = min_t(unsigned int, s->num_modes, EV3_UART_MAX_MODES);

	for (i = 0; i < n; i++) {
		const struct ev3_uart_mode *m = &s->modes[i];

		if (strcmp(m->name, "LIGHT") || m->data_type != EV3_UART_DATA_S8 ||
		    m->num_values > EV3_UART_MAX_LIGHTS ||
		    ev3_uart_lump_data_len(s, i) < 0)
			continue;
		*mode = i;
		return m->num_values;
	}
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_lump_lights);

/**
 * ev3_uart_pack_values() - values for a mode, laid out as its FORMAT says
 * @s: a Powered Up device's description
 * @mode: a mode that takes values (ev3_uart_lump_data_len())
 * @v: the values
 * @n: their number, the mode's number of values
 * @buf: room for %EV3_UART_MAX_PAYLOAD bytes
 *
 * Return: their size in bytes, -%EINVAL if @mode takes no values, not @n
 * of them or floats, -%ERANGE if a value does not fit the mode's type.
 */
int ev3_uart_pack_values(const struct ev3_uart_sensor *s, u8 mode,
			 const s32 *v, unsigned int n, u8 *buf)
{
	int len = ev3_uart_lump_data_len(s, mode);
	const struct ev3_uart_mode *m;
	unsigned int i;

	if (len < 0)
		return len;
	m = &s->modes[mode];
	if (n != m->num_values || m->data_type == EV3_UART_DATA_FLOAT)
		return -EINVAL;
	for (i = 0; i < n; i++) {
		switch (m->data_type) {
		case EV3_UART_DATA_S8:
			if (v[i] < S8_MIN || v[i] > S8_MAX)
				return -ERANGE;
			buf[i] = (u8)v[i];
			break;
		case EV3_UART_DATA_S16:
			if (v[i] < S16_MIN || v[i] > S16_MAX)
				return -ERANGE;
			put_unaligned_le16((u16)v[i], buf + 2 * i);
			break;
		default:
			put_unaligned_le32((u32)v[i], buf + 4 * i);
			break;
		}
	}
	return len;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_pack_values);

/* The payload size a message of @len bytes of values takes: a power of two. */
static unsigned int ev3_uart_padded_len(unsigned int len)
{
	unsigned int size = 1;

	while (size < len)
		size <<= 1;
	return size;
}

/* The size of entry @e's value, or 0 if @s has no such value. */
static unsigned int ev3_uart_combo_size(const struct ev3_uart_sensor *s,
					const struct ev3_uart_combo_entry *e)
{
	const struct ev3_uart_mode *m;

	if (e->mode >= s->num_modes || e->mode >= EV3_UART_MAX_MODES)
		return 0;
	m = &s->modes[e->mode];
	if (e->index >= m->num_values || e->index > 0xf)
		return 0;
	return ev3_uart_data_size(m->data_type);
}

/**
 * ev3_uart_combo_find() - the combination of a device that has some values
 * @s: a Powered Up device's description
 * @e: the values, in the order the combined DATA message is to carry them
 * @n: their number, 1 to %EV3_UART_MAX_COMBO_ENTRIES
 * @len: set to the size of the values in a combined DATA message
 *
 * The modes of @e must all be in one of the bitmaps the device sent in
 * its MODE_COMBOS INFO; the first such is chosen. A combined DATA message
 * carries the values of @e one after the other, each as its mode's FORMAT
 * says, padded to a power of two (recorded from a Technic Large motor:
 * Pybricks' lib/pbio/test/src/uartdev.c before commit ae927acbd, "DATA
 * speed and position combo"). It comes with the header of mode 0, in which
 * the device was when the combination was set up (see ev3_uart_combo_*()
 * in ev3_uart_core.c), so it must be longer than mode 0's own DATA to be
 * told from it.
 *
 * Return: the index of the combination, or -%EINVAL if none has all the
 * values, they do not fit in a message, or they could not be told from
 * mode 0's values.
 */
int ev3_uart_combo_find(const struct ev3_uart_sensor *s,
			const struct ev3_uart_combo_entry *e, unsigned int n,
			unsigned int *len)
{
	unsigned int i, size, total = 0, first;
	u16 modes = 0;

	if (!s->lump || !n || n > EV3_UART_MAX_COMBO_ENTRIES || !s->num_modes)
		return -EINVAL;
	for (i = 0; i < n; i++) {
		size = ev3_uart_combo_size(s, &e[i]);
		if (!size)
			return -EINVAL;
		total += size;
		modes |= BIT(e[i].mode);
	}
	first = s->modes[0].num_values * ev3_uart_data_size(s->modes[0].data_type);
	if (total > EV3_UART_MAX_PAYLOAD ||
	    ev3_uart_padded_len(total) <= ev3_uart_padded_len(first))
		return -EINVAL;
	for (i = 0; i < s->num_combos && i < EV3_UART_MAX_COMBOS; i++) {
		if ((s->combos[i] & modes) == modes) {
			*len = total;
			return i;
		}
	}
	return -EINVAL;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_combo_find);

/**
 * ev3_uart_combo_offset() - where a value is in a combined DATA message
 * @s: the device's description
 * @e: the values of the combination, as given to ev3_uart_combo_find()
 * @n: their number
 * @j: which value, below @n
 *
 * Return: its offset in the payload, or -%EINVAL.
 */
int ev3_uart_combo_offset(const struct ev3_uart_sensor *s,
			  const struct ev3_uart_combo_entry *e, unsigned int n,
			  unsigned int j)
{
	unsigned int i, size, off = 0;

	if (j >= n || n > EV3_UART_MAX_COMBO_ENTRIES)
		return -EINVAL;
	for (i = 0; i < j; i++) {
		size = ev3_uart_combo_size(s, &e[i]);
		if (!size)
			return -EINVAL;
		off += size;
	}
	return off;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_combo_offset);

/**
 * ev3_uart_build_combo() - the WRITE that sets up a combined mode
 * @buf: at least %EV3_UART_COMBO_MSG_LEN bytes
 * @combo: the index of the combination (ev3_uart_combo_find())
 * @e: its values, in the order the DATA messages are to carry them
 * @n: their number, 1 to %EV3_UART_MAX_COMBO_ENTRIES
 *
 * The payload is %EV3_UART_COMBO_CMD plus @n, @combo, then a byte per value:
 * its mode in the high nibble, its index in the low one. For a Technic
 * Large motor's speed, position and absolute position (combination 0):
 * ``5c 23 00 10 20 30 00 00 00 80``.
 *
 * Return: the message length, or -%EINVAL for a bad argument.
 */
int ev3_uart_build_combo(u8 *buf, u8 combo,
			 const struct ev3_uart_combo_entry *e, unsigned int n)
{
	u8 payload[2 + EV3_UART_MAX_COMBO_ENTRIES];
	unsigned int i;

	if (!n || n > EV3_UART_MAX_COMBO_ENTRIES || combo >= EV3_UART_MAX_COMBOS)
		return -EINVAL;
	payload[0] = EV3_UART_COMBO_CMD | n;
	payload[1] = combo;
	for (i = 0; i < n; i++) {
		if (e[i].mode >= EV3_UART_MAX_MODES || e[i].index > 0xf)
			return -EINVAL;
		payload[2 + i] = e[i].mode << 4 | e[i].index;
	}
	return ev3_uart_build_write(buf, payload, n + 2);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_build_combo);

/* ---- the parser ---- */

static void ev3_uart_set_mode_defaults(struct ev3_uart_parser *p)
{
	p->stash[EV3_UART_STASH_RAW][0] = EV3_UART_F32_0;
	p->stash[EV3_UART_STASH_RAW][1] = EV3_UART_F32_1023;
	p->stash[EV3_UART_STASH_PCT][0] = EV3_UART_F32_0;
	p->stash[EV3_UART_STASH_PCT][1] = EV3_UART_F32_100;
	p->stash[EV3_UART_STASH_SI][0] = EV3_UART_F32_0;
	p->stash[EV3_UART_STASH_SI][1] = EV3_UART_F32_1;
}

static void ev3_uart_reset(struct ev3_uart_parser *p)
{
	p->state = EV3_UART_STATE_SYNC;
	p->sync_speed = EV3_UART_SPEED_MIN;
	p->msg_len = 0;
	p->replay_len = 0;
	p->replay_pos = 0;
}

/**
 * ev3_uart_parser_init() - start a parser hunting for a sensor
 * @p: the parser
 */
void ev3_uart_parser_init(struct ev3_uart_parser *p)
{
	memset(p, 0, sizeof(*p));
	p->info_mode = EV3_UART_NO_MODE;
	p->pending_mode = EV3_UART_NO_MODE;
	ev3_uart_reset(p);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_init);

static void ev3_uart_error(struct ev3_uart_parser *p, struct ev3_uart_event *ev,
			   const char *reason)
{
	ev3_uart_reset(p);
	ev->type = EV3_UART_EV_ERROR;
	ev->reason = reason;
}

/* A TYPE message in the sliding window starts a new handshake. */
static void ev3_uart_start_handshake(struct ev3_uart_parser *p, u8 type,
				     struct ev3_uart_event *ev)
{
	struct ev3_uart_sensor *s = &p->sensor;

	/*
	 * The modes are cleared one by one, by their NAME: the ACK needs
	 * every mode below num_modes described, and nothing reads the others.
	 */
	memset(s, 0, offsetof(struct ev3_uart_sensor, modes));
	s->type = type;
	s->num_modes = 1;
	s->num_view_modes = 1;
	/* No SPEED: stay where the handshake came (2400, or a fast sync's). */
	s->speed = p->sync_speed;
	p->cmd_seen = BIT(EV3_UART_CMD_TYPE);
	p->info_mode = EV3_UART_NO_MODE;
	p->info_seen = 0;
	p->modes_done = 0;
	p->ext_mode = 0;
	p->msg_len = 0;
	p->state = EV3_UART_STATE_INFO;
	ev->type = EV3_UART_EV_SYNC;
}

static void ev3_uart_sync_byte(struct ev3_uart_parser *p, u8 b,
			       struct ev3_uart_event *ev)
{
	/*
	 * The only way in is a TYPE message: 0x40, a type id, a checksum.
	 * Keep the last three bytes and test them after every byte, so a
	 * TYPE is found wherever it starts and however the bytes arrive.
	 */
	if (p->msg_len == 3) {
		p->msg[0] = p->msg[1];
		p->msg[1] = p->msg[2];
		p->msg_len = 2;
		p->garbage++;
	}
	p->msg[p->msg_len++] = b;
	if (p->msg_len < 3)
		return;
	if (p->msg[0] == (EV3_UART_MSG_CMD | EV3_UART_CMD_TYPE) &&
	    p->msg[1] >= EV3_UART_TYPE_MIN && p->msg[1] <= EV3_UART_TYPE_MAX &&
	    p->msg[2] == ev3_uart_checksum(p->msg, 2))
		ev3_uart_start_handshake(p, p->msg[1], ev);
}

/* Check a string of up to @size bytes; @len gets its length. */
static const char *ev3_uart_check_string(const u8 *s, size_t size,
					 size_t max, size_t *len)
{
	bool printable = true;
	size_t n;

	/* strnlen() and the check in one pass: 0x20 to 0x7e. */
	for (n = 0; n < size && s[n]; n++)
		printable &= (u8)(s[n] - 0x20) <= 0x7e - 0x20;
	*len = n;
	if (n > max)
		return "string too long";
	if (!printable)
		return "string not printable";
	return NULL;
}

/* MODES: how many modes, and how many of them to show. */
static const char *ev3_uart_cmd_modes(struct ev3_uart_parser *p,
				      const u8 *payload, unsigned int plen)
{
	struct ev3_uart_sensor *s = &p->sensor;

	if (p->info_mode != EV3_UART_NO_MODE)
		return "MODES after INFO";
	if (payload[0] >= EV3_UART_MAX_EV3_MODES)
		return "number of modes out of range";
	/*
	 * The second byte (views) is optional. Powered Up devices send a
	 * 4-byte form whose last two bytes count all their modes (up to 16)
	 * and views; the first two are for EV3 hosts.
	 */
	if (plen >= 4) {
		if (payload[2] >= EV3_UART_MAX_MODES)
			return "number of modes out of range";
		payload += 2;
		s->lump = true;
	}
	s->num_modes = payload[0] + 1;
	s->num_view_modes = plen >= 2 ? min_t(unsigned int, payload[1] + 1,
					      s->num_modes)
				      : s->num_modes;
	return NULL;
}

/* SPEED: the speed of the data phase. */
static const char *ev3_uart_cmd_speed(struct ev3_uart_parser *p,
				      const u8 *payload, unsigned int plen)
{
	u32 speed;

	if (p->info_mode != EV3_UART_NO_MODE)
		return "SPEED after INFO";
	if (plen < 4)
		return "short SPEED";
	speed = get_unaligned_le32(payload);
	if (speed < EV3_UART_SPEED_MIN || speed > EV3_UART_SPEED_MAX)
		return "speed out of range";
	p->sensor.speed = speed;
	return NULL;
}

/* VERSION (Powered Up): firmware and hardware versions, BCD. */
static const char *ev3_uart_cmd_version(struct ev3_uart_parser *p,
					const u8 *payload, unsigned int plen)
{
	struct ev3_uart_sensor *s = &p->sensor;

	if (plen < 8)
		return "short VERSION";
	s->fw_version = get_unaligned_le32(payload);
	s->hw_version = get_unaligned_le32(payload + 4);
	s->lump = true;
	return NULL;
}

/* A CMD message of the handshake, @plen bytes after its header. */
static void ev3_uart_cmd(struct ev3_uart_parser *p, const u8 *msg,
			 unsigned int plen, struct ev3_uart_event *ev)
{
	const u8 *payload = msg + 1;
	u8 cmd = msg[0] & EV3_UART_MSG_CMD_MASK;
	const char *err;

	switch (cmd) {
	case EV3_UART_CMD_MODES:
		err = p->cmd_seen & BIT(cmd) ? "duplicate MODES" :
		      ev3_uart_cmd_modes(p, payload, plen);
		break;
	case EV3_UART_CMD_SPEED:
		err = p->cmd_seen & BIT(cmd) ? "duplicate SPEED" :
		      ev3_uart_cmd_speed(p, payload, plen);
		break;
	case EV3_UART_CMD_VERSION:
		err = ev3_uart_cmd_version(p, payload, plen);
		break;
	case EV3_UART_CMD_EXT_MODE:
		/*
		 * Powered Up: meant for the data phase (see
		 * ev3_uart_ext_mode()); modes 8 and up are described with
		 * the MODE_PLUS_8 flag instead.
		 */
		err = NULL;
		break;
	case EV3_UART_CMD_TYPE:
		err = "duplicate TYPE";
		break;
	default:
		err = "unexpected command";
		break;
	}
	if (err)
		return ev3_uart_error(p, ev, err);
	p->cmd_seen |= BIT(cmd);
}

/* Convert the stashed ranges of a mode once its decimals are known. */
static const char *ev3_uart_convert_ranges(struct ev3_uart_parser *p,
					   struct ev3_uart_mode *m)
{
	u32 (*st)[2] = p->stash;

	if (__ev3_uart_f32_to_fixed(st[EV3_UART_STASH_RAW][0], 0, &m->raw_min) ||
	    __ev3_uart_f32_to_fixed(st[EV3_UART_STASH_RAW][1], 0, &m->raw_max) ||
	    __ev3_uart_f32_to_fixed(st[EV3_UART_STASH_PCT][0], 0, &m->pct_min) ||
	    __ev3_uart_f32_to_fixed(st[EV3_UART_STASH_PCT][1], 0, &m->pct_max))
		return "range not representable";
	/* Most modes send the RAW range again as SI: no need to convert it twice. */
	if (!m->decimals && st[EV3_UART_STASH_SI][0] == st[EV3_UART_STASH_RAW][0] &&
	    st[EV3_UART_STASH_SI][1] == st[EV3_UART_STASH_RAW][1]) {
		m->si_min = m->raw_min;
		m->si_max = m->raw_max;
		return NULL;
	}
	if (__ev3_uart_f32_to_fixed(st[EV3_UART_STASH_SI][0], m->decimals, &m->si_min) ||
	    __ev3_uart_f32_to_fixed(st[EV3_UART_STASH_SI][1], m->decimals, &m->si_max))
		return "range not representable";
	return NULL;
}

static void ev3_uart_format(struct ev3_uart_parser *p, u8 mode,
			    const u8 *payload, unsigned int plen,
			    struct ev3_uart_event *ev)
{
	struct ev3_uart_mode *m = &p->sensor.modes[mode];
	unsigned int size;
	const char *err;

	if (plen < 4)
		return ev3_uart_error(p, ev, "short FORMAT");
	size = ev3_uart_data_size(payload[1]);
	if (payload[1] > EV3_UART_DATA_FLOAT || !size)
		return ev3_uart_error(p, ev, "unknown data type");
	if (!payload[0] || payload[0] * size > EV3_UART_MAX_PAYLOAD)
		return ev3_uart_error(p, ev, "FORMAT value count out of range");
	if (payload[2] > EV3_UART_MAX_FIGURES ||
	    payload[3] > EV3_UART_MAX_DECIMALS)
		return ev3_uart_error(p, ev, "FORMAT figures or decimals out of range");

	m->num_values = payload[0];
	m->data_type = payload[1];
	m->figures = payload[2];
	m->decimals = payload[3];

	/*
	 * Quirk: the colour sensor's RGB-RAW announces three values but sends
	 * four; the fourth is the reading with the LED off. Show it, as
	 * ev3dev does.
	 */
	if (p->sensor.type == EV3_UART_TYPE_COLOR && mode == 4 &&
	    m->data_type == EV3_UART_DATA_S16 && m->num_values == 3)
		m->num_values = 4;

	err = ev3_uart_convert_ranges(p, m);
	if (err)
		return ev3_uart_error(p, ev, err);
	p->modes_done |= BIT(mode);
}

/* The Powered Up INFO types 0x05 to 0x0c of mode @m: none is fatal. */
static noinline void ev3_uart_info_lump(struct ev3_uart_sensor *s,
					struct ev3_uart_mode *m, u8 itype,
					const u8 *payload, unsigned int plen)
{
	unsigned int i;

	switch (itype) {
	case EV3_UART_INFO_MAPPING:
		if (plen >= 2) {
			m->mapping_in = payload[0];
			m->mapping_out = payload[1];
		}
		break;
	case EV3_UART_INFO_MODE_COMBOS:
		/* Bitmaps of modes, up to the first empty one. */
		for (i = 0; i < plen / 2 && i < EV3_UART_MAX_COMBOS; i++) {
			s->combos[i] = get_unaligned_le16(payload + 2 * i);
			if (!s->combos[i])
				break;
		}
		s->num_combos = i;
		break;
	default:
		/* Not understood (0x09 looks like motor PID parameters). */
		break;
	}
}

/* NAME: it starts the description of @mode (below num_modes). */
static const char *ev3_uart_info_name(struct ev3_uart_parser *p, u8 mode,
				      const u8 *payload, unsigned int plen)
{
	struct ev3_uart_sensor *s = &p->sensor;
	struct ev3_uart_mode *m = &s->modes[mode];
	const char *err;
	size_t n;

	if (p->info_mode != EV3_UART_NO_MODE &&
	    !(p->modes_done & BIT(p->info_mode)))
		return "NAME before the previous mode's FORMAT";
	if (p->modes_done & BIT(mode))
		return "duplicate mode";
	err = ev3_uart_check_string(payload, plen, EV3_UART_NAME_LEN, &n);
	if (err)
		return err;
	if (payload[0] < 'A' || payload[0] > 'z')
		return "bad mode name";
	memset(m, 0, sizeof(*m));
	/* 8-character names fill their payload with no NUL after them. */
	memcpy(m->name, payload, n);
	/* Powered Up: capability flags after a short name, in a 16-byte payload. */
	if (n <= EV3_UART_SHORT_NAME_LEN &&
	    plen >= EV3_UART_SHORT_NAME_LEN + 1 + EV3_UART_NAME_FLAGS) {
		memcpy(m->flags, payload + EV3_UART_SHORT_NAME_LEN + 1,
		       EV3_UART_NAME_FLAGS);
		s->lump = true;
	}
	ev3_uart_set_mode_defaults(p);
	p->info_mode = mode;
	p->info_seen = BIT(EV3_UART_INFO_NAME);
	return NULL;
}

/*
 * RAW, PCT, SI (a range, kept until FORMAT gives the decimals) and UNITS
 * of the mode being described, @m.
 */
static const char *ev3_uart_info_field(struct ev3_uart_parser *p,
				       struct ev3_uart_mode *m, u8 itype,
				       const u8 *payload, unsigned int plen)
{
	const char *err;
	size_t n;

	if (itype == EV3_UART_INFO_UNITS) {
		if (p->info_seen & BIT(itype))
			return "duplicate UNITS";
		err = ev3_uart_check_string(payload, plen, EV3_UART_UNITS_LEN, &n);
		if (err)
			return err;
		memcpy(m->units, payload, n);
	} else {
		if (p->info_seen & BIT(itype))
			return "duplicate range INFO";
		if (plen < 8)
			return "short range INFO";
		p->stash[itype - EV3_UART_INFO_RAW][0] = get_unaligned_le32(payload);
		p->stash[itype - EV3_UART_INFO_RAW][1] = get_unaligned_le32(payload + 4);
	}
	p->info_seen |= BIT(itype);
	return NULL;
}

/*
 * An INFO message of type @itype for mode @mode (below 16). EV3 types only,
 * and the MODE_PLUS_8 flag already taken off (see ev3_uart_info()).
 */
static __always_inline void __ev3_uart_info(struct ev3_uart_parser *p, u8 mode,
					    u8 itype, const u8 *payload,
					    unsigned int plen,
					    struct ev3_uart_event *ev)
{
	const char *err;

	if (mode >= p->sensor.num_modes)
		err = "INFO for a mode out of range";
	else if (itype == EV3_UART_INFO_NAME)
		err = ev3_uart_info_name(p, mode, payload, plen);
	else if (mode != p->info_mode)
		err = "INFO for a mode not being described";
	else if (p->modes_done & BIT(mode))
		err = "INFO after FORMAT";
	else if (itype == EV3_UART_INFO_FORMAT)
		return ev3_uart_format(p, mode, payload, plen, ev);
	else if (itype >= EV3_UART_INFO_RAW && itype <= EV3_UART_INFO_UNITS)
		/* mode < num_modes <= EV3_UART_MAX_MODES */
		err = ev3_uart_info_field(p, &p->sensor.modes[mode], itype,
					  payload, plen);
	else
		err = "unknown INFO type";
	if (err)
		ev3_uart_error(p, ev, err);
}

/*
 * The INFO types beyond EV3's: the MODE_PLUS_8 flag (Powered Up: modes 8 to
 * 15), the Powered Up types 0x05 to 0x0c, and unknown ones.
 */
static noinline void ev3_uart_info_ext(struct ev3_uart_parser *p, const u8 *msg,
				       unsigned int plen, struct ev3_uart_event *ev)
{
	struct ev3_uart_sensor *s = &p->sensor;
	u8 mode = msg[0] & EV3_UART_MSG_CMD_MASK;
	u8 itype = msg[1];

	if (itype & EV3_UART_INFO_MODE_PLUS_8) {
		itype &= ~EV3_UART_INFO_MODE_PLUS_8;
		mode += EV3_UART_MAX_EV3_MODES;
		s->lump = true;
	}
	/*
	 * Powered Up INFO types: kept where they are understood, skipped
	 * otherwise (for a mode the device does not have too), never fatal;
	 * they may come after FORMAT (MODE_COMBOS).
	 */
	if (itype >= EV3_UART_INFO_PUP_FIRST && itype <= EV3_UART_INFO_PUP_LAST) {
		s->lump = true;
		if (mode < s->num_modes)
			ev3_uart_info_lump(s, &s->modes[mode], itype, msg + 2, plen);
		return;
	}
	__ev3_uart_info(p, mode, itype, msg + 2, plen, ev);
}

static void ev3_uart_info(struct ev3_uart_parser *p, const u8 *msg,
			  unsigned int plen, struct ev3_uart_event *ev)
{
	u8 itype = msg[1];

	/* EV3 sensors send NAME, RAW, PCT, SI, UNITS and FORMAT only. */
	if (itype > EV3_UART_INFO_UNITS && itype != EV3_UART_INFO_FORMAT)
		return ev3_uart_info_ext(p, msg, plen, ev);
	__ev3_uart_info(p, msg[0] & EV3_UART_MSG_CMD_MASK, itype, msg + 2, plen, ev);
}

static void ev3_uart_sys_info(struct ev3_uart_parser *p, u8 b,
			      struct ev3_uart_event *ev)
{
	u16 all = GENMASK(p->sensor.num_modes - 1, 0);

	if (b != EV3_UART_SYS_ACK)
		return;	/* SYNC, NACK and the reserved ESC bytes carry nothing */
	if ((p->modes_done & all) != all)
		return ev3_uart_error(p, ev, "ACK before every mode was described");
	p->state = EV3_UART_STATE_ACKED;
	ev->type = EV3_UART_EV_HANDSHAKE;
}

/*
 * A whole handshake message of @len bytes (as its header says), in @p->msg
 * or in the caller's buffer.
 */
static void ev3_uart_info_msg(struct ev3_uart_parser *p, const u8 *msg,
			      unsigned int len, struct ev3_uart_event *ev)
{
	if (msg[len - 1] != ev3_uart_checksum(msg, len - 1))
		return ev3_uart_error(p, ev, "bad checksum in handshake");

	switch (msg[0] & EV3_UART_MSG_TYPE_MASK) {
	case EV3_UART_MSG_CMD:
		ev3_uart_cmd(p, msg, len - 2, ev);
		break;
	case EV3_UART_MSG_INFO:
		ev3_uart_info(p, msg, len - 3, ev);
		break;
	default:
		return ev3_uart_error(p, ev, "DATA before ACK");
	}
	/* Reported for tracing only: the handshake, never the data phase. */
	if (p->report_msgs && ev->type == EV3_UART_EV_NONE) {
		ev->type = EV3_UART_EV_MSG;
		ev->mode = msg[0];
		ev->len = len;
		p->msg_info = (msg[0] & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_INFO ?
			      msg[1] : 0;
	}
}

/* The size code (L) of %EV3_UART_MAX_PAYLOAD. */
#define EV3_UART_MAX_SIZE_CODE	5

static bool ev3_uart_data_hdr_ok(u8 b)
{
	BUILD_BUG_ON(1 << EV3_UART_MAX_SIZE_CODE != EV3_UART_MAX_PAYLOAD);
	return (b & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_DATA &&
	       (b & EV3_UART_MSG_SIZE_MASK) >> EV3_UART_MSG_SIZE_SHIFT <=
	       EV3_UART_MAX_SIZE_CODE;
}

/*
 * Drop the first byte of a bad DATA message and parse the rest again: the
 * real next message may start inside it.
 */
static void ev3_uart_data_resync(struct ev3_uart_parser *p)
{
	unsigned int rest = p->replay_len - p->replay_pos;

	/* Unparsed replay bytes follow the message they were part of. */
	memmove(p->replay + p->msg_len - 1, p->replay + p->replay_pos, rest);
	memcpy(p->replay, p->msg + 1, p->msg_len - 1);
	p->replay_len = p->msg_len - 1 + rest;
	p->replay_pos = 0;
	p->msg_len = 0;
}

/*
 * Quirk: the sensor switches speed as soon as it has the host's ACK, and
 * the host only once the ACK is on the wire, so the first bytes of the
 * data phase can arrive garbled (a 34-byte message at 57600 baud read at
 * 2400 is a dozen framing errors), and the tty may hand them over only
 * after the switch. Until the first good DATA message, bad bytes and
 * frames are garbage, not errors: a sensor that never gets there is lost
 * by the keep-alive ticks (ev3_uart_parser_tick()) all the same.
 */
static bool ev3_uart_settling(const struct ev3_uart_parser *p)
{
	return !p->frames;
}

static void ev3_uart_bad_frame(struct ev3_uart_parser *p,
			       struct ev3_uart_event *ev)
{
	p->bad_frames++;
	if (!ev3_uart_settling(p) && ++p->data_err > EV3_UART_MAX_DATA_ERR)
		return ev3_uart_error(p, ev, "too many bad DATA messages");
	ev3_uart_data_resync(p);
}

/*
 * Quirk: the colour sensor's RGB-RAW messages (header 0xdc: DATA, 8 bytes,
 * mode 4) mostly carry a wrong checksum; LEGO's firmware does not check
 * them either.
 */
static bool ev3_uart_rgb_raw_quirk(const struct ev3_uart_sensor *s, u8 hdr)
{
	return s->type == EV3_UART_TYPE_COLOR && hdr == 0xdc;
}

/*
 * Powered Up: an EXT_MODE message (3 bytes) in the data phase. The DATA
 * messages after it are of the mode in their header plus its value, 0 or 8.
 */
static void ev3_uart_ext_mode(struct ev3_uart_parser *p,
			      struct ev3_uart_event *ev)
{
	u8 ext = p->msg[1];

	if (p->msg[2] != ev3_uart_checksum(p->msg, 2) ||
	    (ext && ext != EV3_UART_MAX_EV3_MODES))
		return ev3_uart_bad_frame(p, ev);
	p->ext_mode = ext;
}

/*
 * Quirk: in US-DC-IN (mode 6) the ultrasonic sensor tags the DATA messages
 * it sends on its own with mode 5 (US-DC-CM) and only its NACK replies with
 * mode 6; both carry the mode 6 value. So a message tagged mode 5 is mode
 * 6's in mode 6 and mode 5's in mode 5. While a SELECT switches between the
 * two, the sensor goes on in the old mode until it has switched, and such a
 * message may be of either mode: nobody can tell. From 5 to 6, a mode 6
 * message (a NACK reply: within a keep-alive period) confirms the switch.
 * From 6 to 5 no message says that the sensor has switched, but one says
 * it has not: a mode 6 message, its reply to a NACK. So once
 * %EV3_UART_US_SELECT_TICKS keep-alive ticks have passed since the SELECT
 * or the last mode 6 message, the NACK of the first was answered in mode
 * 5, and the messages tagged 5 are mode 5's (the real sensor switches
 * within a few ms: 100 to 200 ms after the SELECT). Until then they are
 * nobody's.
 *
 * Return: the mode of a DATA message tagged mode 5 from the ultrasonic
 * sensor, or %EV3_UART_NO_MODE while it cannot be told.
 */
#define EV3_UART_US_SELECT_TICKS	2

static u8 ev3_uart_us_mode5(const struct ev3_uart_parser *p)
{
	u8 from = p->mode, to = p->pending_mode;

	if (to == 6)
		return from == 5 ? EV3_UART_NO_MODE : 6;
	if (from == 6 && to == 5)
		return p->select_ticks >= EV3_UART_US_SELECT_TICKS ? 5 :
		       EV3_UART_NO_MODE;
	return from == 6 ? 6 : 5;
}

/*
 * Quirk: US-DC-IN's messages tagged mode 5 (see above). The mode of an
 * EV3 ultrasonic sensor's DATA message tagged @mode, in @mode, and whether
 * it is US-DC-IN's in @us_dc_in; EV3_UART_NO_MODE when no one can tell.
 */
static u8 ev3_uart_us_mode(struct ev3_uart_parser *p, u8 mode, bool *us_dc_in)
{
	if (p->sensor.type != EV3_UART_TYPE_US || p->sensor.lump)
		return mode;
	if (mode == 5) {
		mode = ev3_uart_us_mode5(p);
		*us_dc_in = mode == 6;
	} else if (mode == 6 && p->pending_mode == 5) {
		/* Not switched yet: count again. */
		p->select_ticks = 0;
	}
	return mode;
}

static void ev3_uart_data_msg(struct ev3_uart_parser *p,
			      struct ev3_uart_event *ev)
{
	struct ev3_uart_sensor *s = &p->sensor;
	unsigned int len = p->msg_len, plen = len - 2;
	u8 hdr = p->msg[0];
	u8 mode = (hdr & EV3_UART_MSG_CMD_MASK) + p->ext_mode;
	bool changed = false, us_dc_in = false;
	struct ev3_uart_mode *m;

	/* The one non-DATA message ev3_uart_msg_start() lets through. */
	if (hdr == EV3_UART_EXT_MODE_HDR)
		return ev3_uart_ext_mode(p, ev);
	if (p->msg[len - 1] != ev3_uart_checksum(p->msg, len - 1) &&
	    !ev3_uart_rgb_raw_quirk(s, hdr))
		return ev3_uart_bad_frame(p, ev);
	mode = ev3_uart_us_mode(p, mode, &us_dc_in);
	if (mode == EV3_UART_NO_MODE) {
		/* The sensor is there, but whose value is it? */
		p->data_since_tick = true;
		p->msg_len = 0;
		return;
	}
	if (mode >= s->num_modes)
		return ev3_uart_bad_frame(p, ev);
	if (mode == p->pending_mode) {
		changed = mode != p->mode;
		p->mode = mode;
		p->pending_mode = EV3_UART_NO_MODE;
	} else if (mode != p->mode) {
		/*
		 * A message of the old mode can still arrive just after a
		 * SELECT. Not an error, but not news either.
		 */
		p->msg_len = 0;
		return;
	}

	m = &s->modes[mode];
	if (plen < m->num_values * ev3_uart_data_size(m->data_type))
		return ev3_uart_bad_frame(p, ev);

	memcpy(p->data, p->msg + 1, plen);
	p->msg_len = 0;
	p->frames++;
	if (p->data_err)
		p->data_err--;
	p->data_since_tick = true;
	ev->type = EV3_UART_EV_DATA;
	ev->mode = mode;
	ev->mode_changed = changed;
	ev->us_dc_in = us_dc_in;
	ev->len = plen;
}

/* A whole message is in @p->msg: act on it. */
static void ev3_uart_msg_done(struct ev3_uart_parser *p,
			      struct ev3_uart_event *ev)
{
	if (p->state != EV3_UART_STATE_DATA)
		ev3_uart_info_msg(p, p->msg, p->msg_len, ev);
	else
		ev3_uart_data_msg(p, ev);
	p->msg_len = 0;
}

/* The first byte of a message in the INFO and DATA states: its header. */
static void ev3_uart_msg_start(struct ev3_uart_parser *p, u8 b,
			       struct ev3_uart_event *ev)
{
	/*
	 * Quirk: a lone 0xff shows up at message boundaries: the infrared
	 * sensor sends "00 ff" in its handshake, and a line glitch reads as
	 * 0xff when the speed changes. 0xff would start a 128-byte DATA
	 * message: skip it.
	 */
	if (b == 0xff) {
		p->garbage++;
		return;
	}
	if (p->state == EV3_UART_STATE_DATA) {
		/*
		 * Re-align on the next plausible DATA header, or a Powered Up
		 * device's EXT_MODE.
		 */
		if (!ev3_uart_data_hdr_ok(b) &&
		    !(b == EV3_UART_EXT_MODE_HDR && p->sensor.lump)) {
			p->garbage++;
			return;
		}
	} else if ((b & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_SYS) {
		return ev3_uart_sys_info(p, b, ev);
	} else if (ev3_uart_payload_len(b) > EV3_UART_MAX_PAYLOAD) {
		return ev3_uart_error(p, ev, "message too long");
	}
	p->msg[0] = b;
	p->msg_len = 1;
	p->msg_size = ev3_uart_msg_len(b);
}

/*
 * The rest of a message whose header is in @p->msg: nothing looks at these
 * bytes before the message is whole, so they are taken as many at a time
 * as @buf holds. The header bounds the length to %EV3_UART_MAX_MSG_LEN.
 *
 * Return: the number of bytes of @buf taken.
 */
static size_t ev3_uart_msg_body(struct ev3_uart_parser *p, const u8 *buf,
				size_t len, struct ev3_uart_event *ev)
{
	unsigned int need = p->msg_size - p->msg_len;

	if (len < need) {
		memcpy(p->msg + p->msg_len, buf, len);
		p->msg_len += len;
		return len;
	}
	memcpy(p->msg + p->msg_len, buf, need);
	p->msg_len += need;
	ev3_uart_msg_done(p, ev);
	return need;
}

/*
 * A byte while the host waits for the answer to its probe: a Powered Up
 * device's ACK (unless the byte is the type id of a TYPE message the window
 * holds the header of: type 4 is valid), else a byte for the TYPE hunt at
 * 2400 baud, which goes on meanwhile. On a UART a sensor talking at 2400
 * only sends garbage at the probe's speed; but on a line that carries
 * bytes whatever the speed (a pty, a socket) an EV3 sensor that started its
 * handshake during the probe would otherwise lose it, and register only
 * after its next one, 1.3 to 1.6 s later. Its TYPE ends the probe
 * unanswered: the handshake is at 2400 baud.
 */
static void ev3_uart_probe_byte(struct ev3_uart_parser *p, u8 b,
				struct ev3_uart_event *ev)
{
	if (b == EV3_UART_SYS_ACK &&
	    !(p->msg_len && p->msg[p->msg_len - 1] ==
	      (EV3_UART_MSG_CMD | EV3_UART_CMD_TYPE))) {
		/* A fast sync: the handshake follows at this speed. */
		p->state = EV3_UART_STATE_SYNC;
		p->msg_len = 0;
		ev->type = EV3_UART_EV_FAST;
		return;
	}
	ev3_uart_sync_byte(p, b, ev);
	if (ev->type == EV3_UART_EV_SYNC) {
		p->sync_speed = EV3_UART_SPEED_MIN;
		p->sensor.speed = EV3_UART_SPEED_MIN;
	}
}

/* One byte, from @p->replay or from the caller's buffer. */
static void ev3_uart_byte(struct ev3_uart_parser *p, u8 b,
			  struct ev3_uart_event *ev)
{
	switch (p->state) {
	case EV3_UART_STATE_SYNC:
		ev3_uart_sync_byte(p, b, ev);
		break;
	case EV3_UART_STATE_ACKED:
		p->garbage++;
		break;
	case EV3_UART_STATE_PROBE:
		ev3_uart_probe_byte(p, b, ev);
		break;
	default:
		if (!p->msg_len)
			ev3_uart_msg_start(p, b, ev);
		else
			ev3_uart_msg_body(p, &b, 1, ev);
		break;
	}
}

/*
 * The general case of ev3_uart_parser_feed(): byte by byte, except that the
 * rest of a message whose header was accepted is taken in one go.
 */
static size_t ev3_uart_feed_bytes(struct ev3_uart_parser *p, const u8 *buf,
				  size_t len, struct ev3_uart_event *ev)
{
	size_t used = 0;

	do {
		if (p->replay_pos < p->replay_len)
			ev3_uart_byte(p, p->replay[p->replay_pos++], ev);
		else if (used == len)
			break;
		else if (p->state != EV3_UART_STATE_INFO &&
			 p->state != EV3_UART_STATE_DATA)
			ev3_uart_byte(p, buf[used++], ev);
		else if (p->msg_len)
			used += ev3_uart_msg_body(p, buf + used, len - used, ev);
		else
			ev3_uart_msg_start(p, buf[used++], ev);
	} while (ev->type == EV3_UART_EV_NONE);
	return used;
}

/**
 * ev3_uart_parser_feed() - parse received bytes up to the next event
 * @p: the parser
 * @buf: received bytes
 * @len: their number
 * @ev: filled with the event that stopped parsing, or %EV3_UART_EV_NONE
 *
 * Call again with the rest of @buf until everything is consumed; act on
 * each event in between. Never sleeps.
 *
 * Return: the number of bytes of @buf consumed.
 */
size_t ev3_uart_parser_feed(struct ev3_uart_parser *p, const u8 *buf,
			    size_t len, struct ev3_uart_event *ev)
{
	memset(ev, 0, sizeof(*ev));
	return ev3_uart_feed_bytes(p, buf, len, ev);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_feed);

/**
 * ev3_uart_parser_line_error() - the UART reported a break, framing,
 * parity or overrun error
 * @p: the parser
 * @ev: set to %EV3_UART_EV_ERROR if the error ends the connection
 *
 * In the handshake every byte matters, so the handshake starts over. In the
 * data phase the message being received is dropped and counted as bad.
 */
void ev3_uart_parser_line_error(struct ev3_uart_parser *p,
				struct ev3_uart_event *ev)
{
	memset(ev, 0, sizeof(*ev));
	switch (p->state) {
	case EV3_UART_STATE_SYNC:
		p->msg_len = 0;
		break;
	case EV3_UART_STATE_INFO:
		ev3_uart_error(p, ev, "line error in handshake");
		break;
	case EV3_UART_STATE_PROBE:
		/* A device that cannot answer at the probe's speed, garbled. */
		p->msg_len = 0;
		break;
	case EV3_UART_STATE_ACKED:
		break;
	case EV3_UART_STATE_DATA:
		p->msg_len = 0;
		p->bad_frames++;
		if (!ev3_uart_settling(p) && ++p->data_err > EV3_UART_MAX_DATA_ERR)
			ev3_uart_error(p, ev, "too many line errors");
		break;
	}
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_line_error);

/**
 * ev3_uart_parser_start_data() - the host answered ACK and switched speed
 * @p: the parser, in %EV3_UART_STATE_ACKED
 *
 * Every sensor starts the data phase in mode 0.
 */
void ev3_uart_parser_start_data(struct ev3_uart_parser *p)
{
	if (p->state != EV3_UART_STATE_ACKED)
		return;
	p->state = EV3_UART_STATE_DATA;
	p->msg_len = 0;
	p->mode = 0;
	p->ext_mode = 0;
	p->pending_mode = EV3_UART_NO_MODE;
	p->select_ticks = 0;
	p->data_err = 0;
	p->silent_ticks = 0;
	p->data_since_tick = false;
	p->frames = 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_start_data);

/**
 * ev3_uart_parser_select() - note that a SELECT is being sent
 * @p: the parser
 * @mode: the mode asked for
 *
 * The first DATA message of @mode confirms it (%EV3_UART_EV_DATA with
 * mode_changed set, or without it if @mode was already current).
 *
 * Return: 0, -%ENODEV outside the data phase, -%EINVAL for a mode the sensor
 * does not have.
 */
int ev3_uart_parser_select(struct ev3_uart_parser *p, u8 mode)
{
	if (p->state != EV3_UART_STATE_DATA)
		return -ENODEV;
	if (mode >= p->sensor.num_modes)
		return -EINVAL;
	/* A SELECT sent again goes on counting from the first. */
	if (mode != p->pending_mode)
		p->select_ticks = 0;
	p->pending_mode = mode;
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_select);

/**
 * ev3_uart_parser_probe() - note that the host offers a fast sync
 * @p: the parser, hunting for a TYPE message at 2400 baud
 * @speed: the speed the host switched the line to and sends SPEED at
 *	(%EV3_UART_SPEED_FAST)
 *
 * Powered Up devices that can send their handshake at 115200 baud answer
 * a SPEED 115200 message sent at 115200 (ev3_uart_build_speed()) with ACK
 * (they listen for it for about 500 ms after they reset, before their
 * 2400-baud handshake), then send the handshake at that speed, and no
 * speed change follows the host's ACK. EV3 sensors and devices that do not
 * answer stay at 2400: the host calls ev3_uart_parser_probe_end() when it
 * has waited long enough (Pybricks waits 10 ms) and goes back to 2400. Meanwhile the
 * parser takes the ACK (%EV3_UART_EV_FAST), and hunts for a TYPE message as
 * at 2400 baud: on a line with no speeds (a pty) an EV3 sensor's TYPE starts
 * its handshake at 2400 (%EV3_UART_EV_SYNC) and ends the probe; line
 * errors are dropped.
 *
 * Return: 0, -%EBUSY outside the SYNC state at 2400 baud (a handshake is
 * under way), -%EINVAL for a speed out of range.
 */
int ev3_uart_parser_probe(struct ev3_uart_parser *p, u32 speed)
{
	if (speed < EV3_UART_SPEED_MIN || speed > EV3_UART_SPEED_MAX)
		return -EINVAL;
	if (p->state != EV3_UART_STATE_SYNC ||
	    p->sync_speed != EV3_UART_SPEED_MIN)
		return -EBUSY;
	/* The TYPE hunt goes on: a TYPE may have begun at 2400. */
	p->state = EV3_UART_STATE_PROBE;
	p->sync_speed = speed;
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_probe);

/**
 * ev3_uart_parser_probe_end() - the host stops waiting for the probe's ACK
 * @p: the parser
 *
 * Without an answer the parser hunts for a TYPE message at 2400 baud
 * again (as it did meanwhile: what it holds of one is kept); after one
 * (%EV3_UART_EV_FAST), at the probe's speed, whatever state the handshake
 * that followed has reached; after a TYPE at 2400, at 2400.
 *
 * Return: the speed the line must run at from now on, &p->sync_speed.
 */
u32 ev3_uart_parser_probe_end(struct ev3_uart_parser *p)
{
	if (p->state == EV3_UART_STATE_PROBE) {
		p->state = EV3_UART_STATE_SYNC;
		p->sync_speed = EV3_UART_SPEED_MIN;
	}
	return p->sync_speed;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_probe_end);

/**
 * ev3_uart_parser_tick() - account for one keep-alive period (100 ms)
 * @p: the parser
 * @ev: set to %EV3_UART_EV_ERROR if the sensor is considered lost
 *
 * Sensors answer every NACK with a DATA message, so a period without any
 * good DATA means trouble; more than %EV3_UART_MAX_DATA_ERR in a row (about
 * 700 ms) means the sensor is gone.
 *
 * Return: true if the sensor is lost (the parser is back in SYNC state).
 */
bool ev3_uart_parser_tick(struct ev3_uart_parser *p, struct ev3_uart_event *ev)
{
	memset(ev, 0, sizeof(*ev));
	if (p->state != EV3_UART_STATE_DATA)
		return false;
	if (p->pending_mode != EV3_UART_NO_MODE && p->select_ticks < U8_MAX)
		p->select_ticks++;
	if (p->data_since_tick)
		p->silent_ticks = 0;
	else if (++p->silent_ticks > EV3_UART_MAX_DATA_ERR)
		ev3_uart_error(p, ev, "no data from the sensor");
	p->data_since_tick = false;
	return ev->type == EV3_UART_EV_ERROR;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_parser_tick);

/**
 * ev3_uart_backoff_lost() - a sensor was lost: how long to hold off the
 *	next connection on its line
 * @b: the line's record (zeroed when the line is attached)
 * @lived_ms: milliseconds from its registration to its loss
 *
 * A device that answers the fast sync probe, sends its handshake and a
 * few bad DATA messages, again and again, would have a class device and an
 * IIO device registered and unregistered every 100 ms or so, with their
 * uevents. A sensor that lived %EV3_UART_SHORT_LIFE_MS or more ends such a
 * run; the first %EV3_UART_FREE_RETRIES failures in a row cost nothing (a
 * sensor plugged in badly), then the wait doubles from
 * %EV3_UART_BACKOFF_MIN_MS to %EV3_UART_BACKOFF_MAX_MS.
 *
 * Return: the milliseconds during which the next handshakes must be left
 * unanswered, 0 for none.
 */
unsigned int ev3_uart_backoff_lost(struct ev3_uart_backoff *b,
				   unsigned int lived_ms)
{
	unsigned int shift;

	if (lived_ms >= EV3_UART_SHORT_LIFE_MS) {
		b->failures = 0;
		return 0;
	}
	/* No further than the longest wait needs. */
	if (b->failures <= EV3_UART_FREE_RETRIES + EV3_UART_BACKOFF_MAX_SHIFT)
		b->failures++;
	if (b->failures <= EV3_UART_FREE_RETRIES)
		return 0;
	shift = min_t(unsigned int, b->failures - EV3_UART_FREE_RETRIES - 1,
		      EV3_UART_BACKOFF_MAX_SHIFT);
	return EV3_UART_BACKOFF_MIN_MS << shift;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_backoff_lost);
