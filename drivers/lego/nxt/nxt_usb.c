// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: USB transport.
 *
 * Binds the brick's vendor interface (0694:0002, interface 0), keeps a
 * 64-byte IN transfer pending to collect replies while the brick is open,
 * and sends telegrams for the transaction engine (nxt_core.c), which it
 * tells about every packet, completion and error. The engine owns the
 * transactions, their timeouts and the drain of late replies.
 *
 * What the firmware does on USB and why it matters here:
 *
 *  - it handles one OUT packet as one command, about one per millisecond;
 *  - it writes each reply into its IN FIFO and then busy-waits, up to about
 *    500 ms with the whole brick frozen, for the host to collect it. An
 *    uncollected reply stays queued (the endpoint is double-buffered) and
 *    comes out later in front of newer ones, which is how host tools lose
 *    track of which reply answers what. Keeping an IN transfer pending
 *    avoids the freeze, and anything that arrives while no reply is awaited
 *    is dropped;
 *  - it never sends a zero-length packet after a full 64-byte reply, so IN
 *    transfers are exactly one packet long.
 */
#include <linux/errno.h>
#include <linux/jiffies.h>
#include <linux/limits.h>
#include <linux/module.h>
#include <linux/slab.h>
#include <linux/string.h>
#include <linux/usb.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_views.h"
#include "nxt_usb_trace.h"

#define NXT_USB_VENDOR		0x0694
#define NXT_USB_PRODUCT		0x0002
/* Restart delay of the reader after a transfer error other than a stall. */
#define NXT_RECOVER_MS		10
/* How long suspend() lets the transaction in flight finish. */
#define NXT_SUSPEND_WAIT_MS	1000

/**
 * struct nxt_usb - one brick on USB
 * @brick: the brick, for the engine and the views
 * @udev: the USB device, referenced while this structure lives
 * @intf: the bound interface; NULL once disconnected (@brick.tx_lock)
 * @out_pipe: bulk OUT pipe (endpoint 0x01 on a LEGO brick)
 * @in_pipe: bulk IN pipe (endpoint 0x82)
 * @reader_wanted: a file is open: the reader runs when not suspended
 *	(@brick.tx_lock)
 * @reader_running: @in_urb is submitted (@brick.lock)
 * @in_urb: the reader's URB
 * @in_buf: its 64-byte buffer
 * @out_anchor: telegrams in flight, killed on disconnect, reset, suspend
 * @recover_work: clears a halted endpoint and restarts the reader; sending a
 *	telegram does the same first (nxt_usb_start())
 * @halted_in: the IN endpoint stalled (@brick.lock)
 * @halted_out: the OUT endpoint stalled (@brick.lock)
 * @stalls: IN stalls in a row, with no packet in between (@brick.lock)
 *
 * @brick.tx_lock serialises every URB submission from process context
 * against disconnect, reset and suspend, and is held from pre_reset() to
 * post_reset(); @brick.lock is taken in the URB completions.
 */
struct nxt_usb {
	struct nxt_brick brick;
	struct usb_device *udev;
	struct usb_interface *intf;
	unsigned int out_pipe;
	unsigned int in_pipe;
	bool reader_wanted;
	bool reader_running;
	struct urb *in_urb;
	u8 *in_buf;
	struct usb_anchor out_anchor;
	struct delayed_work recover_work;
	bool halted_in;
	bool halted_out;
	u8 stalls;
};

static struct nxt_usb *to_nxt_usb(struct nxt_brick *b)
{
	return container_of(b, struct nxt_usb, brick);
}

/*
 * When to restart the reader after a transfer error: after a stall, as
 * nxt_stall_backoff_ms() says (at once the first time, later when the
 * endpoint stalls again and again); NXT_RECOVER_MS after other errors.
 * @brick.lock held.
 */
static unsigned long nxt_recover_delay(struct nxt_usb *nxt)
{
	lockdep_assert_held(&nxt->brick.lock);
	if (!nxt->halted_in)
		return msecs_to_jiffies(NXT_RECOVER_MS);
	return msecs_to_jiffies(nxt_stall_backoff_ms(nxt->stalls));
}

/* The IN endpoint stalled. @brick.lock held. */
static void nxt_in_stalled(struct nxt_usb *nxt)
{
	dev_warn_ratelimited(&nxt->udev->dev, "IN endpoint stalled\n");
	nxt->halted_in = true;
	if (nxt->stalls < U8_MAX)
		nxt->stalls++;
	nxt->brick.stats.stalls_in++;
	trace_nxt_usb_stall(nxt->brick.name, true, nxt->stalls);
	nxt_brick_in_stalled(&nxt->brick);
}

/*
 * A packet, or why none came: the packet goes to the engine. True if the
 * reader goes on, false if it stopped (@recover: and is to be restarted).
 * @brick.lock held.
 */
static bool nxt_in_status(struct nxt_usb *nxt, struct urb *urb, bool *recover)
{
	switch (urb->status) {
	case 0:
		nxt->stalls = 0;
		nxt_brick_rx(&nxt->brick, nxt->in_buf, urb->actual_length);
		return true;
	case -ENOENT:
	case -ECONNRESET:
	case -ESHUTDOWN:
	case -ENODEV:
		/* Killed, or the brick is gone. */
		return false;
	case -EPIPE:
		nxt_in_stalled(nxt);
		*recover = true;
		return false;
	default:
		/* -EPROTO, -EILSEQ, -EOVERFLOW...: often an unplug in progress. */
		dev_dbg_ratelimited(&nxt->udev->dev, "IN transfer error %d\n", urb->status);
		nxt_brick_link_error(&nxt->brick);
		*recover = true;
		return false;
	}
}

static void nxt_in_complete(struct urb *urb)
{
	struct nxt_usb *nxt = urb->context;
	bool resubmit, recover = false;
	unsigned long flags, delay;
	int ret;

	spin_lock_irqsave(&nxt->brick.lock, flags);
	resubmit = nxt_in_status(nxt, urb, &recover);
	if (!resubmit)
		nxt->reader_running = false;
	delay = nxt_recover_delay(nxt);
	spin_unlock_irqrestore(&nxt->brick.lock, flags);

	if (resubmit) {
		ret = usb_submit_urb(urb, GFP_ATOMIC);
		if (ret) {
			spin_lock_irqsave(&nxt->brick.lock, flags);
			nxt->reader_running = false;
			spin_unlock_irqrestore(&nxt->brick.lock, flags);
			/* -EPERM: being killed; -ENODEV: unplugged. */
			if (ret != -EPERM && ret != -ENODEV) {
				dev_err_ratelimited(&nxt->udev->dev,
						    "cannot resubmit the IN transfer: %d\n", ret);
				recover = true;
			}
		}
	}
	if (recover)
		schedule_delayed_work(&nxt->recover_work, delay);
}

/* What an OUT URB's status means for its transaction. */
static int nxt_out_errno(int status)
{
	switch (status) {
	case 0:
		return 0;
	case -EPIPE:
		return -EPIPE;
	case -ENODEV:
	case -ESHUTDOWN:
		return -ENODEV;
	case -ENOENT:
	case -ECONNRESET:
		return -EINTR;
	default:
		return -EIO;
	}
}

static void nxt_out_complete(struct urb *urb)
{
	struct nxt_xfer *x = urb->context;
	struct nxt_usb *nxt = to_nxt_usb(x->brick);
	unsigned long flags;

	if (urb->status == -EPIPE) {
		spin_lock_irqsave(&nxt->brick.lock, flags);
		nxt->halted_out = true;
		nxt->brick.stats.stalls_out++;
		trace_nxt_usb_stall(nxt->brick.name, false, nxt->stalls);
		spin_unlock_irqrestore(&nxt->brick.lock, flags);
		schedule_delayed_work(&nxt->recover_work, 0);
	}
	/* The last touch of @x. */
	nxt_brick_sent(&nxt->brick, x, nxt_out_errno(urb->status));
}

/* Starts the reader unless it runs, cannot run or is not wanted. @tx_lock held. */
static int nxt_reader_start_locked(struct nxt_usb *nxt)
{
	bool start;
	int ret;

	lockdep_assert_held(&nxt->brick.tx_lock);
	if (!nxt->intf || nxt->brick.paused || !nxt->reader_wanted)
		return 0;

	spin_lock_irq(&nxt->brick.lock);
	start = !nxt->reader_running && !nxt->halted_in;
	if (start) {
		nxt->reader_running = true;
		nxt_brick_rx_started(&nxt->brick);
	}
	spin_unlock_irq(&nxt->brick.lock);
	if (!start)
		return 0;

	ret = usb_submit_urb(nxt->in_urb, GFP_KERNEL);
	if (ret) {
		spin_lock_irq(&nxt->brick.lock);
		nxt->reader_running = false;
		spin_unlock_irq(&nxt->brick.lock);
		/* -ENODEV: unplugged, disconnect() is on its way. */
		if (ret != -ENODEV)
			dev_err_ratelimited(&nxt->udev->dev,
					    "cannot start the IN transfer: %d\n", ret);
	}
	return ret;
}

/*
 * Clears the stalls seen and (re)starts the reader. @tx_lock held. Only the
 * flags read here are cleared: a stall flagged meanwhile by a running reader
 * stays flagged, for the next call.
 */
static int nxt_recover_locked(struct nxt_usb *nxt)
{
	bool in, out;

	lockdep_assert_held(&nxt->brick.tx_lock);
	spin_lock_irq(&nxt->brick.lock);
	in = nxt->halted_in;
	out = nxt->halted_out;
	spin_unlock_irq(&nxt->brick.lock);

	if (out && usb_clear_halt(nxt->udev, nxt->out_pipe))
		dev_warn_ratelimited(&nxt->udev->dev, "cannot clear the OUT stall\n");
	if (in && usb_clear_halt(nxt->udev, nxt->in_pipe))
		dev_warn_ratelimited(&nxt->udev->dev, "cannot clear the IN stall\n");

	spin_lock_irq(&nxt->brick.lock);
	if (in)
		nxt->halted_in = false;
	if (out)
		nxt->halted_out = false;
	spin_unlock_irq(&nxt->brick.lock);
	return nxt_reader_start_locked(nxt);
}

/* Clears stalls and restarts the reader, in process context. */
static void nxt_recover_work(struct work_struct *work)
{
	struct nxt_usb *nxt = container_of(to_delayed_work(work), struct nxt_usb,
					   recover_work);

	mutex_lock(&nxt->brick.tx_lock);
	if (nxt->intf && !nxt->brick.paused)
		nxt_recover_locked(nxt);
	mutex_unlock(&nxt->brick.tx_lock);
}

/* nxt_transport_ops.start: before each telegram. */
static int nxt_usb_start(struct nxt_brick *b)
{
	return nxt_recover_locked(to_nxt_usb(b));
}

/*
 * nxt_transport_ops.open: the first open file. The brick stays resumed,
 * and its replies are collected, until the last one is closed.
 */
static int nxt_usb_open(struct nxt_brick *b)
{
	struct nxt_usb *nxt = to_nxt_usb(b);
	int ret;

	/*
	 * Called from open(), which usb_deregister_dev() waits for: @intf
	 * is still bound. A resume takes @tx_lock: not held here.
	 */
	ret = usb_autopm_get_interface(nxt->intf);
	if (ret)
		return ret;
	/* Interrupted (a reset holds the lock): nothing done, open restarts. */
	if (mutex_lock_interruptible(&b->tx_lock)) {
		usb_autopm_put_interface(nxt->intf);
		return -ERESTARTSYS;
	}
	nxt->reader_wanted = true;
	ret = nxt_reader_start_locked(nxt);
	if (ret)
		nxt->reader_wanted = false;
	mutex_unlock(&b->tx_lock);
	if (ret)
		usb_autopm_put_interface(nxt->intf);
	return ret;
}

/*
 * nxt_transport_ops.close: the last open file was closed. The reader stops
 * (a late reply left in the brick is drained at the next open) and the
 * brick may autosuspend.
 */
static void nxt_usb_close(struct nxt_brick *b)
{
	struct nxt_usb *nxt = to_nxt_usb(b);

	mutex_lock(&b->tx_lock);
	nxt->reader_wanted = false;
	usb_kill_urb(nxt->in_urb);
	/*
	 * Once unbound, the USB core has undone the reference of open. The
	 * put is asynchronous: an autosuspend takes @tx_lock.
	 */
	if (nxt->intf)
		usb_autopm_put_interface_async(nxt->intf);
	mutex_unlock(&b->tx_lock);
}

/*
 * nxt_transport_ops.send: one bulk OUT transfer of the telegram; the URB is
 * the handle. @x may live on the stack: the URB gets a buffer of its own.
 */
static void *nxt_usb_send(struct nxt_brick *b, struct nxt_xfer *x)
{
	struct nxt_usb *nxt = to_nxt_usb(b);
	struct urb *urb;
	void *buf;
	int ret;

	urb = usb_alloc_urb(0, GFP_KERNEL);
	if (!urb)
		return ERR_PTR(-ENOMEM);
	buf = kmemdup(x->tg, x->len, GFP_KERNEL);
	if (!buf) {
		usb_free_urb(urb);
		return ERR_PTR(-ENOMEM);
	}
	usb_fill_bulk_urb(urb, nxt->udev, nxt->out_pipe, buf, x->len,
			  nxt_out_complete, x);
	urb->transfer_flags |= URB_FREE_BUFFER;
	usb_anchor_urb(urb, &nxt->out_anchor);
	ret = usb_submit_urb(urb, GFP_KERNEL);
	if (ret) {
		usb_unanchor_urb(urb);
		usb_free_urb(urb);
		return ERR_PTR(ret);
	}
	return urb;
}

static void nxt_usb_unlink(void *urb)
{
	usb_unlink_urb(urb);
}

static void nxt_usb_kill(void *urb)
{
	usb_kill_urb(urb);
}

static void nxt_usb_get_urb(void *urb)
{
	usb_get_urb(urb);
}

static void nxt_usb_put_urb(void *urb)
{
	usb_free_urb(urb);
}

static void nxt_usb_release(struct nxt_brick *b)
{
	struct nxt_usb *nxt = to_nxt_usb(b);

	usb_free_urb(nxt->in_urb);
	kfree(nxt->in_buf);
	usb_put_dev(nxt->udev);
	kfree(nxt);
}

static const struct nxt_transport_ops nxt_usb_ops = {
	.start		= nxt_usb_start,
	.open		= nxt_usb_open,
	.close		= nxt_usb_close,
	.send		= nxt_usb_send,
	.unlink		= nxt_usb_unlink,
	.kill		= nxt_usb_kill,
	.get		= nxt_usb_get_urb,
	.put		= nxt_usb_put_urb,
	.release	= nxt_usb_release,
	.owner		= THIS_MODULE,
};

/* Finds the endpoints and sets up the reader. */
static int nxt_usb_setup(struct nxt_usb *nxt, struct usb_interface *intf)
{
	struct usb_endpoint_descriptor *in, *out;
	int ret;

	ret = usb_find_common_endpoints(intf->cur_altsetting, &in, &out, NULL, NULL);
	if (ret) {
		dev_err(&intf->dev, "no bulk endpoints\n");
		return ret;
	}
	if (usb_endpoint_maxp(in) < NXT_TELEGRAM_MAX ||
	    usb_endpoint_maxp(out) < NXT_TELEGRAM_MAX) {
		dev_err(&intf->dev, "bulk endpoints smaller than a telegram\n");
		return -ENODEV;
	}
	nxt->out_pipe = usb_sndbulkpipe(nxt->udev, usb_endpoint_num(out));
	nxt->in_pipe = usb_rcvbulkpipe(nxt->udev, usb_endpoint_num(in));

	nxt->in_urb = usb_alloc_urb(0, GFP_KERNEL);
	nxt->in_buf = kmalloc(NXT_TELEGRAM_MAX, GFP_KERNEL);
	if (!nxt->in_urb || !nxt->in_buf)
		return -ENOMEM;
	/* Exactly one packet: the brick sends no zero-length packet after 64 bytes. */
	usb_fill_bulk_urb(nxt->in_urb, nxt->udev, nxt->in_pipe, nxt->in_buf,
			  NXT_TELEGRAM_MAX, nxt_in_complete, nxt);
	return 0;
}

static int nxt_usb_probe(struct usb_interface *intf,
			 const struct usb_device_id *id)
{
	struct nxt_usb *nxt;
	int ret;

	nxt = kzalloc_obj(*nxt, GFP_KERNEL);
	if (!nxt)
		return -ENOMEM;
	nxt->udev = usb_get_dev(interface_to_usbdev(intf));
	nxt->intf = intf;
	nxt_brick_init(&nxt->brick, &nxt_usb_ops, &intf->dev, dev_name(&nxt->udev->dev));
	init_usb_anchor(&nxt->out_anchor);
	INIT_DELAYED_WORK(&nxt->recover_work, nxt_recover_work);
	ret = nxt_usb_setup(nxt, intf);
	if (ret)
		goto err_put;
	usb_set_intfdata(intf, nxt);
	/* The brick's iSerial is its Bluetooth address, twelve hex digits. */
	if (nxt->udev->serial)
		strscpy(nxt->brick.serial, nxt->udev->serial, sizeof(nxt->brick.serial));

	ret = nxt_node_add(&nxt->brick, &intf->dev);
	if (ret) {
		dev_err(&intf->dev, "cannot get a minor: %d\n", ret);
		usb_set_intfdata(intf, NULL);
		goto err_put;
	}
	nxt_brick_debugfs(&nxt->brick);

	/*
	 * Nothing is sent to the brick until a program that opened it for
	 * writing sends a telegram: not at probe, not from sysfs.
	 */
	dev_info(&intf->dev, "LEGO NXT brick %s now at %s\n",
		 nxt->udev->serial ?: "(no serial)", dev_name(nxt->brick.node));
	return 0;

err_put:
	nxt_brick_put(&nxt->brick);
	return ret;
}

/* Stops every transfer. @brick.tx_lock held. */
static void nxt_usb_stop_io(struct nxt_usb *nxt)
{
	usb_kill_anchored_urbs(&nxt->out_anchor);
	usb_kill_urb(nxt->in_urb);
}

static void nxt_usb_disconnect(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_DISCONNECT);
	/* No new opens; then no new transfers; then none in flight. */
	nxt_node_remove(&nxt->brick);

	mutex_lock(&nxt->brick.tx_lock);
	nxt->intf = NULL;
	nxt_brick_disconnect(&nxt->brick);
	/* Poisoned: a completion or a late work item cannot resubmit them. */
	usb_poison_anchored_urbs(&nxt->out_anchor);
	usb_poison_urb(nxt->in_urb);
	mutex_unlock(&nxt->brick.tx_lock);

	cancel_delayed_work_sync(&nxt->recover_work);
	nxt_brick_shutdown(&nxt->brick);

	usb_set_intfdata(intf, NULL);
	dev_info(&intf->dev, "LEGO NXT brick disconnected\n");
	nxt_brick_put(&nxt->brick);
}

/* A reset cleared the endpoints' halts: none is left to clear. */
static void nxt_forget_halts(struct nxt_usb *nxt)
{
	spin_lock_irq(&nxt->brick.lock);
	nxt->halted_in = false;
	nxt->halted_out = false;
	nxt->stalls = 0;
	spin_unlock_irq(&nxt->brick.lock);
}

/*
 * A USB reset (nxt-python resets the brick before using it) keeps the
 * driver bound: transfers stop in pre_reset() and start again in
 * post_reset(), and the brick is paused in between. A transaction in flight
 * fails with -EIO, since its reply is lost; one that holds the slot but
 * has not sent its telegram yet sends it after the reset.
 */
static int nxt_usb_pre_reset(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_PRE_RESET);
	/* Held until post_reset(). */
	mutex_lock(&nxt->brick.tx_lock);
	nxt->brick.paused = true;
	nxt_brick_fail(&nxt->brick, -EIO);
	nxt_usb_stop_io(nxt);
	return 0;
}

static int nxt_usb_post_reset(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_POST_RESET);
	spin_lock_irq(&nxt->brick.lock);
	nxt->brick.stats.resets++;
	spin_unlock_irq(&nxt->brick.lock);
	nxt_forget_halts(nxt);
	nxt->brick.paused = false;
	nxt_reader_start_locked(nxt);
	mutex_unlock(&nxt->brick.tx_lock);
	return 0;
}

/*
 * Nothing new is sent once the brick is paused; the transaction in flight
 * gets up to NXT_SUSPEND_WAIT_MS to finish (the brick answers within a few
 * milliseconds), and fails with -EIO after that. An autosuspend comes only
 * with no file open, so nothing is in flight then.
 */
static int nxt_usb_suspend(struct usb_interface *intf, pm_message_t message)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_SUSPEND);
	mutex_lock(&nxt->brick.tx_lock);
	/* A transaction in flight holds the slot: the slot is not free then. */
	if (PMSG_IS_AUTO(message) && !nxt_slot_free(&nxt->brick)) {
		mutex_unlock(&nxt->brick.tx_lock);
		return -EBUSY;
	}
	nxt->brick.paused = true;
	if (!wait_event_timeout(nxt->brick.wait, !nxt_brick_in_flight(&nxt->brick),
				msecs_to_jiffies(NXT_SUSPEND_WAIT_MS)))
		dev_warn(&intf->dev, "suspended with a transaction in flight\n");
	nxt_brick_fail(&nxt->brick, -EIO);
	nxt_usb_stop_io(nxt);
	mutex_unlock(&nxt->brick.tx_lock);
	return 0;
}

static int nxt_usb_resume(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);
	int ret;

	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_RESUME);
	mutex_lock(&nxt->brick.tx_lock);
	nxt->brick.paused = false;
	ret = nxt_reader_start_locked(nxt);
	mutex_unlock(&nxt->brick.tx_lock);
	return ret;
}

static int nxt_usb_reset_resume(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	/* The brick was reset: its endpoints are no longer halted. */
	trace_nxt_usb_reset(nxt->brick.name, NXT_USB_TRACE_RESET_RESUME);
	nxt_forget_halts(nxt);
	return nxt_usb_resume(intf);
}

/*
 * The brick's vendor interface is interface 0, class ff/ff/ff. Matching the
 * interface number keeps the driver off anything else sharing the ID; the
 * firmware-update (SAM-BA, 03eb:6124) and WeDo (0694:0003) devices have IDs
 * of their own. Bricks running leJOS NXJ share this ID; nothing is sent to
 * a brick unless a user asks.
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
	.pre_reset	= nxt_usb_pre_reset,
	.post_reset	= nxt_usb_post_reset,
	.suspend	= nxt_usb_suspend,
	.resume		= nxt_usb_resume,
	.reset_resume	= nxt_usb_reset_resume,
	.id_table	= nxt_usb_ids,
	.supports_autosuspend = 1,
};

module_usb_driver(nxt_usb_driver);

MODULE_DESCRIPTION("LEGO MINDSTORMS NXT brick USB driver");
MODULE_LICENSE("GPL");
