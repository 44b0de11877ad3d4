/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensors: the views' registration, for the
 * module's init and exit. Each view registers its &struct ev3_uart_view_ops
 * with the core (ev3_uart_core.h) and is called only through them.
 */
#ifndef _EV3_UART_VIEWS_H
#define _EV3_UART_VIEWS_H

#include <linux/kconfig.h>

/* ev3_uart_class.c: the lego-sensor class, which can be left out */
#if IS_ENABLED(CONFIG_LEGO_EV3_UART_CLASS)
int ev3_uart_class_init(void);
void ev3_uart_class_exit(void);
#else
static inline int ev3_uart_class_init(void)
{
	return 0;
}

static inline void ev3_uart_class_exit(void)
{
}
#endif

/* ev3_uart_leds.c: Powered Up lights, when the LED class is reachable */
#if IS_REACHABLE(CONFIG_LEDS_CLASS)
int ev3_uart_leds_init(void);
void ev3_uart_leds_exit(void);
#else
static inline int ev3_uart_leds_init(void)
{
	return 0;
}

static inline void ev3_uart_leds_exit(void)
{
}
#endif

/* ev3_uart_iio.c */
int ev3_uart_iio_init(void);
void ev3_uart_iio_exit(void);

#endif /* _EV3_UART_VIEWS_H */
