// SPDX-License-Identifier: GPL-2.0
/* 6.2: class uevent callbacks take a const struct device. */
#include <linux/device.h>

static_assert(__same_type(((struct class *)0)->dev_uevent,
			  (int (*)(const struct device *, struct kobj_uevent_env *))0),
	      "dev_uevent");
