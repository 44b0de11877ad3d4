// SPDX-License-Identifier: GPL-2.0
/* 6.12: iio_for_each_active_channel() (active_scan_mask's length is private). */
#include <linux/iio/iio.h>

#ifndef iio_for_each_active_channel
#error no iio_for_each_active_channel
#endif
