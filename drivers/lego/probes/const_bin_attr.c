// SPDX-License-Identifier: GPL-2.0
/*
 * 6.16: bin_attribute callbacks take a const struct bin_attribute, and
 * attribute_group::bin_attrs lists const ones.
 */
#include <linux/sysfs.h>

static_assert(__same_type(((struct bin_attribute *)0)->read,
			  (ssize_t (*)(struct file *, struct kobject *,
					const struct bin_attribute *, char *, loff_t, size_t))0),
	      "bin_attribute read");
static_assert(__same_type(((struct attribute_group *)0)->bin_attrs,
			  (const struct bin_attribute *const *)0),
	      "bin_attrs");
