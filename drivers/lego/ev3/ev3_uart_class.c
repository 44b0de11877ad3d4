// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: the lego-sensor class.
 *
 * /sys/class/lego-sensor/sensorN with the attributes, formats and errors of
 * ev3dev's lego-sensor ABI, so that programs written for ev3dev (such as
 * python-ev3dev2) work unchanged. See
 * Documentation/ABI/testing/sysfs-class-lego-sensor.
 */
#include <linux/device.h>
#include <linux/idr.h>
#include <linux/jiffies.h>
#include <linux/kernel.h>
#include <linux/kobject.h>
#include <linux/slab.h>
#include <linux/string.h>
#include <linux/sysfs.h>

#include "lego_compat.h"
#include "ev3_uart_core.h"
#include "ev3_uart_chan.h"
#include "ev3_uart_views.h"

#define EV3_UART_NUM_VALUES	8

/**
 * struct ev3_uart_class_dev - a sensor in the lego-sensor class
 * @dev: its class device, sensorN
 * @sd: the sensor (a reference, dropped when @dev is released)
 * @id: N
 * @mode_work: sends the uevent for a mode change (uevents may sleep)
 */
struct ev3_uart_class_dev {
	struct device dev;
	struct ev3_uart_sensor_dev *sd;
	int id;
	struct work_struct mode_work;
};

static DEFINE_IDA(ev3_uart_sensor_ida);

static struct ev3_uart_sensor_dev *to_sensor(struct device *dev)
{
	return container_of(dev, struct ev3_uart_class_dev, dev)->sd;
}

static const struct ev3_uart_mode *current_mode(struct ev3_uart_sensor_dev *sd,
						u8 *data, int *len)
{
	u8 buf[EV3_UART_MAX_PAYLOAD], mode;
	int n;

	/* The values wait until they can be trusted; the mode's fields not. */
	n = data ? ev3_uart_get_values(sd, &mode, data) :
		   ev3_uart_get_data(sd, &mode, buf);
	if (n < 0)
		return ERR_PTR(n);
	if (len)
		*len = n;
	return &sd->desc.modes[mode];
}

static const char * const ev3_uart_bin_formats[] = {
	[EV3_UART_DATA_S8] = "s8",
	[EV3_UART_DATA_S16] = "s16",
	[EV3_UART_DATA_S32] = "s32",
	[EV3_UART_DATA_FLOAT] = "float",
};

enum ev3_mode_field {
	EV3_FIELD_NUM_VALUES,
	EV3_FIELD_DECIMALS,
	EV3_FIELD_UNITS,
	EV3_FIELD_BIN_FORMAT,
};

/* Show one property of the current mode. */
static ssize_t mode_field_show(struct device *dev, char *buf,
			       enum ev3_mode_field field)
{
	const struct ev3_uart_mode *m = current_mode(to_sensor(dev), NULL, NULL);

	if (IS_ERR(m))
		return PTR_ERR(m);
	switch (field) {
	case EV3_FIELD_NUM_VALUES:
		return sysfs_emit(buf, "%u\n", m->num_values);
	case EV3_FIELD_DECIMALS:
		return sysfs_emit(buf, "%u\n", m->decimals);
	case EV3_FIELD_UNITS:
		return sysfs_emit(buf, "%s\n", m->units);
	case EV3_FIELD_BIN_FORMAT:
		return sysfs_emit(buf, "%s\n", ev3_uart_bin_formats[m->data_type]);
	}
	return -EINVAL;
}

static ssize_t address_show(struct device *dev, struct device_attribute *attr,
			    char *buf)
{
	return sysfs_emit(buf, "%s\n", to_sensor(dev)->address);
}
static DEVICE_ATTR_RO(address);

static ssize_t driver_name_show(struct device *dev,
				struct device_attribute *attr, char *buf)
{
	return sysfs_emit(buf, "%s\n", to_sensor(dev)->driver_name);
}
static DEVICE_ATTR_RO(driver_name);

static ssize_t modes_show(struct device *dev, struct device_attribute *attr,
			  char *buf)
{
	return ev3_uart_show_modes(to_sensor(dev), buf);
}
static DEVICE_ATTR_RO(modes);

static ssize_t mode_show(struct device *dev, struct device_attribute *attr,
			 char *buf)
{
	return ev3_uart_show_mode(to_sensor(dev), buf);
}

static ssize_t mode_store(struct device *dev, struct device_attribute *attr,
			  const char *buf, size_t count)
{
	int ret = ev3_uart_set_mode_by_name(to_sensor(dev), buf);

	return ret ? ret : count;
}
static DEVICE_ATTR_RW(mode);

/* The modes that take values from the host (Powered Up devices only). */
static ssize_t mode_data_show(struct device *dev, struct device_attribute *attr,
			      char *buf)
{
	struct ev3_uart_sensor_dev *sd = to_sensor(dev);
	char tok[EV3_UART_TOKEN_LEN + 1];
	int i, len = 0;

	for (i = 0; i < sd->desc.num_modes; i++) {
		if (ev3_uart_lump_data_len(&sd->desc, i) < 0 ||
		    ev3_uart_mode_token(&sd->desc, i, tok, sizeof(tok)) < 0)
			continue;
		len += sysfs_emit_at(buf, len, "%s%s", len ? " " : "", tok);
	}
	return len + sysfs_emit_at(buf, len, "\n");
}

/* "MODE V0 V1 ...": the values sent to the mode (ev3_uart_set_mode_data()). */
static ssize_t mode_data_store(struct device *dev, struct device_attribute *attr,
			       const char *buf, size_t count)
{
	struct ev3_uart_sensor_dev *sd = to_sensor(dev);
	u8 data[EV3_UART_MAX_PAYLOAD];
	s32 v[EV3_UART_MAX_PAYLOAD];
	char *copy, *p, *t;
	int mode, ret;
	unsigned int n = 0;

	copy = kstrndup(buf, count, GFP_KERNEL);
	if (!copy)
		return -ENOMEM;
	p = strim(copy);
	t = strsep(&p, " ");
	mode = ev3_uart_find_mode(&sd->desc, t);
	ret = min(mode, 0);
	while (!ret && p) {
		t = strsep(&p, " ");
		if (!*t)
			continue;
		ret = n < ARRAY_SIZE(v) ? kstrtos32(t, 0, &v[n++]) : -EINVAL;
	}
	if (!ret)
		ret = ev3_uart_pack_values(&sd->desc, mode, v, n, data);
	if (ret > 0)
		ret = ev3_uart_set_mode_data(sd, mode, data, ret);
	kfree(copy);
	return ret ? ret : count;
}
static DEVICE_ATTR_RW(mode_data);

static ssize_t commands_show(struct device *dev, struct device_attribute *attr,
			     char *buf)
{
	return sysfs_emit(buf, "\n");
}
static DEVICE_ATTR_RO(commands);

/* No EV3 UART sensor has commands: every command is invalid. */
static ssize_t command_store(struct device *dev, struct device_attribute *attr,
			     const char *buf, size_t count)
{
	return -EINVAL;
}
static DEVICE_ATTR_WO(command);

static ssize_t num_values_show(struct device *dev,
			       struct device_attribute *attr, char *buf)
{
	return mode_field_show(dev, buf, EV3_FIELD_NUM_VALUES);
}
static DEVICE_ATTR_RO(num_values);

static ssize_t decimals_show(struct device *dev, struct device_attribute *attr,
			     char *buf)
{
	return mode_field_show(dev, buf, EV3_FIELD_DECIMALS);
}
static DEVICE_ATTR_RO(decimals);

static ssize_t units_show(struct device *dev, struct device_attribute *attr,
			  char *buf)
{
	return mode_field_show(dev, buf, EV3_FIELD_UNITS);
}
static DEVICE_ATTR_RO(units);

static ssize_t bin_data_format_show(struct device *dev,
				    struct device_attribute *attr, char *buf)
{
	return mode_field_show(dev, buf, EV3_FIELD_BIN_FORMAT);
}
static DEVICE_ATTR_RO(bin_data_format);

/* Only I2C sensors can be polled: not supported, as on ev3dev. */
static ssize_t poll_ms_show(struct device *dev, struct device_attribute *attr,
			    char *buf)
{
	return -EOPNOTSUPP;
}

static ssize_t poll_ms_store(struct device *dev, struct device_attribute *attr,
			     const char *buf, size_t count)
{
	return -EOPNOTSUPP;
}
static DEVICE_ATTR_RW(poll_ms);

/* A Powered Up device's VERSION; EV3 sensors send none. */
static ssize_t fw_version_show(struct device *dev,
			       struct device_attribute *attr, char *buf)
{
	struct ev3_uart_sensor_dev *sd = to_sensor(dev);
	char ver[EV3_UART_VERSION_LEN + 1] = "";

	if (sd->desc.fw_version &&
	    ev3_uart_version_string(sd->desc.fw_version, ver, sizeof(ver)) < 0)
		return -EINVAL;
	return sysfs_emit(buf, "%s\n", ver);
}
static DEVICE_ATTR_RO(fw_version);

static ssize_t text_value_show(struct device *dev,
			       struct device_attribute *attr, char *buf)
{
	return -EOPNOTSUPP;
}
static DEVICE_ATTR_RO(text_value);

/**
 * struct ev3_value_attr - one of value0 .. value7
 * @attr: the sysfs attribute
 * @index: which value of the DATA message it shows
 */
struct ev3_value_attr {
	struct device_attribute attr;
	unsigned int index;
};

static ssize_t value_show(struct device *dev, struct device_attribute *attr,
			  char *buf)
{
	struct ev3_value_attr *va = container_of(attr, struct ev3_value_attr, attr);
	u8 data[EV3_UART_MAX_PAYLOAD];
	const struct ev3_uart_mode *m;
	int len, ret;
	s32 v;

	m = current_mode(to_sensor(dev), data, &len);
	if (IS_ERR(m))
		return PTR_ERR(m);
	if (va->index >= m->num_values)
		return -ENXIO;
	/* Before the first DATA message the values read as zero. */
	ret = ev3_uart_read_value(m, data, EV3_UART_MAX_PAYLOAD, va->index, &v);
	if (ret)
		return ret;
	return sysfs_emit(buf, "%d\n", ev3_uart_scale_value(m, v));
}

#define EV3_VALUE_ATTR(n) \
	static struct ev3_value_attr ev3_value##n = { \
		.attr = __ATTR(value##n, 0444, value_show, NULL), \
		.index = n, \
	}

EV3_VALUE_ATTR(0);
EV3_VALUE_ATTR(1);
EV3_VALUE_ATTR(2);
EV3_VALUE_ATTR(3);
EV3_VALUE_ATTR(4);
EV3_VALUE_ATTR(5);
EV3_VALUE_ATTR(6);
EV3_VALUE_ATTR(7);

static ssize_t bin_data_read(struct file *file, struct kobject *kobj,
			     LEGO_BIN_ATTR *attr, char *buf,
			     loff_t off, size_t count)
{
	struct ev3_uart_sensor_dev *sd = to_sensor(kobj_to_dev(kobj));
	u8 data[EV3_UART_MAX_PAYLOAD];
	const struct ev3_uart_mode *m;

	m = current_mode(sd, data, NULL);
	if (IS_ERR(m))
		return PTR_ERR(m);
	if (off >= EV3_UART_MAX_PAYLOAD)
		return 0;
	count = min_t(size_t, count, EV3_UART_MAX_PAYLOAD - off);
	memcpy(buf, data + off, count);
	return count;
}
static BIN_ATTR_RO(bin_data, EV3_UART_MAX_PAYLOAD);

static ssize_t direct_read(struct file *file, struct kobject *kobj,
			   LEGO_BIN_ATTR *attr, char *buf,
			   loff_t off, size_t count)
{
	return -EOPNOTSUPP;
}

/* A write sends the bytes to the sensor in one WRITE message. */
static ssize_t direct_write(struct file *file, struct kobject *kobj,
			    LEGO_BIN_ATTR *attr, char *buf,
			    loff_t off, size_t count)
{
	int ret;

	if (off)
		return -EINVAL;
	ret = ev3_uart_write(to_sensor(kobj_to_dev(kobj)), buf, count);
	return ret ? ret : count;
}
static BIN_ATTR_RW(direct, 255);

static LEGO_ATTR_CONST struct attribute *LEGO_ATTR_CONST ev3_uart_sensor_attrs[] = {
	&dev_attr_address.attr,
	&dev_attr_driver_name.attr,
	&dev_attr_modes.attr,
	&dev_attr_mode.attr,
	&dev_attr_mode_data.attr,
	&dev_attr_commands.attr,
	&dev_attr_command.attr,
	&dev_attr_num_values.attr,
	&dev_attr_decimals.attr,
	&dev_attr_units.attr,
	&dev_attr_bin_data_format.attr,
	&dev_attr_poll_ms.attr,
	&dev_attr_fw_version.attr,
	&dev_attr_text_value.attr,
	&ev3_value0.attr.attr,
	&ev3_value1.attr.attr,
	&ev3_value2.attr.attr,
	&ev3_value3.attr.attr,
	&ev3_value4.attr.attr,
	&ev3_value5.attr.attr,
	&ev3_value6.attr.attr,
	&ev3_value7.attr.attr,
	NULL
};

static LEGO_BIN_ATTR *LEGO_BIN_ATTR_CONST ev3_uart_sensor_bin_attrs[] = {
	&bin_attr_bin_data,
	&bin_attr_direct,
	NULL
};

static const struct attribute_group ev3_uart_sensor_group = {
	.LEGO_GROUP_ATTRS = ev3_uart_sensor_attrs,
	.bin_attrs = ev3_uart_sensor_bin_attrs,
};

static const struct attribute_group *ev3_uart_sensor_groups[] = {
	&ev3_uart_sensor_group,
	NULL
};

static int ev3_uart_sensor_uevent(LEGO_UEVENT_CONST struct device *dev,
				  struct kobj_uevent_env *env)
{
	const struct ev3_uart_sensor_dev *sd =
		container_of(dev, struct ev3_uart_class_dev, dev)->sd;
	int ret;

	ret = add_uevent_var(env, "LEGO_DRIVER_NAME=%s", sd->driver_name);
	if (ret)
		return ret;
	return add_uevent_var(env, "LEGO_ADDRESS=%s", sd->address);
}

static LEGO_CLASS_CONST struct class lego_sensor_class = {
	.name = "lego-sensor",
	.dev_groups = ev3_uart_sensor_groups,
	.dev_uevent = ev3_uart_sensor_uevent,
};

static void ev3_uart_class_release(struct device *dev)
{
	struct ev3_uart_class_dev *cd = container_of(dev, struct ev3_uart_class_dev, dev);

	ida_free(&ev3_uart_sensor_ida, cd->id);
	ev3_uart_sensor_put(cd->sd);
	kfree(cd);
}

static void ev3_uart_class_mode_work(struct work_struct *work)
{
	struct ev3_uart_class_dev *cd = container_of(work, struct ev3_uart_class_dev,
						     mode_work);

	kobject_uevent(&cd->dev.kobj, KOBJ_CHANGE);
}

/* A sensor completed its handshake: sensorN in the class. */
static int ev3_uart_class_add(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_class_dev *cd;
	int ret;

	cd = kzalloc_obj(*cd, GFP_KERNEL);
	if (!cd)
		return -ENOMEM;
	cd->id = ida_alloc(&ev3_uart_sensor_ida, GFP_KERNEL);
	if (cd->id < 0) {
		ret = cd->id;
		kfree(cd);
		return ret;
	}
	ev3_uart_sensor_get(sd);
	cd->sd = sd;
	INIT_WORK(&cd->mode_work, ev3_uart_class_mode_work);

	device_initialize(&cd->dev);
	cd->dev.class = &lego_sensor_class;
	cd->dev.parent = sd->port->parent;
	cd->dev.release = ev3_uart_class_release;
	ret = dev_set_name(&cd->dev, "sensor%d", cd->id);
	if (!ret)
		ret = device_add(&cd->dev);
	if (ret) {
		put_device(&cd->dev);
		return ret;
	}
	strscpy(sd->name, dev_name(&cd->dev), sizeof(sd->name));
	sd->cls = cd;
	return 0;
}

/* Under the port lock: the uevent goes from a work item. */
static void ev3_uart_class_mode_changed(struct ev3_uart_sensor_dev *sd)
{
	schedule_work(&sd->cls->mode_work);
}

/*
 * The sensor is gone: no mode change can queue the uevent any more. Waits
 * for sysfs callbacks in flight; the memory goes with the last reference
 * to the device.
 */
static void ev3_uart_class_remove(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_class_dev *cd = sd->cls;

	cancel_work_sync(&cd->mode_work);
	device_unregister(&cd->dev);
}

static const struct ev3_uart_view_ops ev3_uart_class_view = {
	.add		= ev3_uart_class_add,
	.remove		= ev3_uart_class_remove,
	.mode_changed	= ev3_uart_class_mode_changed,
};

/**
 * ev3_uart_class_init() - register the lego-sensor class and its view
 *
 * Return: 0 or the class registration error (-%EEXIST if another driver,
 * such as ev3dev's own, registered it first).
 */
int ev3_uart_class_init(void)
{
	int ret = class_register(&lego_sensor_class);

	if (ret)
		return ret;
	ret = ev3_uart_view_register(&ev3_uart_class_view);
	if (ret)
		class_unregister(&lego_sensor_class);
	return ret;
}

/**
 * ev3_uart_class_exit() - unregister the view and the class
 */
void ev3_uart_class_exit(void)
{
	ev3_uart_view_unregister(&ev3_uart_class_view);
	class_unregister(&lego_sensor_class);
}
