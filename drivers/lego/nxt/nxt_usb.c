// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: USB char device.
 *
 * Binds the brick's vendor interface (0694:0002, interface 0) and registers
 * /dev/nxtN through the USB class. This file is the transport glue; telegram
 * validation lives in nxt_proto.c.
 *
 * Lifetime: struct nxt_usb is reference counted. probe() holds one reference
 * and every open file holds one; disconnect() clears @intf under @io_mutex so
 * that file operations still in flight see the brick is gone.
 */
#include <linux/kref.h>
#include <linux/module.h>
#include <linux/mutex.h>
#include <linux/slab.h>
#include <linux/usb.h>

#include "lego_compat.h"
#include "nxt_proto.h"

#define NXT_USB_VENDOR		0x0694
#define NXT_USB_PRODUCT		0x0002
/* Minors used when the kernel has no dynamic USB minors. */
#define NXT_USB_MINOR_BASE	240

/**
 * struct nxt_usb - one brick
 * @udev: the USB device, referenced while this structure lives
 * @intf: the bound interface, NULL once the brick is disconnected
 * @ep_out: bulk OUT endpoint number
 * @ep_in: bulk IN endpoint number
 * @io_mutex: serialises transactions; protects @intf against disconnect
 * @kref: references: probe() and each open file
 */
struct nxt_usb {
	struct usb_device *udev;
	struct usb_interface *intf;
	u8 ep_out;
	u8 ep_in;
	struct mutex io_mutex;	/* one transaction at a time; guards @intf */
	struct kref kref;
};

static struct usb_driver nxt_usb_driver;

static void nxt_usb_free(struct kref *kref)
{
	struct nxt_usb *nxt = container_of(kref, struct nxt_usb, kref);

	usb_put_dev(nxt->udev);
	kfree(nxt);
}

static int nxt_usb_open(struct inode *inode, struct file *file)
{
	struct usb_interface *intf;
	struct nxt_usb *nxt;

	intf = usb_find_interface(&nxt_usb_driver, iminor(inode));
	if (!intf)
		return -ENODEV;

	nxt = usb_get_intfdata(intf);
	if (!nxt)
		return -ENODEV;

	kref_get(&nxt->kref);
	file->private_data = nxt;
	return 0;
}

static int nxt_usb_release(struct inode *inode, struct file *file)
{
	struct nxt_usb *nxt = file->private_data;

	kref_put(&nxt->kref, nxt_usb_free);
	return 0;
}

static const struct file_operations nxt_usb_fops = {
	.owner		= THIS_MODULE,
	.open		= nxt_usb_open,
	.release	= nxt_usb_release,
	.llseek		= noop_llseek,
};

static struct usb_class_driver nxt_usb_class = {
	.name		= "nxt%d",
	.fops		= &nxt_usb_fops,
	.minor_base	= NXT_USB_MINOR_BASE,
};

static int nxt_usb_probe(struct usb_interface *intf,
			 const struct usb_device_id *id)
{
	struct usb_endpoint_descriptor *in, *out;
	struct nxt_usb *nxt;
	int ret;

	ret = usb_find_common_endpoints(intf->cur_altsetting, &in, &out,
					NULL, NULL);
	if (ret) {
		dev_err(&intf->dev, "no bulk endpoints\n");
		return ret;
	}

	nxt = kzalloc(sizeof(*nxt), GFP_KERNEL);
	if (!nxt)
		return -ENOMEM;

	kref_init(&nxt->kref);
	mutex_init(&nxt->io_mutex);
	nxt->udev = usb_get_dev(interface_to_usbdev(intf));
	nxt->intf = intf;
	nxt->ep_in = usb_endpoint_num(in);
	nxt->ep_out = usb_endpoint_num(out);
	usb_set_intfdata(intf, nxt);

	ret = usb_register_dev(intf, &nxt_usb_class);
	if (ret) {
		dev_err(&intf->dev, "cannot get a minor: %d\n", ret);
		usb_set_intfdata(intf, NULL);
		kref_put(&nxt->kref, nxt_usb_free);
		return ret;
	}

	dev_info(&intf->dev, "LEGO NXT brick now at nxt%d\n", intf->minor);
	return 0;
}

static void nxt_usb_disconnect(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	usb_deregister_dev(intf, &nxt_usb_class);

	mutex_lock(&nxt->io_mutex);
	nxt->intf = NULL;
	mutex_unlock(&nxt->io_mutex);

	usb_set_intfdata(intf, NULL);
	kref_put(&nxt->kref, nxt_usb_free);
}

/*
 * The brick's vendor interface is interface 0, class ff/ff/ff. Matching the
 * interface number keeps the driver off anything else sharing the ID.
 */
static const struct usb_device_id nxt_usb_ids[] = {
	{ USB_DEVICE_INTERFACE_NUMBER(NXT_USB_VENDOR, NXT_USB_PRODUCT, 0) },
	{ }
};
MODULE_DEVICE_TABLE(usb, nxt_usb_ids);

static struct usb_driver nxt_usb_driver = {
	.name		= "lego_nxt_usb",
	.probe		= nxt_usb_probe,
	.disconnect	= nxt_usb_disconnect,
	.id_table	= nxt_usb_ids,
};
module_usb_driver(nxt_usb_driver);

MODULE_DESCRIPTION("LEGO MINDSTORMS NXT brick USB driver");
MODULE_LICENSE("GPL");
