/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT brick: the views of a brick, whatever its link: the
 * char device /dev/nxtN (nxt_cdev.c), its sysfs attributes (nxt_sysfs.c)
 * and the I2C adapters of its sensor ports (nxt_i2c.c). They use the
 * engine (nxt_core.h) only; a transport adds a brick's node, with its
 * adapters, when the brick comes and removes them when it goes.
 */
#ifndef _NXT_VIEWS_H
#define _NXT_VIEWS_H

#include <linux/device.h>
#include <linux/sysfs.h>

struct nxt_brick;

/* nxt_cdev.c */
int nxt_cdev_init(void);
void nxt_cdev_exit(void);
int nxt_node_add(struct nxt_brick *b, struct device *parent);
void nxt_node_remove(struct nxt_brick *b);

/* nxt_i2c.c: the sensor ports' I2C adapters, children of the node */
#if IS_ENABLED(CONFIG_LEGO_NXT_I2C)
void nxt_i2c_add(struct nxt_brick *b);
void nxt_i2c_remove(struct nxt_brick *b);
#else
static inline void nxt_i2c_add(struct nxt_brick *b) { }
static inline void nxt_i2c_remove(struct nxt_brick *b) { }
#endif

/* nxt_sysfs.c: the attributes of each node */
extern const struct attribute_group *nxt_groups[];

#endif /* _NXT_VIEWS_H */
