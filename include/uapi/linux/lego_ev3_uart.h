/* SPDX-License-Identifier: GPL-2.0 WITH Linux-syscall-note */
/*
 * LEGO MINDSTORMS EV3 UART sensors: userspace interface of the
 * lego_ev3_uart line discipline.
 *
 * Attach the discipline with TIOCSETD to N_LEGOEV3 (or ldattach), then use
 * these ioctls on the same tty.
 */
#ifndef _UAPI_LINUX_LEGO_EV3_UART_H
#define _UAPI_LINUX_LEGO_EV3_UART_H

#include <linux/ioctl.h>
#include <linux/tty.h>
#include <linux/types.h>

#ifndef N_LEGOEV3
/*
 * N_LEGOEV3 - the discipline's number. A kernel that has the driver in its
 * tree reserves one in <linux/tty.h>; the out-of-tree module takes
 * N_DEVELOPMENT (29), the number kept for disciplines outside the tree, as
 * ev3dev's did. tools/upstream/series.sh drops this block (unifdef).
 */
#define N_LEGOEV3		29
#endif

/** LEGO_EV3_LABEL_LEN - size of a port label, NUL included */
#define LEGO_EV3_LABEL_LEN	16

/**
 * struct lego_ev3_port_label - the label of the port a tty serves
 * @label: NUL-terminated, at most 15 characters from ``[A-Za-z0-9_.-]``,
 *	e.g. "in1"; empty for none. A sensor's address is "<tty>:<label>", or
 *	the tty name alone without a label.
 */
struct lego_ev3_port_label {
	char label[LEGO_EV3_LABEL_LEN];
};

#define LEGO_EV3_IOC_MAGIC	0xE3

/**
 * LEGO_EV3_SET_PORT_LABEL - set the port label (needs CAP_SYS_ADMIN)
 *
 * Applies to sensors that connect from then on; set it right after
 * attaching, before the sensor's handshake ends (1 to 2 s). Errors: EPERM,
 * EFAULT, EINVAL (characters outside the set, or no NUL).
 */
#define LEGO_EV3_SET_PORT_LABEL	_IOW(LEGO_EV3_IOC_MAGIC, 0x01, struct lego_ev3_port_label)

/** LEGO_EV3_GET_PORT_LABEL - read the port label */
#define LEGO_EV3_GET_PORT_LABEL	_IOR(LEGO_EV3_IOC_MAGIC, 0x02, struct lego_ev3_port_label)

#endif /* _UAPI_LINUX_LEGO_EV3_UART_H */
