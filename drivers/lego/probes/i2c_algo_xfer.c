// SPDX-License-Identifier: GPL-2.0
/* 6.8: struct i2c_algorithm's master_xfer became xfer (the old name is deprecated). */
#include <linux/i2c.h>

static const struct i2c_algorithm lego_probe_algo = { .xfer = NULL };
