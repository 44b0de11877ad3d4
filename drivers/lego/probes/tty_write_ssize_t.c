// SPDX-License-Identifier: GPL-2.0
/* 6.6: tty_operations::write returns ssize_t and takes a size_t count. */
#include <linux/tty_driver.h>

static_assert(__same_type(((const struct tty_operations *)0)->write,
			  (ssize_t (*)(struct tty_struct *, const u8 *, size_t))0),
	      "write");
