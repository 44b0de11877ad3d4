// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: sysfs attributes of /sys/class/lego-nxt/nxtN
 * (Documentation/ABI/testing/sysfs-class-lego-nxt), whatever the link.
 *
 * The attributes are world-readable, /dev/nxtN is not: reading them sends
 * nothing to the brick. Each shows what the brick said in its last reply to
 * GetVersions, GetDeviceInfo or GetBatteryLevel that passed through the
 * driver, whoever asked (the users of /dev/nxtN; the driver never asks by
 * itself), and fails with ENODATA while no such reply has come (or, for the
 * GetDeviceInfo values, since a command that may change them was sent).
 * A show() never waits for the brick, so none holds up an unplug or an
 * unbind, which wait for the running show()s before disconnect().
 */
#include <linux/device.h>
#include <linux/spinlock.h>
#include <linux/sysfs.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_views.h"

enum nxt_attr {
	NXT_ATTR_BATTERY,
	NXT_ATTR_FIRMWARE,
	NXT_ATTR_PROTOCOL,
	NXT_ATTR_NAME,
	NXT_ATTR_BT_ADDRESS,
	NXT_ATTR_FREE_FLASH,
};

static ssize_t nxt_attr_show(struct device *dev, char *buf, enum nxt_attr which)
{
	struct nxt_brick *b = dev_get_drvdata(dev);
	struct nxt_brick_info info;

	nxt_brick_info(b, &info);

	switch (which) {
	case NXT_ATTR_BATTERY:
		if (!info.have_battery)
			return -ENODATA;
		return sysfs_emit(buf, "%u\n", info.battery_mv);
	case NXT_ATTR_FIRMWARE:
		if (!info.have_versions)
			return -ENODATA;
		return sysfs_emit(buf, "%u.%02u\n", info.firmware[0], info.firmware[1]);
	case NXT_ATTR_PROTOCOL:
		if (!info.have_versions)
			return -ENODATA;
		return sysfs_emit(buf, "%u.%u\n", info.protocol[0], info.protocol[1]);
	case NXT_ATTR_NAME:
		if (!info.have_device)
			return -ENODATA;
		return sysfs_emit(buf, "%s\n", info.device.name);
	case NXT_ATTR_BT_ADDRESS:
		if (!info.have_device)
			return -ENODATA;
		return sysfs_emit(buf, "%pM\n", info.device.bt_address);
	case NXT_ATTR_FREE_FLASH:
		if (!info.have_device)
			return -ENODATA;
		return sysfs_emit(buf, "%u\n", info.device.free_flash);
	}
	return -EINVAL;
}

#define NXT_ATTR_RO(_name, _which)					\
static ssize_t _name##_show(struct device *dev,				\
			    struct device_attribute *attr, char *buf)	\
{									\
	return nxt_attr_show(dev, buf, _which);				\
}									\
static DEVICE_ATTR_RO(_name)

NXT_ATTR_RO(battery_mv, NXT_ATTR_BATTERY);
NXT_ATTR_RO(firmware_version, NXT_ATTR_FIRMWARE);
NXT_ATTR_RO(protocol_version, NXT_ATTR_PROTOCOL);
NXT_ATTR_RO(brick_name, NXT_ATTR_NAME);
NXT_ATTR_RO(bt_address, NXT_ATTR_BT_ADDRESS);
NXT_ATTR_RO(free_flash, NXT_ATTR_FREE_FLASH);

static LEGO_ATTR_CONST struct attribute *LEGO_ATTR_CONST nxt_attrs[] = {
	&dev_attr_battery_mv.attr,
	&dev_attr_firmware_version.attr,
	&dev_attr_protocol_version.attr,
	&dev_attr_brick_name.attr,
	&dev_attr_bt_address.attr,
	&dev_attr_free_flash.attr,
	NULL
};

static const struct attribute_group nxt_group = {
	.LEGO_GROUP_ATTRS = nxt_attrs,
};

const struct attribute_group *nxt_groups[] = {
	&nxt_group,
	NULL
};
