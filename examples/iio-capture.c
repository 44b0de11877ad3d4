// SPDX-License-Identifier: GPL-2.0
/*
 * iio-capture: a buffered capture from an EV3 sensor's IIO device with
 * libiio. Each sample is printed as one line: the timestamp in nanoseconds
 * (CLOCK_REALTIME unless the device's current_timestamp_clock says other),
 * the raw value, and the value in the channel's IIO unit,
 * (raw + offset) * scale.
 *
 * Needs:  the lego_ev3_uart module and a sensor attached to its tty (see
 *         Documentation/lego/ev3-uart.rst), libiio and its headers
 *         (Debian: apt install libiio-dev), and read/write access to the
 *         IIO device's sysfs attributes and /dev/iio:deviceN: root, or
 *         the group "lego" with tools/udev/70-lego-ev3-iio.rules.
 * Build:  make iio-capture          (in this directory; by hand, link
 *         with -liio)
 * Run:    ./iio-capture [-n SAMPLES] DEVICE CHANNEL
 *         e.g. ./iio-capture -n 100 lego-ev3-gyro angl0
 *         DEVICE is the IIO device's name (lego-ev3-gyro), its label (the
 *         sensor's address, e.g. ttyAMA0) or its id (iio:device0); CHANNEL
 *         is a channel id as iio_info lists them. Enabling the buffer
 *         switches the sensor to the channel's mode. libiio 0.24 says
 *         "WARNING: High-speed mode not enabled" on stderr: the driver's
 *         buffer is a kfifo read with read(), without mmap, which is all
 *         this rate needs.
 */
#include <errno.h>
#include <getopt.h>
#include <iio.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Samples per buffer refill: enough for ~70 ms of a gyro at full speed. */
#define CHUNK 100

static long long raw_value(const struct iio_channel *ch, const void *src)
{
	const struct iio_data_format *fmt = iio_channel_get_data_format(ch);
	union {
		int8_t s8; uint8_t u8; int16_t s16; uint16_t u16;
		int32_t s32; uint32_t u32; int64_t s64;
	} v = { 0 };

	/* Byte order, shift and sign extension to the storage size. */
	iio_channel_convert(ch, &v, src);
	switch (fmt->length) {
	case 8:
		return fmt->is_signed ? (long long)v.s8 : (long long)v.u8;
	case 16:
		return fmt->is_signed ? (long long)v.s16 : (long long)v.u16;
	case 32:
		return fmt->is_signed ? (long long)v.s32 : (long long)v.u32;
	default:
		return v.s64;
	}
}

static void print_usage(FILE *f, const char *argv0)
{
	fprintf(f, "usage: %s [-n SAMPLES] DEVICE CHANNEL\n"
		"e.g.   %s -n 100 lego-ev3-gyro angl0\n", argv0, argv0);
}

int main(int argc, char **argv)
{
	struct iio_context *ctx;
	struct iio_device *dev;
	struct iio_channel *ch, *ts;
	struct iio_buffer *buf;
	double scale = 1.0, offset = 0.0;
	long count = 10, done = 0;
	int opt, ret = 1;

	while ((opt = getopt(argc, argv, "hn:")) != -1) {
		switch (opt) {
		case 'n':
			count = strtol(optarg, NULL, 0);
			if (count <= 0) {
				fprintf(stderr, "bad sample count: %s\n", optarg);
				return 2;
			}
			break;
		case 'h':
			print_usage(stdout, argv[0]);
			return 0;
		default:
			print_usage(stderr, argv[0]);
			return 2;
		}
	}
	if (argc - optind != 2) {
		print_usage(stderr, argv[0]);
		return 2;
	}

	ctx = iio_create_local_context();
	if (!ctx) {
		perror("iio_create_local_context");
		return 1;
	}
	dev = iio_context_find_device(ctx, argv[optind]);
	if (!dev) {
		fprintf(stderr, "no IIO device %s\n", argv[optind]);
		goto out_ctx;
	}
	ch = iio_device_find_channel(dev, argv[optind + 1], false);
	if (!ch || !iio_channel_is_scan_element(ch)) {
		fprintf(stderr, "%s has no buffered input channel %s\n",
			argv[optind], argv[optind + 1]);
		goto out_ctx;
	}
	ts = iio_device_find_channel(dev, "timestamp", false);
	/* Missing attributes leave the defaults: scale 1, offset 0. */
	iio_channel_attr_read_double(ch, "scale", &scale);
	iio_channel_attr_read_double(ch, "offset", &offset);

	iio_channel_enable(ch);
	if (ts)
		iio_channel_enable(ts);
	buf = iio_device_create_buffer(dev, count < CHUNK ? count : CHUNK, false);
	if (!buf) {
		fprintf(stderr, "iio_device_create_buffer: %s\n", strerror(errno));
		goto out_ctx;
	}

	while (done < count) {
		ptrdiff_t step = iio_buffer_step(buf);
		char *p, *pt = NULL, *end;
		ssize_t n = iio_buffer_refill(buf);

		if (n < 0) {
			fprintf(stderr, "iio_buffer_refill: %s\n", strerror((int)-n));
			goto out_buf;
		}
		end = iio_buffer_end(buf);
		if (ts)
			pt = iio_buffer_first(buf, ts);
		for (p = iio_buffer_first(buf, ch); p < end && done < count;
		     p += step, done++) {
			long long raw = raw_value(ch, p);

			printf("%lld %lld %.6f\n", pt ? raw_value(ts, pt) : 0LL,
			       raw, (raw + offset) * scale);
			if (pt)
				pt += step;
		}
		fflush(stdout);
	}
	ret = 0;
out_buf:
	iio_buffer_destroy(buf);
out_ctx:
	iio_context_destroy(ctx);
	return ret;
}
