// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: IIO channels and mode names from a
 * sensor's description.
 *
 * A sensor chooses its own units, ranges, value counts and mode names, and
 * a sensor that follows every rule of the protocol can still announce 256
 * values, a range a million times wider than its raw values, or two modes
 * of the same name. This file turns such descriptions into something IIO
 * and sysfs can show, or leaves a channel out, and never does arithmetic
 * that can trap or wrap on the way.
 */
#include <linux/errno.h>
#include <linux/export.h>
#include <linux/kernel.h>
#include <linux/limits.h>
#include <linux/math64.h>
#include <linux/overflow.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "ev3_uart_chan.h"

#define NANO		1000000000ULL
#define MICRO		1000000ULL
/*
 * A scale below this many nano-units would be shown with fewer than four
 * significant digits (IIO prints nine decimals): the channel is left out
 * rather than shown with a scale that is mostly rounding.
 */
#define EV3_UART_SCALE_MIN_NANO	1000
/* The largest scale IIO_VAL_INT_PLUS_NANO can show. */
#define EV3_UART_SCALE_MAX_NANO	((u64)S32_MAX * NANO + NANO - 1)

static const u64 ev3_pow10[EV3_UART_MAX_DECIMALS + 1] = {
	1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000,
	1000000000,
};

/* @nano scaled to nano-units and split into IIO_VAL_INT_PLUS_NANO. */
static int ev3_uart_set_scale(struct ev3_uart_chan *c, u64 nano, bool neg)
{
	if (nano < EV3_UART_SCALE_MIN_NANO || nano > EV3_UART_SCALE_MAX_NANO)
		return -ERANGE;
	c->scale_val = div_u64(nano, NANO);
	c->scale_val2 = nano - (u64)c->scale_val * NANO;
	if (neg) {
		c->scale_val = -c->scale_val;
		c->scale_val2 = -c->scale_val2;
	}
	return 0;
}

/**
 * ev3_uart_chan_scale() - the scale and offset of one channel
 * @m: the mode its value belongs to
 * @unit_nano: IIO units per SI unit of the mode, times 10^9
 * @c: the channel: gets @decimals, the scale and the offset
 *
 * Integer values are mapped linearly from the RAW range onto the SI range,
 * which is in units of 10^-decimals: scale = si_span / raw_span / 10^decimals
 * and offset = si_min * raw_span / si_span - raw_min, so that
 * (raw + offset) * scale is the SI value (times @unit_nano / 10^9). A zero
 * span maps nothing: the raw value is then taken as the SI value.
 *
 * Float values arrive in SI units already; _raw is the value times
 * 10^decimals, with as many of the mode's decimals as leave the scale at
 * least %EV3_UART_SCALE_MIN_NANO (a float with 9 decimals in degrees would
 * otherwise get a scale of 1.7e-11 rad, shown as 0).
 *
 * Return: 0, or -%ERANGE if the scale or offset cannot be shown (too large,
 * or too small to keep its precision): leave the channel out.
 */
int ev3_uart_chan_scale(const struct ev3_uart_mode *m, u64 unit_nano,
			struct ev3_uart_chan *c)
{
	s64 raw_span = (s64)m->raw_max - m->raw_min;
	s64 si_span = (s64)m->si_max - m->si_min;
	unsigned int dec = min_t(unsigned int, m->decimals, EV3_UART_MAX_DECIMALS);
	u64 scale, off, abs_min;
	s64 offset;
	s32 rem;
	bool neg;

	c->decimals = 0;
	c->offset_val = 0;
	c->offset_val2 = 0;

	if (m->data_type == EV3_UART_DATA_FLOAT) {
		/* Keep the most decimals that leave the scale precise. */
		for (c->decimals = dec; c->decimals; c->decimals--)
			if (div_u64(unit_nano, ev3_pow10[c->decimals]) >=
			    EV3_UART_SCALE_MIN_NANO)
				break;
		return ev3_uart_set_scale(c, div_u64(unit_nano + ev3_pow10[c->decimals] / 2,
						     ev3_pow10[c->decimals]), false);
	}

	if (!raw_span || !si_span) {
		if (ev3_uart_mul_div(unit_nano, 1, ev3_pow10[dec], true, &scale))
			return -ERANGE;
		return ev3_uart_set_scale(c, scale, false);
	}

	/* |raw_span| < 2^32 and 10^9 < 2^30: the divisor fits. */
	if (ev3_uart_mul_div(ev3_uart_abs64(si_span), unit_nano,
			     (u64)ev3_uart_abs64(raw_span) * ev3_pow10[dec], true,
			     &scale))
		return -ERANGE;
	neg = (si_span < 0) != (raw_span < 0);
	if (ev3_uart_set_scale(c, scale, neg))
		return -ERANGE;

	/* |si_min| <= 2^31 and |raw_span| < 2^32: the product fits. */
	abs_min = ev3_uart_abs64(m->si_min);
	if (ev3_uart_mul_div(abs_min * ev3_uart_abs64(raw_span), MICRO,
			     ev3_uart_abs64(si_span), true, &off))
		return -ERANGE;
	offset = ((m->si_min < 0) != neg) ? -(s64)off : (s64)off;
	if (check_sub_overflow(offset, (s64)m->raw_min * (s64)MICRO, &offset))
		return -ERANGE;
	offset = div_s64_rem(offset, MICRO, &rem);
	if (offset > S32_MAX || offset < S32_MIN)
		return -ERANGE;
	c->offset_val = offset;
	c->offset_val2 = rem;
	return 0;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_chan_scale);

/**
 * struct ev3_uart_unit - how a sensor unit maps onto an IIO channel type
 * @units: the sensor's unit symbol
 * @type: IIO channel type
 * @nano: IIO units per sensor unit, times 10^9
 */
struct ev3_uart_unit {
	const char *units;
	enum iio_chan_type type;
	u64 nano;
};

static const struct ev3_uart_unit ev3_uart_units[] = {
	{ "deg",	IIO_ANGL,		17453293 },	/* rad */
	{ "DEG",	IIO_ANGL,		17453293 },	/* Powered Up motors */
	{ "d/s",	IIO_ANGL_VEL,		17453293 },	/* rad/s */
	{ "cm",		IIO_DISTANCE,		10000000 },	/* m */
	{ "inch",	IIO_DISTANCE,		25400000 },	/* m */
	{ "mm",		IIO_DISTANCE,		1000000 },	/* m */
	{ "C",		IIO_TEMP,		1000000000000ULL },	/* m°C */
	{ "%RH",	IIO_HUMIDITYRELATIVE,	1000000000000ULL },	/* m% */
	{ "mV",		IIO_VOLTAGE,		1000000000 },	/* mV */
	{ "lx",		IIO_LIGHT,		1000000000 },	/* lux */
	{ "hPa",	IIO_PRESSURE,		100000000 },	/* kPa */
	{ "g",		IIO_ACCEL,		9806650000ULL },	/* m/s^2 */
	{ "uT",		IIO_MAGN,		10000000 },	/* gauss */
};

/*
 * The LEGO sensors' modes whose unit alone does not say what they measure.
 * A mode's values past the listed types get the last one. @lump: a Powered
 * Up device (their type ids overlap third-party EV3 ones).
 */
static const struct {
	u8 type;
	bool lump;
	const char *mode;
	enum iio_chan_type chan[2];
	u64 nano;
} ev3_uart_lego_modes[] = {
	{ EV3_UART_TYPE_COLOR, false, "COL-REFLECT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, false, "COL-AMBIENT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, false, "REF-RAW", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, false, "RGB-RAW", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_GYRO, false, "GYRO-FAS", { IIO_ANGL_VEL }, 17453293 },
	{ EV3_UART_TYPE_GYRO, false, "GYRO-G&A", { IIO_ANGL, IIO_ANGL_VEL }, 17453293 },
	{ EV3_UART_TYPE_IR, false, "IR-PROX", { IIO_PROXIMITY }, 1000000000 },
	{ EV3_UART_TYPE_BOOST_CDS, true, "REFLT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_BOOST_CDS, true, "AMBI", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_BOOST_CDS, true, "RGB I", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_BOOST_CDS, true, "PROX", { IIO_PROXIMITY }, 1000000000 },
	{ EV3_UART_TYPE_BOOST_CDS, true, "COUNT", { IIO_COUNT }, 1000000000 },
	{ EV3_UART_TYPE_SPIKE_COLOR, true, "REFLT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_SPIKE_COLOR, true, "AMBI", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_SPIKE_COLOR, true, "RREFL", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_SPIKE_COLOR, true, "RGB I", { IIO_INTENSITY }, 1000000000 },
	/*
	 * The Powered Up motors' speed, in percent of their top speed: IIO
	 * has no type for it, so a count (its label says SPEED).
	 */
	{ 38, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 46, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 47, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 48, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 49, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 65, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 75, true, "SPEED", { IIO_COUNT }, 1000000000 },
	{ 76, true, "SPEED", { IIO_COUNT }, 1000000000 },
};

static bool ev3_uart_chan_type(const struct ev3_uart_sensor *desc, u8 mode,
			       unsigned int index, enum iio_chan_type *type,
			       u64 *nano)
{
	const struct ev3_uart_mode *m = &desc->modes[mode];
	unsigned int i;

	for (i = 0; i < ARRAY_SIZE(ev3_uart_lego_modes); i++) {
		const enum iio_chan_type *chan = ev3_uart_lego_modes[i].chan;

		if (ev3_uart_lego_modes[i].type != desc->type ||
		    ev3_uart_lego_modes[i].lump != desc->lump ||
		    strcmp(ev3_uart_lego_modes[i].mode, m->name))
			continue;
		*type = chan[index && chan[1] ? 1 : 0];
		*nano = ev3_uart_lego_modes[i].nano;
		return true;
	}
	/* Units tell nothing for the colour or IR sensor's percentages. */
	for (i = 0; i < ARRAY_SIZE(ev3_uart_units); i++) {
		if (!strcmp(ev3_uart_units[i].units, m->units)) {
			*type = ev3_uart_units[i].type;
			*nano = ev3_uart_units[i].nano;
			return true;
		}
	}
	return false;
}

/*
 * The colour sensor's RGB-RAW: red, green, blue, then the LED-off reading;
 * the Powered Up colour sensors' RGB I likewise. Only the first mode of
 * that name (@rgb_used: its mode number, else %EV3_UART_NO_MODE) gets the
 * modifiers: a sensor that sends two modes of the same name would give
 * two channels the same IIO name (in_intensity_red_raw twice), and the IIO
 * core would refuse the whole device. The other mode's values are indexed
 * channels like any.
 */
static u8 ev3_uart_chan_modifier(const struct ev3_uart_sensor *desc, u8 mode,
				 unsigned int index, u8 *rgb_used)
{
	static const u8 rgb[] = { IIO_MOD_LIGHT_RED, IIO_MOD_LIGHT_GREEN,
				  IIO_MOD_LIGHT_BLUE };

	if (index >= ARRAY_SIZE(rgb))
		return 0;
	if (!(!desc->lump && desc->type == EV3_UART_TYPE_COLOR &&
	      !strcmp(desc->modes[mode].name, "RGB-RAW")) &&
	    !(desc->lump && (desc->type == EV3_UART_TYPE_BOOST_CDS ||
			     desc->type == EV3_UART_TYPE_SPIKE_COLOR) &&
	      !strcmp(desc->modes[mode].name, "RGB I")))
		return 0;
	if (*rgb_used == EV3_UART_NO_MODE)
		*rgb_used = mode;
	return *rgb_used == mode ? rgb[index] : 0;
}

/**
 * ev3_uart_chans_build() - the IIO channels of a sensor
 * @desc: the sensor's description, as the parser accepted it
 * @chans: room for @max channels, or NULL to count them only
 * @max: the room in @chans
 *
 * Every value of every mode whose unit has an IIO channel type, and whose
 * scale and offset can be shown, becomes a channel, in mode order. At most
 * %EV3_UART_MAX_CHANS channels are counted and at most @max filled in.
 * No two channels have the same type, modifier and index, the parts of
 * their IIO attribute names, whatever the sensor sent (twin mode names
 * included).
 *
 * Return: the number of channels the sensor has (call with @chans NULL to
 * size the array).
 */
unsigned int ev3_uart_chans_build(const struct ev3_uart_sensor *desc,
				  struct ev3_uart_chan *chans,
				  unsigned int max)
{
	u16 type_count[64] = { };
	u8 rgb_used = EV3_UART_NO_MODE;
	unsigned int n = 0, k, nmodes;
	struct ev3_uart_chan c;
	enum iio_chan_type type;
	u64 nano;
	u8 mode;

	nmodes = min_t(unsigned int, desc->num_modes, EV3_UART_MAX_MODES);
	for (mode = 0; mode < nmodes; mode++) {
		const struct ev3_uart_mode *m = &desc->modes[mode];
		unsigned int size = ev3_uart_data_size(m->data_type);
		unsigned int nvals = size ? min_t(unsigned int, m->num_values,
						  EV3_UART_MAX_PAYLOAD / size) : 0;

		for (k = 0; k < nvals && n < EV3_UART_MAX_CHANS; k++) {
			if (!ev3_uart_chan_type(desc, mode, k, &type, &nano) ||
			    type >= ARRAY_SIZE(type_count))
				continue;
			memset(&c, 0, sizeof(c));
			if (ev3_uart_chan_scale(m, nano, &c))
				continue;
			c.mode = mode;
			c.index = k;
			c.type = type;
			c.modifier = ev3_uart_chan_modifier(desc, mode, k, &rgb_used);
			if (!c.modifier)
				c.channel = type_count[type]++;
			c.realbits = 8 * size;
			if (chans && n < max)
				chans[n] = c;
			n++;
		}
	}
	return n;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_chans_build);

/**
 * ev3_uart_chan_read() - the _raw value of a channel from a DATA payload
 * @desc: the sensor
 * @c: the channel
 * @data: a DATA payload of the channel's mode
 * @len: its length
 * @out: the value (floats times 10^@c->decimals)
 *
 * Return: 0, or the errors of ev3_uart_read_value().
 */
int ev3_uart_chan_read(const struct ev3_uart_sensor *desc,
		       const struct ev3_uart_chan *c, const u8 *data,
		       size_t len, s32 *out)
{
	struct ev3_uart_mode m;

	if (c->mode >= EV3_UART_MAX_MODES)
		return -ENXIO;
	m = desc->modes[c->mode];
	if (m.data_type == EV3_UART_DATA_FLOAT)
		m.decimals = c->decimals;
	return ev3_uart_read_value(&m, data, len, c->index, out);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_chan_read);

/* ---- mode names ---- */

/* A mode's name with its spaces shown as underscores. */
static void ev3_uart_name_token(const char *name, char *buf)
{
	size_t i;

	for (i = 0; i < EV3_UART_NAME_LEN && name[i]; i++)
		buf[i] = name[i] == ' ' ? '_' : name[i];
	buf[i] = '\0';
}

/**
 * ev3_uart_mode_token() - how sysfs shows the name of a mode
 * @desc: the sensor
 * @mode: the mode, below @desc->num_modes
 * @buf: room for the token
 * @size: at least %EV3_UART_TOKEN_LEN + 1
 *
 * The "modes" attribute lists the modes separated by spaces, but sensors
 * name modes as they like: Powered Up devices call them "COL O" or
 * "IR Tx", and nothing stops two modes from having the same name. So a
 * mode is shown by its name with every space replaced by an underscore,
 * unless another mode would be shown the same way: then by "#" and its
 * number. Neither can be mistaken for another mode's token: a name starts
 * with a letter (the parser checks it).
 *
 * Return: the token's length, or -%EINVAL for a bad mode or too small a
 * buffer.
 */
int ev3_uart_mode_token(const struct ev3_uart_sensor *desc, u8 mode,
			char *buf, size_t size)
{
	char mine[EV3_UART_NAME_LEN + 1], other[EV3_UART_NAME_LEN + 1];
	unsigned int i;

	if (mode >= desc->num_modes || mode >= EV3_UART_MAX_MODES ||
	    size < EV3_UART_TOKEN_LEN + 1)
		return -EINVAL;
	ev3_uart_name_token(desc->modes[mode].name, mine);
	for (i = 0; i < desc->num_modes && i < EV3_UART_MAX_MODES; i++) {
		if (i == mode)
			continue;
		ev3_uart_name_token(desc->modes[i].name, other);
		if (!strcmp(mine, other))
			return snprintf(buf, size, "#%u", mode);
	}
	strscpy(buf, mine, size);
	return strlen(buf);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_mode_token);

/**
 * ev3_uart_version_string() - a Powered Up VERSION as LEGO writes it
 * @version: the firmware or hardware version from the VERSION message
 * @buf: room for the string
 * @size: at least %EV3_UART_VERSION_LEN + 1
 *
 * The version is four BCD fields: major (3 bits), minor (one digit),
 * bug fix (two digits) and build (four digits), shown as "1.0.00.0000".
 * The device is not trusted to send BCD: a nibble above 9 shows as a hex
 * digit, in the same room.
 *
 * Return: the string's length, or -%EINVAL if @size is too small.
 */
int ev3_uart_version_string(u32 version, char *buf, size_t size)
{
	if (size < EV3_UART_VERSION_LEN + 1)
		return -EINVAL;
	return snprintf(buf, size, "%x.%x.%02x.%04x", (version >> 28) & 0x7,
			(version >> 24) & 0xf, (version >> 16) & 0xff,
			version & 0xffff);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_version_string);

/* @str equals @s, ignoring one newline at the end of @str. */
static bool ev3_uart_streq(const char *str, size_t len, const char *s)
{
	return strlen(s) == len && !memcmp(str, s, len);
}

/**
 * ev3_uart_find_mode() - the mode a user named
 * @desc: the sensor
 * @str: what was written to a "mode" attribute (a newline may follow)
 *
 * Accepted: a token as ev3_uart_mode_token() shows it, "#" and a mode
 * number, or the name exactly as the sensor sent it if no other mode has
 * that name.
 *
 * Return: the mode number, or -%EINVAL.
 */
int ev3_uart_find_mode(const struct ev3_uart_sensor *desc, const char *str)
{
	char tok[EV3_UART_TOKEN_LEN + 1];
	unsigned int i, n = min_t(unsigned int, desc->num_modes, EV3_UART_MAX_MODES);
	size_t len = strlen(str);
	int found = -EINVAL;

	if (len && str[len - 1] == '\n')
		len--;
	/*
	 * "#" and the number, as ev3_uart_mode_token() writes it: one or two
	 * digits (Powered Up devices have up to 16 modes), no leading zero.
	 * No mode name starts with '#'.
	 */
	if (len && str[0] == '#') {
		unsigned int m = 0;

		if (len < 2 || len > 3 || (len == 3 && str[1] == '0'))
			return -EINVAL;
		for (i = 1; i < len; i++) {
			if (str[i] < '0' || str[i] > '9')
				return -EINVAL;
			m = m * 10 + str[i] - '0';
		}
		return m < n ? m : -EINVAL;
	}
	for (i = 0; i < n; i++) {
		if (ev3_uart_mode_token(desc, i, tok, sizeof(tok)) >= 0 &&
		    ev3_uart_streq(str, len, tok))
			return i;
	}
	for (i = 0; i < n; i++) {
		if (!ev3_uart_streq(str, len, desc->modes[i].name))
			continue;
		if (found >= 0)
			return -EINVAL;	/* two modes of that name */
		found = i;
	}
	return found;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_find_mode);
