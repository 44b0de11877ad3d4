// SPDX-License-Identifier: GPL-2.0
/* 6.16: iio_push_to_buffers_with_ts() takes the scan's size. */
#include <linux/iio/buffer.h>

static_assert(__same_type(&iio_push_to_buffers_with_ts,
			  int (*)(struct iio_dev *, void *, size_t, s64)),
	      "iio_push_to_buffers_with_ts");
