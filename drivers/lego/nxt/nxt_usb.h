/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT brick over USB: what the USB transport (nxt_usb.c)
 * shares with the char device (nxt_cdev.c) and the sysfs attributes
 * (nxt_sysfs.c), which find the brick (struct nxt_brick, nxt_core.h) as
 * the bound interface's data.
 */
#ifndef _NXT_USB_H
#define _NXT_USB_H

#include <linux/sysfs.h>
#include <linux/usb.h>

extern struct usb_driver nxt_usb_driver;

/* nxt_cdev.c */
extern struct usb_class_driver nxt_usb_class;

/* nxt_sysfs.c */
extern const struct attribute_group *nxt_groups[];

#endif /* _NXT_USB_H */
