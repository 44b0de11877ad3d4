// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: the core module, lego_nxt. The transports
 * (lego_nxt_usb, lego_nxt_serial) give it bricks; it gives each brick its
 * /dev/nxtN, sysfs attributes, trace events and debugfs counters.
 */
#include <linux/init.h>
#include <linux/module.h>

#include "nxt_core.h"
#include "nxt_views.h"

static int __init nxt_init(void)
{
	int ret;

	ret = nxt_cdev_init();
	if (ret)
		return ret;
	nxt_core_debugfs_init();
	return 0;
}
module_init(nxt_init);

static void __exit nxt_exit(void)
{
	nxt_core_debugfs_exit();
	nxt_cdev_exit();
}
module_exit(nxt_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS NXT brick core: transactions, /dev/nxtN, sysfs");
MODULE_LICENSE("GPL");
