// SPDX-License-Identifier: GPL-2.0
/* 6.4: class_register() takes a const struct class. */
#include <linux/device/class.h>

static_assert(__same_type(&class_register, int (*)(const struct class *)), "class_register");
