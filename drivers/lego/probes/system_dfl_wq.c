// SPDX-License-Identifier: GPL-2.0
/*
 * 6.17 (and 6.12.y): system_percpu_wq and system_dfl_wq, the new names of
 * system_wq and system_unbound_wq (whose names are to be removed).
 */
#include <linux/workqueue.h>

static_assert(__same_type(system_dfl_wq, struct workqueue_struct *), "system_dfl_wq");
static_assert(__same_type(system_percpu_wq, struct workqueue_struct *), "system_percpu_wq");
