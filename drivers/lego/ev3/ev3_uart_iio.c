// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: IIO front end.
 *
 * One IIO device per sensor, named after its driver name, labelled with its
 * address and parented to the tty. The channels come from
 * ev3_uart_chans_build(): every value of every mode whose unit has an IIO
 * channel type and whose scale IIO can show; _raw is the sensor's integer
 * (floats times 10^decimals) and _scale/_offset map it onto the IIO unit of
 * that type, derived from the RAW and SI ranges the sensor announced (see
 * Documentation/lego/ev3-uart.rst for the table). A sensor with no channel
 * gets no IIO device.
 *
 * A channel belongs to one mode. Reading a channel of a mode that is not the
 * current one fails with EBUSY: write the mode first ("mode" attribute).
 * A buffer holds channels of one mode, or of several modes that one of
 * the combinations a Powered Up device offers (MODE_COMBOS) has: enabling
 * it switches the sensor to that mode, or sets the combined mode up
 * (ev3_uart_hold_combo()). Every DATA message of that mode, or every
 * combined one, is then pushed with a timestamp, from the receive path.
 */
#include <linux/iio/buffer.h>
#include <linux/iio/iio.h>
#include <linux/iio/kfifo_buf.h>
#include <linux/iio/sysfs.h>
#include <linux/lockdep.h>
#include <linux/math.h>
#include <linux/slab.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "ev3_uart_core.h"
#include "ev3_uart_chan.h"
#include "ev3_uart_views.h"

/**
 * struct ev3_uart_iio - the IIO side of one sensor
 * @sd: the sensor; valid until ev3_uart_iio_unregister() returns, after
 *	which the IIO core calls none of the callbacks below (it checks
 *	&iio_dev.info), even for a /dev/iio:deviceN still held open
 * @indio: the IIO device
 * @buffer: its kfifo
 * @chans: the channels as ev3_uart_chans_build() made them, by scan index
 * @num_chans: their number, at least 1
 * @last_ts: timestamp of the last message pushed, 0 for none yet (under the
 *	port lock)
 * @scan: one scan: a value per channel, then the timestamp (under the port
 *	lock)
 * @scan_size: the size of @scan in bytes
 * @combo: while a buffer of several modes is enabled, its channels' values
 *	in scan order (set before the combined mode, read under the port lock)
 * @combo_off: where each of them is in a combined DATA message
 * @combo_n: their number; 0 while no combined mode is set up
 * @name: the IIO device's name, the sensor's driver name (a copy: the IIO
 *	device can outlive the sensor)
 * @label: its label, the sensor's address (a copy)
 */
struct ev3_uart_iio {
	struct ev3_uart_sensor_dev *sd;
	struct iio_dev *indio;
	struct iio_buffer *buffer;
	struct ev3_uart_chan *chans;
	unsigned int num_chans;
	s64 last_ts;
	s32 *scan;
	size_t scan_size;
	struct ev3_uart_combo_entry combo[EV3_UART_MAX_COMBO_ENTRIES];
	u8 combo_off[EV3_UART_MAX_COMBO_ENTRIES];
	unsigned int combo_n;
	char name[sizeof_field(struct ev3_uart_sensor_dev, driver_name)];
	char label[EV3_UART_ADDRESS_LEN];
};

static int ev3_iio_read_raw(struct iio_dev *indio, struct iio_chan_spec const *chan,
			    int *val, int *val2, long mask)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	const struct ev3_uart_chan *c = &iio->chans[chan->scan_index];
	u8 data[EV3_UART_MAX_PAYLOAD], mode;
	int ret;

	switch (mask) {
	case IIO_CHAN_INFO_RAW:
		ret = ev3_uart_get_values(iio->sd, &mode, data);
		if (ret < 0)
			return ret;
		if (mode != c->mode)
			return -EBUSY;
		ret = ev3_uart_chan_read(&iio->sd->desc, c, data,
					 EV3_UART_MAX_PAYLOAD, val);
		return ret ? ret : IIO_VAL_INT;
	case IIO_CHAN_INFO_SCALE:
		*val = c->scale_val;
		*val2 = c->scale_val2;
		return IIO_VAL_INT_PLUS_NANO;
	case IIO_CHAN_INFO_OFFSET:
		*val = c->offset_val;
		*val2 = c->offset_val2;
		return IIO_VAL_INT_PLUS_MICRO;
	default:
		return -EINVAL;
	}
}

static int ev3_iio_read_label(struct iio_dev *indio,
			      struct iio_chan_spec const *chan, char *label)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	const struct ev3_uart_chan *c = &iio->chans[chan->scan_index];
	char tok[EV3_UART_TOKEN_LEN + 1];
	int ret;

	ret = ev3_uart_mode_token(&iio->sd->desc, c->mode, tok, sizeof(tok));
	if (ret < 0)
		return ret;
	return sysfs_emit(label, "%s value%u\n", tok, c->index);
}

/*
 * The values of the channels of @mask, in scan order, in @e (room for
 * %EV3_UART_MAX_COMBO_ENTRIES). Return: their number, 0 if they are of
 * one mode (however many), or -%E2BIG if they are of several modes and
 * too many to combine.
 */
static int ev3_iio_combo_entries(struct ev3_uart_iio *iio,
				 const unsigned long *mask,
				 struct ev3_uart_combo_entry *e)
{
	unsigned int ch, n = 0;
	bool one_mode = true;
	int first = -1;

	for_each_set_bit(ch, mask, iio->num_chans) {
		if (first < 0)
			first = iio->chans[ch].mode;
		else if (iio->chans[ch].mode != first)
			one_mode = false;
		if (n < EV3_UART_MAX_COMBO_ENTRIES) {
			e[n].mode = iio->chans[ch].mode;
			e[n].index = iio->chans[ch].index;
		}
		n++;
	}
	if (one_mode)
		return 0;
	return n <= EV3_UART_MAX_COMBO_ENTRIES ? n : -E2BIG;
}

/*
 * A buffer holds the values of one mode, or of several that a combination
 * of the device has (ev3_uart_combo_find()).
 */
static bool ev3_iio_validate_scan_mask(struct iio_dev *indio,
				       const unsigned long *mask)
{
	struct ev3_uart_combo_entry e[EV3_UART_MAX_COMBO_ENTRIES];
	struct ev3_uart_iio *iio = iio_priv(indio);
	unsigned int len;
	int n;

	n = ev3_iio_combo_entries(iio, mask, e);
	if (!n)
		return true;
	return n > 0 && ev3_uart_combo_find(&iio->sd->desc, e, n, &len) >= 0;
}

static ssize_t mode_show(struct device *dev, struct device_attribute *attr,
			 char *buf)
{
	struct ev3_uart_iio *iio = iio_priv(dev_to_iio_dev(dev));

	return ev3_uart_show_mode(iio->sd, buf);
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

static LEGO_ATTR_CONST struct attribute *LEGO_ATTR_CONST ev3_iio_attrs[] = {
	&iio_dev_attr_mode.dev_attr.attr,
	&iio_dev_attr_modes.dev_attr.attr,
	NULL
};

static const struct attribute_group ev3_iio_attr_group = {
	.LEGO_GROUP_ATTRS = ev3_iio_attrs,
};

static const struct iio_info ev3_iio_info = {
	.read_raw = ev3_iio_read_raw,
	.read_label = ev3_iio_read_label,
	.attrs = &ev3_iio_attr_group,
};

/* Set up the combined mode of a buffer of several modes' channels. */
static int ev3_iio_combo_enable(struct ev3_uart_iio *iio, unsigned int n)
{
	unsigned int j;
	int off, ret;

	for (j = 0; j < n; j++) {
		off = ev3_uart_combo_offset(&iio->sd->desc, iio->combo, n, j);
		if (off < 0)
			return off;
		iio->combo_off[j] = off;
	}
	iio->last_ts = 0;
	/* Read by the receive path only once the core holds the combination. */
	iio->combo_n = n;
	ret = ev3_uart_hold_combo(iio->sd, iio->combo, n);
	if (ret)
		iio->combo_n = 0;
	return ret;
}

static int ev3_iio_postenable(struct iio_dev *indio)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	unsigned int ch;
	int n;
	u8 mode;

	n = ev3_iio_combo_entries(iio, indio->active_scan_mask, iio->combo);
	if (n < 0)
		return n;
	if (n)
		return ev3_iio_combo_enable(iio, n);

	/* The scan mask holds the channels of one mode (validate_scan_mask). */
	iio_for_each_active_channel(indio, ch)
		break;
	if (ch >= iio->num_chans)
		return -EINVAL;
	mode = iio->chans[ch].mode;
	/*
	 * Nothing is pushed until the sensor is held to the mode, which is
	 * before a mode write can take it away: the first timestamp then
	 * has no predecessor.
	 */
	iio->last_ts = 0;
	return ev3_uart_hold_mode(iio->sd, mode);
}

static int ev3_iio_predisable(struct iio_dev *indio)
{
	struct ev3_uart_iio *iio = iio_priv(indio);

	if (iio->combo_n) {
		ev3_uart_release_combo(iio->sd);
		iio->combo_n = 0;
	} else {
		ev3_uart_release_mode(iio->sd);
	}
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

/*
 * Push one combined DATA message: a value per channel of the scan, one after
 * the other (its mode 0 header says nothing). A shorter message is mode 0's
 * own, sent before the combination was set up: dropped.
 */
static void ev3_uart_iio_combo_data(struct ev3_uart_iio *iio, const u8 *data,
				    unsigned int len, size_t rest)
{
	struct ev3_uart_sensor_dev *sd = iio->sd;
	struct ev3_uart_chan c;
	unsigned int ch, i = 0;

	if (len < sd->combo_len || !iio->combo_n)
		return;
	iio_for_each_active_channel(iio->indio, ch) {
		if (ch >= iio->num_chans || i >= iio->combo_n)
			break;
		c = iio->chans[ch];
		c.index = 0;
		if (iio->combo_off[i] >= len ||
		    ev3_uart_chan_read(&sd->desc, &c, data + iio->combo_off[i],
				       len - iio->combo_off[i], &iio->scan[i]))
			iio->scan[i] = 0;
		i++;
	}
	iio_push_to_buffers_with_ts(iio->indio, iio->scan, iio->scan_size,
				    ev3_iio_timestamp(iio, len, rest));
}

/*
 * Push one DATA message of @mode, @len bytes, @rest bytes before the end
 * of its batch, to the buffer if it captures @mode (&ev3_uart_view_ops.data:
 * from the receive path, under the port lock; never sleeps).
 */
static void ev3_uart_iio_data(struct ev3_uart_sensor_dev *sd, u8 mode,
			      const u8 *data, unsigned int len, size_t rest)
{
	struct ev3_uart_iio *iio = sd->iio;
	unsigned int ch, i = 0;

	lockdep_assert_held(&sd->port->lock);
	if (!iio || sd->held_mode != mode)
		return;
	if (sd->combo_len) {
		ev3_uart_iio_combo_data(iio, data, len, rest);
		return;
	}
	iio_for_each_active_channel(iio->indio, ch) {
		/* The timestamp, last of the scan, is no channel of ours. */
		if (ch >= iio->num_chans)
			break;
		if (ev3_uart_chan_read(&sd->desc, &iio->chans[ch], data, len,
				       &iio->scan[i]))
			iio->scan[i] = 0;
		i++;
	}
	iio_push_to_buffers_with_ts(iio->indio, iio->scan, iio->scan_size,
				    ev3_iio_timestamp(iio, len, rest));
}

/* The IIO channel specs of the channels, then the timestamp. */
static struct iio_chan_spec *ev3_iio_chan_specs(struct ev3_uart_iio *iio)
{
	struct iio_chan_spec *specs;
	unsigned int n;

	specs = devm_kcalloc(&iio->indio->dev, iio->num_chans + 1,
			     sizeof(*specs), GFP_KERNEL);
	if (!specs)
		return NULL;
	for (n = 0; n < iio->num_chans; n++) {
		const struct ev3_uart_chan *c = &iio->chans[n];
		struct iio_chan_spec *s = &specs[n];

		s->type = c->type;
		s->modified = c->modifier != 0;
		s->channel2 = c->modifier;
		s->indexed = !s->modified;
		s->channel = c->channel;
		s->info_mask_separate = BIT(IIO_CHAN_INFO_RAW) |
					BIT(IIO_CHAN_INFO_SCALE) |
					BIT(IIO_CHAN_INFO_OFFSET);
		s->scan_index = n;
		s->scan_type.sign = 's';
		s->scan_type.realbits = c->realbits;
		s->scan_type.storagebits = 32;
		s->scan_type.endianness = IIO_CPU;
	}
	specs[n] = (struct iio_chan_spec)IIO_CHAN_SOFT_TIMESTAMP(n);
	return specs;
}

/*
 * The IIO device of @sd with its @n channels (and the timestamp), not
 * registered yet: -ENOMEM, or 0 with what iio_device_free() frees.
 */
static int ev3_uart_iio_setup(struct iio_dev *indio, struct ev3_uart_sensor_dev *sd,
			      unsigned int n)
{
	struct ev3_uart_iio *iio = iio_priv(indio);
	const struct iio_chan_spec *specs;

	iio->sd = sd;
	iio->indio = indio;
	iio->num_chans = n;
	strscpy(iio->name, sd->driver_name, sizeof(iio->name));
	strscpy(iio->label, sd->address, sizeof(iio->label));

	iio->chans = devm_kcalloc(&indio->dev, n, sizeof(*iio->chans), GFP_KERNEL);
	/* A value per channel, then the timestamp, 8-byte aligned. */
	iio->scan_size = round_up(n * sizeof(s32), 8) + 8;
	iio->scan = devm_kzalloc(&indio->dev, iio->scan_size, GFP_KERNEL);
	if (!iio->chans || !iio->scan)
		return -ENOMEM;
	if (WARN_ON(ev3_uart_chans_build(&sd->desc, iio->chans, n) != n))
		return -ENOMEM;
	specs = ev3_iio_chan_specs(iio);
	if (!specs)
		return -ENOMEM;
	indio->channels = specs;
	indio->num_channels = n + 1;
	indio->name = iio->name;
	indio->label = iio->label;
	indio->info = &ev3_iio_info;
	indio->modes = INDIO_DIRECT_MODE;
	indio->setup_ops = &ev3_iio_buffer_ops;
	return 0;
}

/* Create and register a sensor's IIO device: -ENOMEM, or 0. */
static int ev3_uart_iio_register(struct ev3_uart_sensor_dev *sd, unsigned int n)
{
	struct ev3_uart_iio *iio;
	struct iio_dev *indio;
	int ret;

	indio = iio_device_alloc(sd->port->parent, sizeof(*iio));
	if (!indio)
		return -ENOMEM;
	iio = iio_priv(indio);
	ret = ev3_uart_iio_setup(indio, sd, n);
	if (ret)
		goto free;

	ret = -ENOMEM;
	iio->buffer = iio_kfifo_allocate();
	if (!iio->buffer)
		goto free;
	ret = iio_device_attach_buffer(indio, iio->buffer);
	if (ret)
		goto free_buffer;
	indio->modes |= INDIO_BUFFER_SOFTWARE;

	ret = iio_device_register(indio);
	if (ret)
		goto free_buffer;
	/* Not published to the receive path yet: no lock needed. */
	sd->iio = iio;
	return 0;

free_buffer:
	iio_kfifo_free(iio->buffer);
free:
	iio_device_free(indio);
	return ret;
}

/*
 * A sensor completed its handshake: its IIO device (&ev3_uart_view_ops.add).
 * A sensor none of whose values has an IIO channel type (or a scale IIO can
 * show) gets none; one whose device cannot be registered carries on
 * without it, as a sensor of the class: both are said in the log.
 */
static int ev3_uart_iio_add(struct ev3_uart_sensor_dev *sd)
{
	unsigned int n = ev3_uart_chans_build(&sd->desc, NULL, 0);
	int ret;

	if (!n) {
		/* Once a connection: limited like the port's other lines. */
		if (ev3_uart_sensor_log_ok(sd))
			pr_info("%s: %s: no value has an IIO type and scale: no IIO device\n",
				sd->address, ev3_uart_sensor_name(sd));
		return 0;
	}
	ret = ev3_uart_iio_register(sd, n);
	if (ret)
		pr_warn("%s: %s: no IIO device: %d\n", sd->address,
			ev3_uart_sensor_name(sd), ret);
	return 0;
}

/*
 * The sensor is gone and out of the receive path's reach: remove its IIO
 * device (&ev3_uart_view_ops.remove). After this, no IIO callback runs for
 * @sd, even if /dev/iio:deviceN is still open: the IIO core refuses every
 * call on an unregistered device. The IIO device's memory goes with its
 * last reference.
 */
static void ev3_uart_iio_remove(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_iio *iio = sd->iio;

	if (!iio)
		return;
	sd->iio = NULL;
	iio_device_unregister(iio->indio);
	iio_kfifo_free(iio->buffer);
	iio_device_free(iio->indio);
}

static const struct ev3_uart_view_ops ev3_uart_iio_view = {
	.add	= ev3_uart_iio_add,
	.remove	= ev3_uart_iio_remove,
	.data	= ev3_uart_iio_data,
};

/**
 * ev3_uart_iio_init() - register the IIO view with the core
 *
 * Return: 0 or the core's error.
 */
int ev3_uart_iio_init(void)
{
	return ev3_uart_view_register(&ev3_uart_iio_view);
}

/**
 * ev3_uart_iio_exit() - unregister the IIO view
 */
void ev3_uart_iio_exit(void)
{
	ev3_uart_view_unregister(&ev3_uart_iio_view);
}
