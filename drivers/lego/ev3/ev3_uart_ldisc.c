// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: tty line discipline.
 *
 * Attach it to any tty a sensor is wired to (`ldattach 29 /dev/ttyUSB0`).
 * This file is the transport glue: it owns the tty, the timers and the work
 * items. The protocol itself lives in ev3_uart_proto.c.
 *
 * Attaching requires CAP_SYS_ADMIN: a user who could attach the discipline to
 * a pty could play a hostile "sensor" and make the kernel register devices of
 * its choosing.
 */
#include <linux/capability.h>
#include <linux/module.h>
#include <linux/slab.h>
#include <linux/tty.h>
#include <linux/tty_ldisc.h>

#include "lego_compat.h"
#include "ev3_uart_proto.h"

#define EV3_UART_LDISC_NAME	"n_legoev3"

static int ldisc_num = N_DEVELOPMENT;
module_param(ldisc_num, int, 0444);
MODULE_PARM_DESC(ldisc_num, "line discipline number to register (default 29, N_DEVELOPMENT)");

/**
 * struct ev3_uart_port - state of one tty with the discipline attached
 * @tty: the tty, valid from open() to close()
 * @rx_bytes: bytes received since open()
 */
struct ev3_uart_port {
	struct tty_struct *tty;
	unsigned long rx_bytes;
};

static int ev3_uart_open(struct tty_struct *tty)
{
	struct ev3_uart_port *port;

	if (!capable(CAP_SYS_ADMIN))
		return -EPERM;

	/* The protocol needs to send ACK, NACK and SELECT. */
	if (!tty->ops->write)
		return -EOPNOTSUPP;

	port = kzalloc(sizeof(*port), GFP_KERNEL);
	if (!port)
		return -ENOMEM;

	port->tty = tty;
	tty->disc_data = port;
	tty->receive_room = 65536;
	tty_driver_flush_buffer(tty);

	return 0;
}

static void ev3_uart_close(struct tty_struct *tty)
{
	struct ev3_uart_port *port = tty->disc_data;

	tty->disc_data = NULL;
	kfree(port);
}

static void ev3_uart_receive_buf(struct tty_struct *tty, const u8 *cp,
				 const LEGO_TTY_FLAG *fp,
				 LEGO_TTY_COUNT count)
{
	struct ev3_uart_port *port = tty->disc_data;

	port->rx_bytes += count;
}

static struct tty_ldisc_ops ev3_uart_ldisc = {
	.owner		= THIS_MODULE,
	.name		= EV3_UART_LDISC_NAME,
	.open		= ev3_uart_open,
	.close		= ev3_uart_close,
	.receive_buf	= ev3_uart_receive_buf,
};

static int __init ev3_uart_init(void)
{
	int ret;

	if (ldisc_num < 0 || ldisc_num >= NR_LDISCS) {
		pr_err("lego-ev3-uart: ldisc_num %d out of range 0..%d\n",
		       ldisc_num, NR_LDISCS - 1);
		return -EINVAL;
	}

	ev3_uart_ldisc.num = ldisc_num;
	ret = tty_register_ldisc(&ev3_uart_ldisc);
	if (ret)
		pr_err("lego-ev3-uart: cannot register line discipline %d: %d\n",
		       ldisc_num, ret);
	return ret;
}
module_init(ev3_uart_init);

static void __exit ev3_uart_exit(void)
{
	tty_unregister_ldisc(&ev3_uart_ldisc);
}
module_exit(ev3_uart_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS EV3 UART sensor line discipline");
MODULE_LICENSE("GPL");
MODULE_ALIAS_LDISC(N_DEVELOPMENT);
