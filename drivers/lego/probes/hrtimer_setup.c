// SPDX-License-Identifier: GPL-2.0
/* 6.13: hrtimer_setup() (hrtimer_init() is gone since 6.15). */
#include <linux/hrtimer.h>

static_assert(__same_type(&hrtimer_setup,
			  void (*)(struct hrtimer *, enum hrtimer_restart (*)(struct hrtimer *),
				   clockid_t, enum hrtimer_mode)),
	      "hrtimer_setup");
