// SPDX-License-Identifier: GPL-2.0
/* 6.6: tty_ldisc_ops::receive_buf takes u8 flags and a size_t count. */
#include <linux/tty_ldisc.h>

static_assert(__same_type(((struct tty_ldisc_ops *)0)->receive_buf,
			  (void (*)(struct tty_struct *, const u8 *, const u8 *, size_t))0),
	      "receive_buf");
