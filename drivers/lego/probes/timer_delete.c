// SPDX-License-Identifier: GPL-2.0
/* 6.2 (and 6.1.y): del_timer*() became timer_delete*() (gone in 6.15). */
#include <linux/timer.h>

static_assert(__same_type(&timer_delete_sync, int (*)(struct timer_list *)), "timer_delete_sync");
