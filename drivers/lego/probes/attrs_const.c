// SPDX-License-Identifier: GPL-2.0
/* 6.18: attribute_group::attrs_const, a list of const attributes. */
#include <linux/sysfs.h>

static_assert(__same_type(((struct attribute_group *)0)->attrs_const,
			  (const struct attribute *const *)0),
	      "attrs_const");
