// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: sysfs attributes of the bound interface
 * (Documentation/ABI/testing/sysfs-driver-lego-nxt-usb).
 *
 * Each attribute is read from the brick when it is shown, through the same
 * transaction slot as everything else, and cached: the versions until the
 * next USB reset, the battery voltage and GetDeviceInfo's values for a
 * second. GetDeviceInfo's values are also read again after a system command
 * that may change them (SetBrickName, file writes and deletions) went
 * through the char device.
 *
 * The attributes are world-readable, /dev/nxtN is not: whoever reads them,
 * and however often, the brick gets at most one query of each kind a second
 * from them. A failure is cached for a second too, so that a brick that
 * does not answer is not asked again and again; only a query interrupted
 * by a signal is not.
 */
#include <linux/device.h>
#include <linux/jiffies.h>
#include <linux/slab.h>
#include <linux/sysfs.h>
#include <linux/usb.h>

#include "lego_compat.h"
#include "nxt_proto.h"
#include "nxt_usb.h"

#define NXT_INFO_MAX_AGE	HZ

/**
 * nxt_info_init() - set up an empty cache
 * @info: the cache
 */
void nxt_info_init(struct nxt_info *info)
{
	memset(info, 0, sizeof(*info));
	mutex_init(&info->lock);
}

/**
 * nxt_info_invalidate() - forget the cached values
 * @info: the cache
 * @all: the versions too (after a reset)
 *
 * Takes no lock, so it can be called with the brick's @io_mutex held.
 */
void nxt_info_invalidate(struct nxt_info *info, bool all)
{
	WRITE_ONCE(info->device_valid, false);
	WRITE_ONCE(info->battery_valid, false);
	if (all)
		WRITE_ONCE(info->versions_valid, false);
}

/**
 * nxt_info_telegram_sent() - note a telegram a user sent to the brick
 * @info: the cache
 * @tg: the telegram
 *
 * System commands that can change the brick's name or free flash make the
 * next read of those attributes ask the brick again.
 */
void nxt_info_telegram_sent(struct nxt_info *info, const u8 *tg)
{
	if ((tg[0] & ~0x80) != NXT_SYSTEM_CMD)
		return;
	switch (tg[1]) {
	case 0x81:	/* OpenWrite */
	case 0x83:	/* Write */
	case 0x85:	/* Delete */
	case 0x89:	/* OpenWriteLinear */
	case 0x8b:	/* OpenWriteData */
	case 0x8c:	/* OpenAppendData */
	case 0x98:	/* SetBrickName */
	case 0xa0:	/* DeleteUserFlash */
		WRITE_ONCE(info->device_valid, false);
		break;
	}
}

/* Whether a result taken at @when (64-bit jiffies) is less than a second old. */
static bool nxt_info_fresh(bool valid, u64 when)
{
	return valid && nxt_time_fresh(get_jiffies_64(), when, NXT_INFO_MAX_AGE);
}

/* Whether a query's failure says something about the brick: if so, cache it. */
static bool nxt_info_cacheable(int err)
{
	return err != -ERESTARTSYS && err != -EINTR && err != -ENOMEM;
}

/* Sends @tg and checks the reply's status. @info->lock held. */
static int nxt_info_query(struct nxt_usb *nxt, struct nxt_xfer *x,
			  const u8 *tg, size_t len)
{
	int ret;

	ret = nxt_transact(nxt, x, tg, len, NXT_TIMEOUT_DEFAULT_MS, false);
	if (ret)
		return ret;
	return nxt_status_to_errno(x->reply[2]);
}

static int nxt_info_read_versions(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	static const u8 tg[] = { NXT_SYSTEM_CMD, NXT_GET_VERSIONS };
	struct nxt_info *info = &nxt->info;
	int ret;

	/* Read once per reset; a failure is kept for a second. */
	if (READ_ONCE(info->versions_valid) &&
	    (!info->versions_err || nxt_info_fresh(true, info->versions_time)))
		return info->versions_err;
	ret = nxt_info_query(nxt, x, tg, sizeof(tg));
	if (!ret)
		ret = nxt_decode_versions(x->reply, x->reply_len, info->protocol,
					  info->firmware);
	if (nxt_info_cacheable(ret)) {
		info->versions_err = ret;
		info->versions_time = get_jiffies_64();
		WRITE_ONCE(info->versions_valid, true);
	}
	return ret;
}

static int nxt_info_read_device(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	static const u8 tg[] = { NXT_SYSTEM_CMD, NXT_GET_DEVICE_INFO };
	struct nxt_info *info = &nxt->info;
	int ret;

	if (nxt_info_fresh(READ_ONCE(info->device_valid), info->device_time))
		return info->device_err;
	ret = nxt_info_query(nxt, x, tg, sizeof(tg));
	if (!ret)
		ret = nxt_decode_device_info(x->reply, x->reply_len, &info->device);
	if (nxt_info_cacheable(ret)) {
		info->device_err = ret;
		info->device_time = get_jiffies_64();
		WRITE_ONCE(info->device_valid, true);
	}
	return ret;
}

static int nxt_info_read_battery(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	const struct nxt_command *cmd = nxt_command_find(NXT_IOC_GET_BATTERY_LEVEL);
	struct nxt_info *info = &nxt->info;
	struct nxt_battery battery = { };
	u8 tg[NXT_TELEGRAM_MAX];
	int ret, len;

	if (nxt_info_fresh(READ_ONCE(info->battery_valid), info->battery_time))
		return info->battery_err;
	len = nxt_command_encode(cmd, &battery, tg);
	if (len < 0)
		return len;
	ret = nxt_info_query(nxt, x, tg, len);
	if (!ret)
		ret = nxt_command_decode(cmd, x->reply, x->reply_len, &battery);
	if (!ret)
		info->battery = battery.millivolts;
	if (nxt_info_cacheable(ret)) {
		info->battery_err = ret;
		info->battery_time = get_jiffies_64();
		WRITE_ONCE(info->battery_valid, true);
	}
	return ret;
}

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
	struct nxt_usb *nxt = usb_get_intfdata(to_usb_interface(dev));
	struct nxt_info *info = &nxt->info;
	struct nxt_xfer *x;
	int ret;

	x = kzalloc(sizeof(*x), GFP_KERNEL);
	if (!x)
		return -ENOMEM;
	if (mutex_lock_interruptible(&info->lock)) {
		kfree(x);
		return -ERESTARTSYS;
	}

	switch (which) {
	case NXT_ATTR_BATTERY:
		ret = nxt_info_read_battery(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%u\n", info->battery);
		break;
	case NXT_ATTR_FIRMWARE:
		ret = nxt_info_read_versions(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%u.%02u\n", info->firmware[0], info->firmware[1]);
		break;
	case NXT_ATTR_PROTOCOL:
		ret = nxt_info_read_versions(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%u.%u\n", info->protocol[0], info->protocol[1]);
		break;
	case NXT_ATTR_NAME:
		ret = nxt_info_read_device(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%s\n", info->device.name);
		break;
	case NXT_ATTR_BT_ADDRESS:
		ret = nxt_info_read_device(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%pM\n", info->device.bt_address);
		break;
	case NXT_ATTR_FREE_FLASH:
		ret = nxt_info_read_device(nxt, x);
		if (!ret)
			ret = sysfs_emit(buf, "%u\n", info->device.free_flash);
		break;
	default:
		ret = -EINVAL;
	}

	mutex_unlock(&info->lock);
	kfree(x);
	return ret;
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
