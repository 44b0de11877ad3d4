// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: the lights of Powered Up devices as LED
 * class devices.
 *
 * A device whose handshake has a mode "LIGHT" that takes values (the SPIKE
 * colour sensor's three lights, the SPIKE ultrasonic sensor's four: see
 * ev3_uart_lump_lights()) gets one LED class device per light, named
 * "<sensor>:white:light-<n>" after the sensor's name ("sensor3", else its
 * driver name), with a max_brightness of 100 (percent). Setting one light
 * sends the brightness of all of them, the mode's values, through the
 * core (ev3_uart_set_mode_data()), which owns the write path; it may
 * sleep, so the LED core calls it from its work item for triggers.
 *
 * Without the LED class (CONFIG_LEDS_CLASS off, or a module while this
 * driver is built in) there is nothing here, and the sensors work as
 * before.
 */
#include <linux/kernel.h>

#include "lego_compat.h"
#include "ev3_uart_core.h"
#include "ev3_uart_views.h"

#if IS_REACHABLE(CONFIG_LEDS_CLASS)

#include <linux/leds.h>
#include <linux/mutex.h>
#include <linux/slab.h>

/* "<sensor name>:white:light-<n>" */
#define EV3_UART_LED_NAME_LEN	(EV3_UART_DEV_NAME_LEN + 16)

/**
 * struct ev3_uart_led - one light
 * @cdev: its LED class device
 * @leds: the sensor's lights
 * @index: which value of the mode it is
 * @name: the LED device's name
 */
struct ev3_uart_led {
	struct led_classdev cdev;
	struct ev3_uart_leds *leds;
	unsigned int index;
	char name[EV3_UART_LED_NAME_LEN];
};

/**
 * struct ev3_uart_leds - the lights of one sensor
 * @sd: the sensor; valid until ev3_uart_leds_remove() returns
 * @lock: serialises writes, and protects @brightness
 * @mode: the mode whose values are the lights' brightness
 * @num: the number of lights (and of values of @mode)
 * @registered: the LED devices registered so far
 * @brightness: the brightness of each light, as last set
 * @led: the lights
 */
struct ev3_uart_leds {
	struct ev3_uart_sensor_dev *sd;
	struct mutex lock;	/* one write at a time; @brightness */
	u8 mode;
	unsigned int num;
	unsigned int registered;
	s8 brightness[EV3_UART_MAX_LIGHTS];
	struct ev3_uart_led led[EV3_UART_MAX_LIGHTS];
};

static int ev3_uart_led_set(struct led_classdev *cdev,
			    enum led_brightness value)
{
	struct ev3_uart_led *led = container_of(cdev, struct ev3_uart_led, cdev);
	struct ev3_uart_leds *leds = led->leds;
	int ret;

	mutex_lock(&leds->lock);
	leds->brightness[led->index] = min_t(unsigned int, value,
					     EV3_UART_LIGHT_MAX);
	ret = ev3_uart_set_mode_data(leds->sd, leds->mode,
				     (const u8 *)leds->brightness, leds->num);
	mutex_unlock(&leds->lock);
	/* A sensor that is gone took its lights with it: nothing to report. */
	return ret == -ENODEV ? 0 : ret;
}

static void ev3_uart_leds_unregister(struct ev3_uart_leds *leds)
{
	while (leds->registered)
		led_classdev_unregister(&leds->led[--leds->registered].cdev);
}

/*
 * A sensor completed its handshake: an LED device per light
 * (&ev3_uart_view_ops.add). A sensor whose lights cannot be registered
 * carries on without them: said in the log.
 */
static int ev3_uart_leds_add(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_leds *leds;
	unsigned int n, i;
	u8 mode;
	int ret;

	n = ev3_uart_lump_lights(&sd->desc, &mode);
	if (!n)
		return 0;
	leds = kzalloc_obj(*leds, GFP_KERNEL);
	if (!leds) {
		pr_warn("%s: %s: no LED devices: %d\n", sd->address,
			ev3_uart_sensor_name(sd), -ENOMEM);
		return 0;
	}
	leds->sd = sd;
	leds->mode = mode;
	leds->num = n;
	mutex_init(&leds->lock);
	for (i = 0; i < n; i++) {
		struct ev3_uart_led *led = &leds->led[i];

		led->leds = leds;
		led->index = i;
		snprintf(led->name, sizeof(led->name), "%s:white:light-%u",
			 ev3_uart_sensor_name(sd), i);
		led->cdev.name = led->name;
		led->cdev.max_brightness = EV3_UART_LIGHT_MAX;
		led->cdev.brightness_set_blocking = ev3_uart_led_set;
		/* Unregistered when the sensor is gone: no write to turn it off. */
		led->cdev.flags = LED_RETAIN_AT_SHUTDOWN;
		ret = led_classdev_register(sd->port->parent, &led->cdev);
		if (ret) {
			pr_warn("%s: %s: no LED devices: %d\n", sd->address,
				ev3_uart_sensor_name(sd), ret);
			ev3_uart_leds_unregister(leds);
			mutex_destroy(&leds->lock);
			kfree(leds);
			return 0;
		}
		leds->registered++;
	}
	sd->leds = leds;
	return 0;
}

/*
 * The sensor is gone: remove its LED devices (&ev3_uart_view_ops.remove).
 * They are not turned off (LED_RETAIN_AT_SHUTDOWN: there is no device to
 * write to); unregistering one waits for the LED core's work item, whose
 * write fails at once.
 */
static void ev3_uart_leds_remove(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_leds *leds = sd->leds;

	if (!leds)
		return;
	ev3_uart_leds_unregister(leds);
	sd->leds = NULL;
	mutex_destroy(&leds->lock);
	kfree(leds);
}

static const struct ev3_uart_view_ops ev3_uart_leds_view = {
	.add	= ev3_uart_leds_add,
	.remove	= ev3_uart_leds_remove,
};

/**
 * ev3_uart_leds_init() - register the LED view with the core
 *
 * Return: 0 or the core's error.
 */
int ev3_uart_leds_init(void)
{
	return ev3_uart_view_register(&ev3_uart_leds_view);
}

/**
 * ev3_uart_leds_exit() - unregister the LED view
 */
void ev3_uart_leds_exit(void)
{
	ev3_uart_view_unregister(&ev3_uart_leds_view);
}

#endif /* IS_REACHABLE(CONFIG_LEDS_CLASS) */
