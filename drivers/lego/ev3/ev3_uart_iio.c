// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: IIO front end.
 *
 * One IIO device per sensor, named after its driver name and parented to
 * the tty. Every value of every mode whose unit has an IIO channel type
 * becomes a channel; _raw is the sensor's integer and _scale/_offset map it
 * onto the IIO unit of that type, derived from the RAW and SI ranges the
 * sensor announced (see Documentation/lego/ev3-uart.rst for the table).
 *
 * A channel belongs to one mode. Reading a channel of a mode that is not the
 * current one fails with EBUSY: write the mode first ("mode" attribute).
 * A buffer may only hold channels of one mode; enabling it switches the
 * sensor to that mode. Every DATA message of that mode is then pushed with
 * a timestamp, from the receive path.
 */
#include <linux/iio/buffer.h>
#include <linux/iio/iio.h>
#include <linux/iio/kfifo_buf.h>
#include <linux/iio/sysfs.h>
#include <linux/math64.h>
#include <linux/slab.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "ev3_uart.h"

#define EV3_IIO_MAX_CHANNELS	(EV3_UART_MAX_MODES * 8 + 1)

/**
 * struct ev3_uart_iio - the IIO side of one sensor
 * @sd: the sensor
 * @indio: the IIO device
 * @buffer: its kfifo
 * @chan_mode: mode of each channel, by scan index
 * @chan_index: value index within its mode of each channel
 * @scale_nano: scale of each channel, in nano-units of the IIO unit
 * @offset_micro: offset of each channel, in micro raw units
 * @buffer_mode: mode whose DATA messages are pushed, or %EV3_UART_NO_MODE
 *	(under the port lock)
 * @last_ts: timestamp of the last message pushed, 0 for none yet (under the
 *	port lock)
 * @scan: one scan: a value per channel, then the timestamp
 */
struct ev3_uart_iio {
	struct ev3_uart_sensor_dev *sd;
	struct iio_dev *indio;
	struct iio_buffer *buffer;
	u8 chan_mode[EV3_IIO_MAX_CHANNELS];
	u8 chan_index[EV3_IIO_MAX_CHANNELS];
	s64 scale_nano[EV3_IIO_MAX_CHANNELS];
	s64 offset_micro[EV3_IIO_MAX_CHANNELS];
	u8 buffer_mode;
	s64 last_ts;
	struct {
		s32 v[EV3_IIO_MAX_CHANNELS];
		aligned_s64 ts;
	} scan;
};

/**
 * struct ev3_iio_unit - how a sensor unit maps onto an IIO channel type
 * @units: the sensor's unit symbol
 * @type: IIO channel type
 * @nano: IIO units per sensor unit, times 10^9
 */
struct ev3_iio_unit {
	const char *units;
	enum iio_chan_type type;
	s64 nano;
};

static const struct ev3_iio_unit ev3_iio_units[] = {
	{ "deg",	IIO_ANGL,		17453293 },	/* rad */
	{ "d/s",	IIO_ANGL_VEL,		17453293 },	/* rad/s */
	{ "cm",		IIO_DISTANCE,		10000000 },	/* m */
	{ "inch",	IIO_DISTANCE,		25400000 },	/* m */
	{ "mm",		IIO_DISTANCE,		1000000 },	/* m */
	{ "C",		IIO_TEMP,		1000000000000LL },	/* m°C */
	{ "%RH",	IIO_HUMIDITYRELATIVE,	1000000000000LL },	/* m% */
	{ "mV",		IIO_VOLTAGE,		1000000000 },	/* mV */
	{ "lx",		IIO_LIGHT,		1000000000 },	/* lux */
	{ "hPa",	IIO_PRESSURE,		100000000 },	/* kPa */
	{ "g",		IIO_ACCEL,		9806650000LL },	/* m/s^2 */
	{ "uT",		IIO_MAGN,		10000000 },	/* gauss */
};

/*
 * The LEGO sensors' modes whose unit alone does not say what they measure.
 * Values past the listed types get the last one.
 */
static const struct {
	u8 type;
	const char *mode;
	enum iio_chan_type chan[2];
	s64 nano;
} ev3_iio_modes[] = {
	{ EV3_UART_TYPE_COLOR, "COL-REFLECT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, "COL-AMBIENT", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, "REF-RAW", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_COLOR, "RGB-RAW", { IIO_INTENSITY }, 1000000000 },
	{ EV3_UART_TYPE_GYRO, "GYRO-FAS", { IIO_ANGL_VEL }, 17453293 },
	{ EV3_UART_TYPE_GYRO, "GYRO-G&A", { IIO_ANGL, IIO_ANGL_VEL }, 17453293 },
	{ EV3_UART_TYPE_IR, "IR-PROX", { IIO_PROXIMITY }, 1000000000 },
};

static bool ev3_iio_chan_type(const struct ev3_uart_sensor *desc, u8 mode,
			      unsigned int index, enum iio_chan_type *type,
			      s64 *nano)
{
	const struct ev3_uart_mode *m = &desc->modes[mode];
	unsigned int i;

	for (i = 0; i < ARRAY_SIZE(ev3_iio_modes); i++) {
		if (ev3_iio_modes[i].type != desc->type ||
		    strcmp(ev3_iio_modes[i].mode, m->name))
			continue;
		*type = ev3_iio_modes[i].chan[index && ev3_iio_modes[i].chan[1] ? 1 : 0];
		*nano = ev3_iio_modes[i].nano;
		return true;
	}
	/* Units tell nothing for the colour or IR sensor's percentages. */
	for (i = 0; i < ARRAY_SIZE(ev3_iio_units); i++) {
		if (!strcmp(ev3_iio_units[i].units, m->units)) {
			*type = ev3_iio_units[i].type;
			*nano = ev3_iio_units[i].nano;
			return true;
		}
	}
	return false;
}

/* The colour sensor's RGB-RAW: red, green, blue, then the LED-off reading. */
static int ev3_iio_modifier(const struct ev3_uart_sensor *desc, u8 mode,
			    unsigned int index)
{
	static const int rgb[] = { IIO_MOD_LIGHT_RED, IIO_MOD_LIGHT_GREEN,
				   IIO_MOD_LIGHT_BLUE };

	if (desc->type == EV3_UART_TYPE_COLOR &&
	    !strcmp(desc->modes[mode].name, "RGB-RAW") && index < ARRAY_SIZE(rgb))
		return rgb[index];
	return 0;
}

/*
 * processed = (raw + offset) * scale must equal the SI value in IIO units:
 * si = (raw - raw_min) * si_span / raw_span + si_min, si in 10^-decimals.
 */
static void ev3_iio_scale(struct ev3_uart_iio *iio, unsigned int ch,
			  const struct ev3_uart_mode *m, s64 nano)
{
	s64 raw_span = (s64)m->raw_max - m->raw_min;
	s64 si_span = (s64)m->si_max - m->si_min;
	u64 div = 1;
	unsigned int d;
	s64 off;

	for (d = 0; d < m->decimals; d++)
		div *= 10;

	/* Floats arrive already scaled by 10^decimals, in SI units. */
	if (m->data_type == EV3_UART_DATA_FLOAT || !raw_span || !si_span) {
		iio->scale_nano[ch] = div64_s64(nano, div);
		iio->offset_micro[ch] = 0;
		return;
	}

	iio->scale_nano[ch] = mul_u64_u64_div_u64(abs(si_span), nano,
						  abs(raw_span) * div);
	if ((si_span ^ raw_span) < 0)	/* signs differ */
		iio->scale_nano[ch] = -iio->scale_nano[ch];

	/* offset = si_min * raw_span / si_span - raw_min, in micro raw units */
	if (check_mul_overflow((s64)m->si_min, raw_span, &off) ||
	    check_mul_overflow(off, (s64)1000000, &off))
		off = 0;
	iio->offset_micro[ch] = div64_s64(off, si_span) - (s64)m->raw_min * 1000000;
}

static int ev3_iio_read_raw(struct iio_dev *indio, struct iio_chan_spec const *chan,
			    int *val, int *val2, long mask)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	unsigned int ch = chan->scan_index;
	u8 data[EV3_UART_MAX_PAYLOAD], mode;
	s64 v;
	int ret;

	switch (mask) {
	case IIO_CHAN_INFO_RAW:
		ret = ev3_uart_get_data(iio->sd, &mode, data);
		if (ret < 0)
			return ret;
		if (mode != iio->chan_mode[ch])
			return -EBUSY;
		ret = ev3_uart_read_value(&iio->sd->desc.modes[mode], data,
					  EV3_UART_MAX_PAYLOAD, iio->chan_index[ch], val);
		return ret ? ret : IIO_VAL_INT;
	case IIO_CHAN_INFO_SCALE:
		v = iio->scale_nano[ch];
		*val = div_s64_rem(v, 1000000000, val2);
		return IIO_VAL_INT_PLUS_NANO;
	case IIO_CHAN_INFO_OFFSET:
		v = iio->offset_micro[ch];
		*val = div_s64_rem(v, 1000000, val2);
		return IIO_VAL_INT_PLUS_MICRO;
	default:
		return -EINVAL;
	}
}

/* A buffer holds the values of one mode only. */
static bool ev3_iio_validate_scan_mask(struct iio_dev *indio,
				       const unsigned long *mask)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	unsigned int ch, last = indio->num_channels - 1;
	int mode = -1;

	for_each_set_bit(ch, mask, last) {
		if (mode >= 0 && iio->chan_mode[ch] != mode)
			return false;
		mode = iio->chan_mode[ch];
	}
	return true;
}

static ssize_t mode_show(struct device *dev, struct device_attribute *attr,
			 char *buf)
{
	struct ev3_uart_iio *iio = iio_priv(dev_to_iio_dev(dev));
	u8 data[EV3_UART_MAX_PAYLOAD], mode;
	int ret = ev3_uart_get_data(iio->sd, &mode, data);

	if (ret < 0)
		return ret;
	return sysfs_emit(buf, "%s\n", iio->sd->desc.modes[mode].name);
}

static ssize_t mode_store(struct device *dev, struct device_attribute *attr,
			  const char *buf, size_t count)
{
	struct ev3_uart_iio *iio = iio_priv(dev_to_iio_dev(dev));
	int ret = ev3_uart_set_mode_by_name(iio->sd, buf);

	return ret ? ret : count;
}
static IIO_DEVICE_ATTR_RW(mode, 0);

static ssize_t modes_show(struct device *dev, struct device_attribute *attr,
			  char *buf)
{
	struct ev3_uart_iio *iio = iio_priv(dev_to_iio_dev(dev));

	return ev3_uart_show_modes(iio->sd, buf);
}
static IIO_DEVICE_ATTR_RO(modes, 0);

static struct attribute *ev3_iio_attrs[] = {
	&iio_dev_attr_mode.dev_attr.attr,
	&iio_dev_attr_modes.dev_attr.attr,
	NULL
};

static const struct attribute_group ev3_iio_attr_group = {
	.attrs = ev3_iio_attrs,
};

static const struct iio_info ev3_iio_info = {
	.read_raw = ev3_iio_read_raw,
	.attrs = &ev3_iio_attr_group,
};

static int ev3_iio_postenable(struct iio_dev *indio)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	unsigned int ch;
	u8 mode;
	int ret;

	ch = find_first_bit(indio->active_scan_mask, indio->num_channels - 1);
	if (ch >= indio->num_channels - 1)
		return -EINVAL;
	mode = iio->chan_mode[ch];
	ret = ev3_uart_set_mode(iio->sd, mode);
	if (ret)
		return ret;
	spin_lock(&iio->sd->port->lock);
	iio->buffer_mode = mode;
	iio->last_ts = 0;
	spin_unlock(&iio->sd->port->lock);
	return 0;
}

static int ev3_iio_predisable(struct iio_dev *indio)
{
	struct ev3_uart_iio *iio = iio_priv(indio);

	spin_lock(&iio->sd->port->lock);
	iio->buffer_mode = EV3_UART_NO_MODE;
	spin_unlock(&iio->sd->port->lock);
	return 0;
}

static const struct iio_buffer_setup_ops ev3_iio_buffer_ops = {
	.postenable = ev3_iio_postenable,
	.predisable = ev3_iio_predisable,
	.validate_scan_mask = ev3_iio_validate_scan_mask,
};

/*
 * When the last byte of a DATA message of @len payload bytes arrived, @rest
 * bytes before the end of the batch being received (see ev3_uart_msg_time()).
 */
static s64 ev3_iio_timestamp(struct ev3_uart_iio *iio, unsigned int len,
			     size_t rest)
{
	/* On the wire: header, payload, checksum. */
	iio->last_ts = ev3_uart_msg_time(iio_get_time_ns(iio->indio), rest,
					 len + 2, iio->sd->desc.speed,
					 iio->last_ts);
	return iio->last_ts;
}

/**
 * ev3_uart_iio_push() - push one DATA message to the buffer
 * @sd: the sensor
 * @mode: the mode of the message
 * @data: its payload
 * @len: its length
 * @rest: bytes received after the message in the same batch
 *
 * Called from the receive path under the port lock; never sleeps.
 */
void ev3_uart_iio_push(struct ev3_uart_sensor_dev *sd, u8 mode,
		       const u8 *data, unsigned int len, size_t rest)
{
	struct ev3_uart_iio *iio = sd->iio;
	struct iio_dev *indio;
	unsigned int ch, i = 0;

	if (!iio || iio->buffer_mode != mode ||
	    time_before(jiffies, sd->settle_until))
		return;
	indio = iio->indio;
	for_each_set_bit(ch, indio->active_scan_mask, indio->num_channels - 1)
		if (ev3_uart_read_value(&sd->desc.modes[mode], data, len,
					iio->chan_index[ch], &iio->scan.v[i++]))
			iio->scan.v[i - 1] = 0;
	iio_push_to_buffers_with_timestamp(indio, &iio->scan,
					   ev3_iio_timestamp(iio, len, rest));
}

static void ev3_iio_fill_channels(struct ev3_uart_iio *iio,
				  struct iio_chan_spec *chans)
{
	const struct ev3_uart_sensor *desc = &iio->sd->desc;
	unsigned int n = 0, type_count[64] = { };
	enum iio_chan_type type;
	u8 mode, k;
	s64 nano;

	for (mode = 0; mode < desc->num_modes; mode++) {
		const struct ev3_uart_mode *m = &desc->modes[mode];

		for (k = 0; k < m->num_values; k++) {
			struct iio_chan_spec *c = &chans[n];

			if (!ev3_iio_chan_type(desc, mode, k, &type, &nano) ||
			    type >= ARRAY_SIZE(type_count))
				break;
			c->type = type;
			c->modified = ev3_iio_modifier(desc, mode, k) != 0;
			c->channel2 = ev3_iio_modifier(desc, mode, k);
			c->indexed = !c->modified;
			c->channel = type_count[type]++;
			c->info_mask_separate = BIT(IIO_CHAN_INFO_RAW) |
						BIT(IIO_CHAN_INFO_SCALE) |
						BIT(IIO_CHAN_INFO_OFFSET);
			c->scan_index = n;
			c->scan_type.sign = 's';
			c->scan_type.realbits = 8 * ev3_uart_data_size(m->data_type);
			c->scan_type.storagebits = 32;
			c->scan_type.endianness = IIO_CPU;
			iio->chan_mode[n] = mode;
			iio->chan_index[n] = k;
			ev3_iio_scale(iio, n, m, nano);
			n++;
		}
	}
	chans[n] = (struct iio_chan_spec)IIO_CHAN_SOFT_TIMESTAMP(n);
	iio->indio->num_channels = n + 1;
}

/**
 * ev3_uart_iio_register() - create and register a sensor's IIO device
 * @sd: the sensor, registered in the lego-sensor class
 *
 * Return: 0 or a negative errno.
 */
int ev3_uart_iio_register(struct ev3_uart_sensor_dev *sd)
{
	struct iio_chan_spec *chans;
	struct ev3_uart_iio *iio;
	struct iio_dev *indio;
	int ret;

	indio = iio_device_alloc(sd->port->tty->dev, sizeof(*iio));
	if (!indio)
		return -ENOMEM;
	iio = iio_priv(indio);
	iio->sd = sd;
	iio->indio = indio;
	iio->buffer_mode = EV3_UART_NO_MODE;

	chans = devm_kcalloc(&indio->dev, EV3_IIO_MAX_CHANNELS, sizeof(*chans),
			     GFP_KERNEL);
	if (!chans) {
		ret = -ENOMEM;
		goto free;
	}
	ev3_iio_fill_channels(iio, chans);
	indio->channels = chans;
	indio->name = sd->driver_name;
	indio->info = &ev3_iio_info;
	indio->modes = INDIO_DIRECT_MODE;
	indio->setup_ops = &ev3_iio_buffer_ops;

	iio->buffer = iio_kfifo_allocate();
	if (!iio->buffer) {
		ret = -ENOMEM;
		goto free;
	}
	ret = iio_device_attach_buffer(indio, iio->buffer);
	if (ret)
		goto free_buffer;
	indio->modes |= INDIO_BUFFER_SOFTWARE;

	ret = iio_device_register(indio);
	if (ret)
		goto free_buffer;

	/* From now on the receive path may push (under the port lock). */
	spin_lock(&sd->port->lock);
	sd->iio = iio;
	spin_unlock(&sd->port->lock);
	return 0;

free_buffer:
	iio_kfifo_free(iio->buffer);
free:
	iio_device_free(indio);
	return ret;
}

/**
 * ev3_uart_iio_unregister() - remove a sensor's IIO device
 * @sd: the sensor, no longer reachable from the receive path
 */
void ev3_uart_iio_unregister(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_iio *iio = sd->iio;

	if (!iio)
		return;
	sd->iio = NULL;
	iio_device_unregister(iio->indio);
	iio_kfifo_free(iio->buffer);
	iio_device_free(iio->indio);
}
