// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: USB transport.
 *
 * Binds the brick's vendor interface (0694:0002, interface 0), keeps a
 * 64-byte IN transfer pending to collect replies, and runs transactions:
 * one telegram out, its reply (if its type asks for one) in. See
 * nxt_usb.h for the slot, the locking and the lifetimes; telegram
 * validation lives in nxt_proto.c, the char device in nxt_cdev.c.
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
#include <linux/debugfs.h>
#include <linux/errno.h>
#include <linux/jiffies.h>
#include <linux/limits.h>
#include <linux/module.h>
#include <linux/sched/signal.h>
#include <linux/seq_file.h>
#include <linux/slab.h>
#include <linux/usb.h>

#include "lego_compat.h"
#include "nxt_proto.h"
#include "nxt_usb.h"
#include "nxt_usb_trace.h"

#define NXT_USB_VENDOR		0x0694
#define NXT_USB_PRODUCT		0x0002
/* Restart delay of the reader after a transfer error other than a stall. */
#define NXT_RECOVER_MS		10
/*
 * An unplug shows as transfer errors before the hub reports it: after such
 * an error a transaction waits this much past its deadline for disconnect(),
 * so that it ends with -ENODEV rather than with a timeout.
 */
#define NXT_UNPLUG_GRACE_MS	1000
/* How long suspend() lets the transaction in flight finish. */
#define NXT_SUSPEND_WAIT_MS	1000

/* lego_nxt_usb in debugfs: a directory per brick (nxt_usb_probe()). */
static struct dentry *nxt_debugfs_root;

/* The brick's name in the trace events: its USB device's, e.g. "1-1". */
static const char *nxt_name(const struct nxt_usb *nxt)
{
	return dev_name(&nxt->udev->dev);
}

/*
 * Drains packets for @ms from now, unless a drain already lasts longer.
 * The drain clock is 64-bit jiffies: a drain that ended weeks ago on a
 * 32-bit machine stays ended. @lock held.
 */
static void nxt_drain_for(struct nxt_usb *nxt, unsigned int ms)
{
	u64 until = get_jiffies_64() + msecs_to_jiffies(ms);

	lockdep_assert_held(&nxt->lock);
	if (until <= nxt->drain_until)
		return;
	nxt->drain_until = until;
	nxt->stats.drains++;
	trace_nxt_usb_drain(nxt_name(nxt), ms, nxt->orphan, nxt->orphan_op);
	/* Nothing else may happen when it ends: poll() is woken then. */
	mod_delayed_work(system_percpu_wq, &nxt->drain_work, msecs_to_jiffies(ms) + 1);
}

/* The drain has ended (or ended early): writers and poll() may go on. */
static void nxt_drain_work(struct work_struct *work)
{
	struct nxt_usb *nxt = container_of(to_delayed_work(work), struct nxt_usb,
					   drain_work);

	wake_up_all(&nxt->wait);
}

/* Jiffies left of the drain; 0 when none. @lock held. */
static unsigned long nxt_drain_left(struct nxt_usb *nxt)
{
	lockdep_assert_held(&nxt->lock);
	return nxt_time_left(get_jiffies_64(), nxt->drain_until,
			     msecs_to_jiffies(NXT_SLOW_REPLY_MS));
}

static bool nxt_draining(struct nxt_usb *nxt)
{
	unsigned long left;

	spin_lock_irq(&nxt->lock);
	left = nxt_drain_left(nxt);
	spin_unlock_irq(&nxt->lock);
	return left;
}

/*
 * @x, which was sent, ended without its reply: the reply may still be on
 * its way, or queued in the brick's FIFO. If the brick took the telegram,
 * the drain waits for the reply to its opcode (nxt_reply_late_ms()) and
 * ends when it comes; else it lasts NXT_DRAIN_MS. @lock held.
 */
static void nxt_orphan(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	if (!x->delivered) {
		nxt_drain_for(nxt, NXT_DRAIN_MS);
		return;
	}
	nxt->orphan = true;
	nxt->orphan_op = x->tg[1];
	nxt_drain_for(nxt, nxt_reply_late_ms(x->tg, x->len));
}

/*
 * The slot is free, or the first in line changed: wakes the first in line,
 * the only one that may claim it (nxt_claim()). @lock held.
 */
static void nxt_wake_next(struct nxt_usb *nxt)
{
	struct nxt_xfer *next;

	lockdep_assert_held(&nxt->lock);
	if (nxt->cur)
		return;
	next = list_first_entry_or_null(&nxt->queue, struct nxt_xfer, queue);
	if (next)
		wake_up(&next->wait);
}

/* Counts a transaction that ended with @status. @lock held. */
static void nxt_count_end(struct nxt_stats *st, int status)
{
	st->transactions++;
	switch (status) {
	case 0:
		st->ok++;
		break;
	case -ETIMEDOUT:
		st->err_timedout++;
		break;
	case -EPROTO:
		st->err_proto++;
		break;
	case -EPIPE:
		st->err_pipe++;
		break;
	case -EIO:
		st->err_io++;
		break;
	case -ENODEV:
		st->err_nodev++;
		break;
	case -EINTR:
		st->err_intr++;
		break;
	default:
		st->err_other++;
		break;
	}
}

/* Ends the transaction @x with @status and frees the slot. @lock held. */
static void nxt_finish(struct nxt_usb *nxt, struct nxt_xfer *x, int status)
{
	lockdep_assert_held(&nxt->lock);
	x->status = status;
	nxt_count_end(&nxt->stats, status);
	trace_nxt_usb_done(nxt_name(nxt), x, x->tg[1], status);
	if (nxt->cur == x) {
		nxt->cur = NULL;
		timer_delete(&nxt->timer);
		nxt_wake_next(nxt);
	}
	/* A telegram never sent has no reply to wait for. */
	if (status && x->want_reply && x->sent)
		nxt_orphan(nxt, x);
	wake_up(&x->wait);
	/* poll() and suspend(); nobody else sleeps there. */
	wake_up_all(&nxt->wait);
}

static int nxt_urb_errno(int status, bool timed_out)
{
	if (timed_out)
		return -ETIMEDOUT;
	switch (status) {
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

/* A packet that came while draining: dropped; it may end the drain. @lock held. */
static void nxt_drain_packet(struct nxt_usb *nxt, const u8 *buf, unsigned int len)
{
	bool end;

	dev_dbg_ratelimited(&nxt->udev->dev, "dropped a stale packet (%u bytes)\n", len);
	nxt->stats.drained++;
	/*
	 * Replies come in the order of their commands, and the last command
	 * that lost its reply was sent last: once its reply is in, nothing
	 * stale is left to come.
	 */
	end = nxt->orphan && len >= 2 && buf[0] == NXT_REPLY && buf[1] == nxt->orphan_op;
	trace_nxt_usb_drop(nxt_name(nxt), NXT_USB_TRACE_DRAIN, buf, len, end);
	if (end) {
		nxt->orphan = false;
		nxt->drain_until = get_jiffies_64();
		wake_up_all(&nxt->wait);
	}
}

/* A packet from the brick: the awaited reply, or something to drop. @lock held. */
static void nxt_take_packet(struct nxt_usb *nxt, const u8 *buf, unsigned int len)
{
	struct nxt_xfer *x = nxt->cur;
	int ret;

	if (nxt_drain_left(nxt)) {
		nxt_drain_packet(nxt, buf, len);
		return;
	}
	nxt->orphan = false;
	/* Until its telegram is sent, nothing can answer a transaction. */
	if (!x || !x->sent || !x->want_reply || x->status != -EINPROGRESS) {
		dev_dbg_ratelimited(&nxt->udev->dev, "dropped a stale packet (%u bytes)\n", len);
		nxt->stats.stale++;
		trace_nxt_usb_drop(nxt_name(nxt), NXT_USB_TRACE_STALE, buf, len, false);
		return;
	}

	ret = nxt_reply_check(x->tg, x->len, buf, len);
	if (ret < 0) {
		/*
		 * Not this reply: stale, garbage, or the right opcode with the
		 * wrong length or echo. The real reply may still come; the
		 * timeout decides, with -EPROTO if it does not.
		 */
		x->saw_bad = true;
		nxt->stats.mismatched++;
		trace_nxt_usb_drop(nxt_name(nxt), NXT_USB_TRACE_MISMATCH, buf, len, false);
		dev_dbg_ratelimited(&nxt->udev->dev,
				    "packet %*ph... (%u bytes) does not answer opcode 0x%02x\n",
				    min(len, 4U), buf, len, x->tg[1]);
		return;
	}
	memcpy(x->reply, buf, len);
	x->reply_len = len;
	nxt->stats.replies++;
	trace_nxt_usb_rx(nxt_name(nxt), x, buf[0], buf[1], len > 2 ? buf[2] : 0, len);
	nxt_finish(nxt, x, 0);
}

/*
 * When to restart the reader after a transfer error: after a stall, as
 * nxt_stall_backoff_ms() says (at once the first time, later when the
 * endpoint stalls again and again); NXT_RECOVER_MS after other errors.
 * @lock held.
 */
static unsigned long nxt_recover_delay(struct nxt_usb *nxt)
{
	lockdep_assert_held(&nxt->lock);
	if (!nxt->halted_in)
		return msecs_to_jiffies(NXT_RECOVER_MS);
	return msecs_to_jiffies(nxt_stall_backoff_ms(nxt->stalls));
}

static void nxt_in_complete(struct urb *urb)
{
	struct nxt_usb *nxt = urb->context;
	bool resubmit = false, recover = false;
	unsigned long flags, delay;
	int ret;

	spin_lock_irqsave(&nxt->lock, flags);
	switch (urb->status) {
	case 0:
		nxt->stalls = 0;
		nxt_take_packet(nxt, nxt->in_buf, urb->actual_length);
		resubmit = true;
		break;
	case -ENOENT:
	case -ECONNRESET:
	case -ESHUTDOWN:
	case -ENODEV:
		/* Killed, or the brick is gone. */
		break;
	case -EPIPE:
		dev_warn_ratelimited(&nxt->udev->dev, "IN endpoint stalled\n");
		nxt->halted_in = true;
		if (nxt->stalls < U8_MAX)
			nxt->stalls++;
		nxt->stats.stalls_in++;
		trace_nxt_usb_stall(nxt_name(nxt), true, nxt->stalls);
		/* A transaction not sent yet sends its telegram after recovery. */
		if (nxt->cur && nxt->cur->sent && nxt->cur->want_reply &&
		    nxt->cur->status == -EINPROGRESS)
			nxt_finish(nxt, nxt->cur, -EPIPE);
		recover = true;
		break;
	default:
		/* -EPROTO, -EILSEQ, -EOVERFLOW...: often an unplug in progress. */
		dev_dbg_ratelimited(&nxt->udev->dev, "IN transfer error %d\n", urb->status);
		if (nxt->cur && nxt->cur->sent)
			nxt->cur->link_error = true;
		recover = true;
		break;
	}
	if (!resubmit)
		nxt->reader_running = false;
	delay = nxt_recover_delay(nxt);
	spin_unlock_irqrestore(&nxt->lock, flags);

	if (resubmit) {
		ret = usb_submit_urb(urb, GFP_ATOMIC);
		if (ret) {
			spin_lock_irqsave(&nxt->lock, flags);
			nxt->reader_running = false;
			spin_unlock_irqrestore(&nxt->lock, flags);
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

static void nxt_out_complete(struct urb *urb)
{
	struct nxt_xfer *x = urb->context;
	struct nxt_usb *nxt = x->nxt;
	unsigned long flags;

	spin_lock_irqsave(&nxt->lock, flags);
	/* The brick has the telegram, even if it was late (timed out). */
	x->delivered = !urb->status;
	if (x->status == -EINPROGRESS) {
		if (urb->status && !x->timed_out && urb->status != -ENOENT)
			dev_warn_ratelimited(&nxt->udev->dev,
					     "sending opcode 0x%02x failed: %d\n",
					     x->tg[1], urb->status);
		/*
		 * Timed out: even if the unlink came too late to stop the
		 * transfer, the deadline has passed and the timer is done.
		 */
		if (urb->status || x->timed_out)
			nxt_finish(nxt, x, nxt_urb_errno(urb->status, x->timed_out));
		else if (!x->want_reply)
			nxt_finish(nxt, x, 0);
	}
	if (urb->status == -EPIPE) {
		nxt->halted_out = true;
		nxt->stats.stalls_out++;
		trace_nxt_usb_stall(nxt_name(nxt), false, nxt->stalls);
		schedule_delayed_work(&nxt->recover_work, 0);
	}
	/* The last touch of @x: its owner may free it once it sees this. */
	x->out_done = true;
	/* An owner waiting for the reply too is woken when it comes. */
	if (!x->reply_wait || x->status != -EINPROGRESS)
		wake_up(&x->wait);
	spin_unlock_irqrestore(&nxt->lock, flags);
}

/* The transaction in the slot is out of time. */
static void nxt_timer_fn(struct timer_list *t)
{
	struct nxt_usb *nxt = timer_container_of(nxt, t, timer);
	struct urb *unlink = NULL;
	struct nxt_xfer *x;
	unsigned long flags;

	spin_lock_irqsave(&nxt->lock, flags);
	x = nxt->cur;
	/* A timer meant for an earlier transaction cannot end one not yet sent. */
	if (x && x->sent && x->status == -EINPROGRESS) {
		if (time_before(jiffies, x->deadline)) {
			mod_timer(&nxt->timer, x->deadline);
		} else if (!x->out_done) {
			/* The brick did not take the telegram: cancel it. */
			trace_nxt_usb_timeout(nxt_name(nxt), x, x->tg[1],
					      "telegram not taken");
			x->timed_out = true;
			unlink = usb_get_urb(x->urb);
		} else if (READ_ONCE(nxt->udev->state) == USB_STATE_NOTATTACHED) {
			/* Unplugged; disconnect() is on its way. */
			nxt_finish(nxt, x, -ENODEV);
		} else if (x->link_error && !x->grace_used) {
			x->grace_used = true;
			x->deadline = jiffies + msecs_to_jiffies(NXT_UNPLUG_GRACE_MS);
			mod_timer(&nxt->timer, x->deadline);
		} else {
			trace_nxt_usb_timeout(nxt_name(nxt), x, x->tg[1],
					      x->link_error ? "transfer errors, no reply" :
					      x->saw_bad ? "malformed reply" : "no reply");
			dev_warn_ratelimited(&nxt->udev->dev, "%s reply to opcode 0x%02x\n",
					     x->link_error ? "transfer errors, no" :
					     x->saw_bad ? "malformed" : "no", x->tg[1]);
			nxt_finish(nxt, x, x->link_error ? -EIO :
					   x->saw_bad ? -EPROTO : -ETIMEDOUT);
		}
	}
	spin_unlock_irqrestore(&nxt->lock, flags);

	if (unlink) {
		usb_unlink_urb(unlink);
		usb_put_urb(unlink);
	}
}

/* Starts the reader unless it runs, cannot run or is not wanted. @io_mutex held. */
static int nxt_reader_start_locked(struct nxt_usb *nxt)
{
	bool start;
	int ret;

	lockdep_assert_held(&nxt->io_mutex);
	if (!nxt->intf || nxt->suspended || !nxt->reader_wanted)
		return 0;

	spin_lock_irq(&nxt->lock);
	start = !nxt->reader_running && !nxt->halted_in;
	if (start) {
		nxt->reader_running = true;
		/* Whatever the brick still holds from before is stale. */
		nxt_drain_for(nxt, NXT_DRAIN_MS);
	}
	spin_unlock_irq(&nxt->lock);
	if (!start)
		return 0;

	ret = usb_submit_urb(nxt->in_urb, GFP_KERNEL);
	if (ret) {
		spin_lock_irq(&nxt->lock);
		nxt->reader_running = false;
		spin_unlock_irq(&nxt->lock);
		/* -ENODEV: unplugged, disconnect() is on its way. */
		if (ret != -ENODEV)
			dev_err_ratelimited(&nxt->udev->dev,
					    "cannot start the IN transfer: %d\n", ret);
	}
	return ret;
}

/**
 * nxt_reader_ensure() - start collecting the brick's replies
 * @nxt: the brick
 *
 * Called on open; the reader then runs until the brick is gone, and stale
 * packets are drained for NXT_DRAIN_MS when it starts.
 *
 * Return: 0, -%ENODEV if the brick is gone, or -%EINTR.
 */
int nxt_reader_ensure(struct nxt_usb *nxt)
{
	int ret;

	if (mutex_lock_interruptible(&nxt->io_mutex))
		return -EINTR;
	if (nxt->intf) {
		nxt->reader_wanted = true;
		ret = nxt_reader_start_locked(nxt);
	} else {
		ret = -ENODEV;
	}
	mutex_unlock(&nxt->io_mutex);
	return ret;
}

/*
 * Clears the stalls seen and (re)starts the reader. @io_mutex held. Only the
 * flags read here are cleared: a stall flagged meanwhile by a running reader
 * stays flagged, for the next call.
 */
static int nxt_recover_locked(struct nxt_usb *nxt)
{
	bool in, out;

	lockdep_assert_held(&nxt->io_mutex);
	spin_lock_irq(&nxt->lock);
	in = nxt->halted_in;
	out = nxt->halted_out;
	spin_unlock_irq(&nxt->lock);

	if (out && usb_clear_halt(nxt->udev, nxt->out_pipe))
		dev_warn_ratelimited(&nxt->udev->dev, "cannot clear the OUT stall\n");
	if (in && usb_clear_halt(nxt->udev, nxt->in_pipe))
		dev_warn_ratelimited(&nxt->udev->dev, "cannot clear the IN stall\n");

	spin_lock_irq(&nxt->lock);
	if (in)
		nxt->halted_in = false;
	if (out)
		nxt->halted_out = false;
	spin_unlock_irq(&nxt->lock);
	return nxt_reader_start_locked(nxt);
}

/* Clears stalls and restarts the reader, in process context. */
static void nxt_recover_work(struct work_struct *work)
{
	struct nxt_usb *nxt = container_of(to_delayed_work(work), struct nxt_usb,
					   recover_work);

	mutex_lock(&nxt->io_mutex);
	if (nxt->intf && !nxt->suspended)
		nxt_recover_locked(nxt);
	mutex_unlock(&nxt->io_mutex);
}

/*
 * Claims the slot for @x, queued by nxt_enqueue(), once it is free and @x is
 * first in the queue. True when done (@x left the queue) or when the brick
 * is gone (@err).
 */
static bool nxt_claim(struct nxt_usb *nxt, struct nxt_xfer *x, int *err)
{
	bool done = true;

	spin_lock_irq(&nxt->lock);
	if (nxt->gone) {
		list_del_init(&x->queue);
		*err = -ENODEV;
	} else if (!nxt->cur &&
		   list_first_entry(&nxt->queue, struct nxt_xfer, queue) == x) {
		list_del_init(&x->queue);
		nxt->cur = x;
		x->status = -EINPROGRESS;
		*err = 0;
	} else {
		done = false;
	}
	spin_unlock_irq(&nxt->lock);
	return done;
}

/* Puts @x at the end of the queue for the slot. */
static void nxt_enqueue(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	spin_lock_irq(&nxt->lock);
	list_add_tail(&x->queue, &nxt->queue);
	spin_unlock_irq(&nxt->lock);
}

/* Takes @x, interrupted, out of the queue: the next in line may go. */
static void nxt_dequeue(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	spin_lock_irq(&nxt->lock);
	list_del_init(&x->queue);
	nxt_wake_next(nxt);
	spin_unlock_irq(&nxt->lock);
	wake_up_all(&nxt->wait);
}

/**
 * nxt_xfer_done() - whether a transaction has finished
 * @nxt: the brick
 * @x: the transaction
 *
 * Return: true once @x has finished (or was never started).
 */
bool nxt_xfer_done(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	bool done;

	spin_lock_irq(&nxt->lock);
	done = x->status != -EINPROGRESS;
	spin_unlock_irq(&nxt->lock);
	return done;
}

/*
 * Whether the OUT URB of @x has completed and, if its owner waits for the
 * reply too (@reply_wait), whether @x has finished.
 */
static bool nxt_out_done(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	bool done;

	spin_lock_irq(&nxt->lock);
	done = x->out_done && (!x->reply_wait || x->status != -EINPROGRESS);
	spin_unlock_irq(&nxt->lock);
	return done;
}

/**
 * nxt_slot_free() - whether a telegram could be sent now
 * @nxt: the brick
 *
 * Return: true if no transaction holds the brick or waits for it, and no
 * late reply is being drained.
 */
bool nxt_slot_free(struct nxt_usb *nxt)
{
	bool free;

	spin_lock_irq(&nxt->lock);
	free = !nxt->cur && list_empty(&nxt->queue) && !nxt_drain_left(nxt);
	spin_unlock_irq(&nxt->lock);
	return free;
}

/**
 * nxt_gone() - whether the brick has been disconnected
 * @nxt: the brick
 *
 * Return: true once disconnect() has run.
 */
bool nxt_gone(struct nxt_usb *nxt)
{
	bool gone;

	spin_lock_irq(&nxt->lock);
	gone = nxt->gone;
	spin_unlock_irq(&nxt->lock);
	return gone;
}

/*
 * Waits until no packet is being drained. Nothing was sent: interrupted, it
 * asks for the call to be restarted.
 */
static int nxt_drain_wait(struct nxt_usb *nxt, bool nonblock)
{
	unsigned long left;
	long ret;

	for (;;) {
		spin_lock_irq(&nxt->lock);
		left = nxt_drain_left(nxt);
		spin_unlock_irq(&nxt->lock);
		if (!left)
			return 0;
		if (nonblock)
			return -EAGAIN;
		ret = wait_event_interruptible_timeout(nxt->wait,
						       !nxt_draining(nxt) || nxt_gone(nxt),
						       left);
		if (ret < 0)
			return -ERESTARTSYS;
		if (nxt_gone(nxt))
			return -ENODEV;
	}
}

/* Takes @io_mutex for a transaction; -EAGAIN rather than wait if @nonblock. */
static int nxt_io_lock(struct nxt_usb *nxt, bool nonblock)
{
	if (nonblock)
		return mutex_trylock(&nxt->io_mutex) ? 0 : -EAGAIN;
	return mutex_lock_interruptible(&nxt->io_mutex) ? -ERESTARTSYS : 0;
}

/*
 * Submits the telegram of @x, which holds the slot. @x is live (can be
 * answered, timed out, or failed by a reset) from here on only: the timer
 * is armed once the URB is submitted, so that its unlink cannot miss it.
 */
static int nxt_submit(struct nxt_usb *nxt, struct nxt_xfer *x, struct urb *urb,
		      unsigned int timeout_ms)
{
	int ret;

	lockdep_assert_held(&nxt->io_mutex);
	usb_fill_bulk_urb(urb, nxt->udev, nxt->out_pipe, urb->transfer_buffer,
			  x->len, nxt_out_complete, x);
	spin_lock_irq(&nxt->lock);
	if (x->status != -EINPROGRESS) {
		/* Failed while it waited (the brick went away). */
		ret = x->status;
		spin_unlock_irq(&nxt->lock);
		return ret;
	}
	x->urb = urb;
	x->sent = true;
	x->deadline = jiffies + msecs_to_jiffies(timeout_ms);
	spin_unlock_irq(&nxt->lock);

	usb_anchor_urb(urb, &nxt->out_anchor);
	ret = usb_submit_urb(urb, GFP_KERNEL);
	spin_lock_irq(&nxt->lock);
	if (ret)
		x->sent = false;
	else if (nxt->cur == x && x->status == -EINPROGRESS)
		mod_timer(&nxt->timer, x->deadline);
	if (!ret)
		nxt->stats.telegrams++;
	trace_nxt_usb_tx(nxt_name(nxt), x, x->tg[0], x->tg[1], x->len, ret);
	spin_unlock_irq(&nxt->lock);
	if (ret) {
		usb_unanchor_urb(urb);
		dev_err_ratelimited(&nxt->udev->dev, "cannot send a telegram: %d\n", ret);
	}
	return ret;
}

/* Sends the telegram of @x, which holds the slot. */
static int nxt_send(struct nxt_usb *nxt, struct nxt_xfer *x, struct urb *urb,
		    unsigned int timeout_ms, bool nonblock)
{
	int ret;

	/* Let stale packets come and be dropped before this telegram goes. */
	ret = nxt_drain_wait(nxt, nonblock);
	if (ret)
		return ret;
	/* Held across a USB reset: O_NONBLOCK does not wait for one. */
	ret = nxt_io_lock(nxt, nonblock);
	if (ret)
		return ret;
	if (!nxt->intf) {
		ret = -ENODEV;
		goto out;
	}
	if (nxt->suspended) {
		ret = -EIO;
		goto out;
	}
	nxt->reader_wanted = true;
	/*
	 * A stall from the last transaction may not be cleared yet: its work
	 * item can run after this telegram has gone, and would then clear the
	 * stall the brick sets instead of this telegram's reply, which never
	 * comes. Clear it first.
	 */
	ret = nxt_recover_locked(nxt);
	if (ret)
		goto out;
	/* A reader (re)started just now drains too. */
	ret = nxt_drain_wait(nxt, nonblock);
	if (ret)
		goto out;
	ret = nxt_submit(nxt, x, urb, timeout_ms);
out:
	mutex_unlock(&nxt->io_mutex);
	return ret;
}

/*
 * nxt_xfer_start(), and with @reply_wait the reply's wait of nxt_transact()
 * too: then it returns once the reply has come as well (or a signal, which
 * ends the wait but not the transaction), so that its owner sleeps once per
 * transaction.
 */
static int nxt_xfer_run(struct nxt_usb *nxt, struct nxt_xfer *x, const u8 *tg,
			size_t len, unsigned int timeout_ms, bool nonblock,
			bool reply_wait)
{
	struct urb *urb;
	int want, ret, err = 0;

	want = nxt_telegram_check(tg, len);
	if (want < 0)
		return want;

	memset(x, 0, sizeof(*x));
	x->nxt = nxt;
	INIT_LIST_HEAD(&x->queue);
	init_waitqueue_head(&x->wait);
	memcpy(x->tg, tg, len);
	x->len = len;
	x->want_reply = want;
	x->reply_wait = reply_wait && want;

	urb = usb_alloc_urb(0, GFP_KERNEL);
	if (!urb)
		return -ENOMEM;
	/* @x may live on the stack: the URB gets a buffer of its own. */
	urb->transfer_buffer = kmemdup(tg, len, GFP_KERNEL);
	if (!urb->transfer_buffer) {
		usb_free_urb(urb);
		return -ENOMEM;
	}
	urb->transfer_flags |= URB_FREE_BUFFER;

	nxt_enqueue(nxt, x);
	if (nonblock) {
		if (!nxt_claim(nxt, x, &err)) {
			nxt_dequeue(nxt, x);
			err = -EAGAIN;
		}
	} else if (wait_event_interruptible(x->wait, nxt_claim(nxt, x, &err))) {
		nxt_dequeue(nxt, x);
		err = -ERESTARTSYS;
	}
	if (err) {
		usb_free_urb(urb);
		return err;
	}

	ret = nxt_send(nxt, x, urb, timeout_ms, nonblock);
	if (ret) {
		spin_lock_irq(&nxt->lock);
		x->out_done = true;
		if (x->status == -EINPROGRESS)
			nxt_finish(nxt, x, ret);
		x->urb = NULL;
		spin_unlock_irq(&nxt->lock);
		usb_free_urb(urb);
		return ret;
	}

	if (wait_event_interruptible(x->wait, nxt_out_done(nxt, x))) {
		/*
		 * Its completion runs before usb_kill_urb() returns and
		 * finishes @x with -EINTR if the kill stopped it. If the
		 * brick took the telegram first, @x goes on: the caller is
		 * told it was sent, and its reply is still to be read.
		 */
		usb_kill_urb(urb);
		spin_lock_irq(&nxt->lock);
		if (x->status == -EINPROGRESS && !x->delivered)
			nxt_finish(nxt, x, -EINTR);
		spin_unlock_irq(&nxt->lock);
	}

	/*
	 * Once the brick has the telegram, sending it succeeded, whatever
	 * became of its reply meanwhile (a bad one, an IN stall): that is
	 * nxt_xfer_wait()'s to report. A caller told otherwise would send
	 * again a command the brick has run.
	 */
	spin_lock_irq(&nxt->lock);
	x->urb = NULL;
	ret = x->status == -EINPROGRESS || x->delivered ? 0 : x->status;
	spin_unlock_irq(&nxt->lock);
	usb_free_urb(urb);
	return ret;
}

/**
 * nxt_xfer_start() - send a telegram
 * @nxt: the brick
 * @x: the transaction, owned by the caller (see nxt_usb.h)
 * @tg: the telegram
 * @len: its length
 * @timeout_ms: time from now within which the reply must have arrived
 * @nonblock: fail with -%EAGAIN instead of waiting for the brick to be free
 *
 * Claims the brick's slot and sends @tg. Returns once the telegram has been
 * sent; its reply, if its type asks for one, arrives in @x later (see
 * nxt_xfer_wait()), and so does its error if the reply was judged before
 * this returned: once the brick has the telegram, this returns 0.
 *
 * Return: 0, or -%EINVAL / -%EMSGSIZE for a bad telegram, -%EAGAIN
 * (@nonblock: the brick is busy, a late reply is being drained or a reset
 * is under way; nothing was sent), -%ERESTARTSYS (a signal before anything
 * was sent), -%EINTR (a signal while the telegram was being sent), -%ENODEV,
 * -%ENOMEM, -%ETIMEDOUT if the brick did not take the telegram in time,
 * -%EPIPE if it stalled, -%EIO.
 */
int nxt_xfer_start(struct nxt_usb *nxt, struct nxt_xfer *x, const u8 *tg,
		   size_t len, unsigned int timeout_ms, bool nonblock)
{
	return nxt_xfer_run(nxt, x, tg, len, timeout_ms, nonblock, false);
}

/**
 * nxt_xfer_wait() - wait for a started transaction to finish
 * @nxt: the brick
 * @x: a transaction nxt_xfer_start() started
 * @nonblock: return -%EAGAIN instead of waiting
 *
 * Return: 0 when the reply is in @x, -%EAGAIN, -%ERESTARTSYS (the transaction
 * goes on), or the transaction's error: -%ETIMEDOUT, -%EPROTO, -%EPIPE,
 * -%ENODEV, -%EIO, -%EINTR.
 */
int nxt_xfer_wait(struct nxt_usb *nxt, struct nxt_xfer *x, bool nonblock)
{
	int status;

	if (nonblock) {
		if (!nxt_xfer_done(nxt, x))
			return -EAGAIN;
	} else if (wait_event_interruptible(x->wait, nxt_xfer_done(nxt, x))) {
		return -ERESTARTSYS;
	}
	spin_lock_irq(&nxt->lock);
	status = x->status;
	spin_unlock_irq(&nxt->lock);
	return status;
}

/**
 * nxt_xfer_cancel() - stop waiting for a transaction's reply
 * @nxt: the brick
 * @x: a transaction nxt_xfer_start() started
 *
 * Frees the slot if @x still holds it; a reply that comes later is drained.
 * @x may be freed after this.
 */
void nxt_xfer_cancel(struct nxt_usb *nxt, struct nxt_xfer *x)
{
	spin_lock_irq(&nxt->lock);
	if (x->status == -EINPROGRESS)
		nxt_finish(nxt, x, -EINTR);
	spin_unlock_irq(&nxt->lock);
}

/**
 * nxt_transact() - send a telegram and wait for its reply
 * @nxt: the brick
 * @x: the transaction, owned by the caller; the reply is in it on success
 * @tg: the telegram
 * @len: its length
 * @timeout_ms: reply timeout
 * @nonblock: fail with -%EAGAIN if the brick is busy
 *
 * Return: 0, or an error of nxt_xfer_start() or nxt_xfer_wait() (-%EINTR
 * when a signal came while the reply was awaited).
 */
int nxt_transact(struct nxt_usb *nxt, struct nxt_xfer *x, const u8 *tg,
		 size_t len, unsigned int timeout_ms, bool nonblock)
{
	int ret;

	ret = nxt_xfer_run(nxt, x, tg, len, timeout_ms, nonblock, true);
	if (ret || !x->want_reply)
		return ret;
	/* Not finished yet: a signal ended the wait. */
	ret = nxt_xfer_wait(nxt, x, true);
	if (ret == -EAGAIN) {
		nxt_xfer_cancel(nxt, x);
		ret = -EINTR;
	}
	return ret;
}

static void nxt_usb_free(struct kref *kref)
{
	struct nxt_usb *nxt = container_of(kref, struct nxt_usb, kref);

	/* A drain that a last transaction started after disconnect(). */
	cancel_delayed_work_sync(&nxt->drain_work);
	usb_free_urb(nxt->in_urb);
	kfree(nxt->in_buf);
	usb_put_dev(nxt->udev);
	kfree(nxt);
}

/**
 * nxt_usb_get() - take a reference to a brick
 * @nxt: the brick
 */
void nxt_usb_get(struct nxt_usb *nxt)
{
	kref_get(&nxt->kref);
}

/**
 * nxt_usb_put() - drop a reference to a brick
 * @nxt: the brick
 */
void nxt_usb_put(struct nxt_usb *nxt)
{
	kref_put(&nxt->kref, nxt_usb_free);
}

/*
 * Ends the transaction in the slot with @err and stops every transfer.
 * A transaction whose telegram is not sent yet (it waits for @io_mutex)
 * is left alone: it goes after a reset, and fails by itself after a
 * suspend or a disconnect. @io_mutex held.
 */
static void nxt_stop_io(struct nxt_usb *nxt, int err)
{
	lockdep_assert_held(&nxt->io_mutex);
	spin_lock_irq(&nxt->lock);
	if (nxt->cur && nxt->cur->sent && nxt->cur->status == -EINPROGRESS)
		nxt_finish(nxt, nxt->cur, err);
	spin_unlock_irq(&nxt->lock);
	usb_kill_anchored_urbs(&nxt->out_anchor);
	usb_kill_urb(nxt->in_urb);
}

/* Whether a sent transaction is still waiting for its reply. */
static bool nxt_in_flight(struct nxt_usb *nxt)
{
	bool busy;

	spin_lock_irq(&nxt->lock);
	busy = nxt->cur && nxt->cur->sent && nxt->cur->status == -EINPROGRESS;
	spin_unlock_irq(&nxt->lock);
	return busy;
}

/*
 * debugfs lego_nxt_usb/USBDEV/counters: the brick's counters (struct
 * nxt_stats), one "name value" a line.
 */
static int nxt_counters_show(struct seq_file *m, void *unused)
{
	struct nxt_usb *nxt = m->private;
	struct nxt_stats st;

	spin_lock_irq(&nxt->lock);
	st = nxt->stats;
	spin_unlock_irq(&nxt->lock);

	seq_printf(m, "telegrams %llu\n", st.telegrams);
	seq_printf(m, "replies %llu\n", st.replies);
	seq_printf(m, "transactions %llu\n", st.transactions);
	seq_printf(m, "ok %llu\n", st.ok);
	seq_printf(m, "err_timedout %llu\n", st.err_timedout);
	seq_printf(m, "err_proto %llu\n", st.err_proto);
	seq_printf(m, "err_pipe %llu\n", st.err_pipe);
	seq_printf(m, "err_io %llu\n", st.err_io);
	seq_printf(m, "err_nodev %llu\n", st.err_nodev);
	seq_printf(m, "err_intr %llu\n", st.err_intr);
	seq_printf(m, "err_other %llu\n", st.err_other);
	seq_printf(m, "stalls_in %llu\n", st.stalls_in);
	seq_printf(m, "stalls_out %llu\n", st.stalls_out);
	seq_printf(m, "drains %llu\n", st.drains);
	seq_printf(m, "drained %llu\n", st.drained);
	seq_printf(m, "stale %llu\n", st.stale);
	seq_printf(m, "mismatched %llu\n", st.mismatched);
	seq_printf(m, "resets %llu\n", st.resets);
	return 0;
}
DEFINE_SHOW_ATTRIBUTE(nxt_counters);

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
	if (usb_endpoint_maxp(in) < NXT_TELEGRAM_MAX ||
	    usb_endpoint_maxp(out) < NXT_TELEGRAM_MAX) {
		dev_err(&intf->dev, "bulk endpoints smaller than a telegram\n");
		return -ENODEV;
	}

	nxt = kzalloc(sizeof(*nxt), GFP_KERNEL);
	if (!nxt)
		return -ENOMEM;
	kref_init(&nxt->kref);
	mutex_init(&nxt->io_mutex);
	spin_lock_init(&nxt->lock);
	INIT_LIST_HEAD(&nxt->queue);
	init_waitqueue_head(&nxt->wait);
	init_usb_anchor(&nxt->out_anchor);
	timer_setup(&nxt->timer, nxt_timer_fn, 0);
	INIT_DELAYED_WORK(&nxt->recover_work, nxt_recover_work);
	INIT_DELAYED_WORK(&nxt->drain_work, nxt_drain_work);
	nxt_info_init(&nxt->info);
	nxt->udev = usb_get_dev(interface_to_usbdev(intf));
	nxt->intf = intf;
	nxt->out_pipe = usb_sndbulkpipe(nxt->udev, usb_endpoint_num(out));
	nxt->in_pipe = usb_rcvbulkpipe(nxt->udev, usb_endpoint_num(in));

	nxt->in_urb = usb_alloc_urb(0, GFP_KERNEL);
	nxt->in_buf = kmalloc(NXT_TELEGRAM_MAX, GFP_KERNEL);
	if (!nxt->in_urb || !nxt->in_buf) {
		ret = -ENOMEM;
		goto err_put;
	}
	/* Exactly one packet: the brick sends no zero-length packet after 64 bytes. */
	usb_fill_bulk_urb(nxt->in_urb, nxt->udev, nxt->in_pipe, nxt->in_buf,
			  NXT_TELEGRAM_MAX, nxt_in_complete, nxt);
	usb_set_intfdata(intf, nxt);

	ret = usb_register_dev(intf, &nxt_usb_class);
	if (ret) {
		dev_err(&intf->dev, "cannot get a minor: %d\n", ret);
		usb_set_intfdata(intf, NULL);
		goto err_put;
	}

	nxt->debugfs = debugfs_create_dir(nxt_name(nxt), nxt_debugfs_root);
	debugfs_create_file("counters", 0400, nxt->debugfs, nxt,
			    &nxt_counters_fops);

	/* Nothing is sent to the brick until someone opens it or reads sysfs. */
	dev_info(&intf->dev, "LEGO NXT brick %s now at %s\n",
		 nxt->udev->serial ?: "(no serial)", dev_name(intf->usb_dev));
	return 0;

err_put:
	nxt_usb_put(nxt);
	return ret;
}

static void nxt_usb_disconnect(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);
	struct nxt_xfer *x;

	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_DISCONNECT);
	debugfs_remove_recursive(nxt->debugfs);
	/* No new opens; then no new transfers; then none in flight. */
	usb_deregister_dev(intf, &nxt_usb_class);

	mutex_lock(&nxt->io_mutex);
	nxt->intf = NULL;
	spin_lock_irq(&nxt->lock);
	nxt->gone = true;
	if (nxt->cur && nxt->cur->status == -EINPROGRESS)
		nxt_finish(nxt, nxt->cur, -ENODEV);
	/* Those waiting for the slot see @gone (nxt_claim()). */
	list_for_each_entry(x, &nxt->queue, queue)
		wake_up(&x->wait);
	spin_unlock_irq(&nxt->lock);
	/* Poisoned: a completion or a late work item cannot resubmit them. */
	usb_poison_anchored_urbs(&nxt->out_anchor);
	usb_poison_urb(nxt->in_urb);
	mutex_unlock(&nxt->io_mutex);

	cancel_delayed_work_sync(&nxt->recover_work);
	cancel_delayed_work_sync(&nxt->drain_work);
	timer_delete_sync(&nxt->timer);
	wake_up_all(&nxt->wait);

	usb_set_intfdata(intf, NULL);
	dev_info(&intf->dev, "LEGO NXT brick disconnected\n");
	nxt_usb_put(nxt);
}

/*
 * A USB reset (nxt-python resets the brick before using it) keeps the
 * driver bound: transfers stop in pre_reset() and start again in
 * post_reset(), and @io_mutex is held in between. A transaction in flight
 * fails with -EIO, since its reply is lost; one that holds the slot but
 * has not sent its telegram yet sends it after the reset.
 */
/* A reset cleared the endpoints' halts: none is left to clear. */
static void nxt_forget_halts(struct nxt_usb *nxt)
{
	spin_lock_irq(&nxt->lock);
	nxt->halted_in = false;
	nxt->halted_out = false;
	nxt->stalls = 0;
	spin_unlock_irq(&nxt->lock);
}

static int nxt_usb_pre_reset(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_PRE_RESET);
	mutex_lock(&nxt->io_mutex);
	nxt->suspended = true;
	nxt_stop_io(nxt, -EIO);
	return 0;
}

static int nxt_usb_post_reset(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_POST_RESET);
	spin_lock_irq(&nxt->lock);
	nxt->stats.resets++;
	spin_unlock_irq(&nxt->lock);
	nxt_forget_halts(nxt);
	nxt->suspended = false;
	nxt_info_invalidate(&nxt->info, true);
	nxt_reader_start_locked(nxt);
	mutex_unlock(&nxt->io_mutex);
	return 0;
}

/*
 * Nothing new is sent once @suspended is set; the transaction in flight
 * gets up to NXT_SUSPEND_WAIT_MS to finish (the brick answers within a few
 * milliseconds), and fails with -EIO after that. An autosuspend does not
 * interrupt one at all.
 */
static int nxt_usb_suspend(struct usb_interface *intf, pm_message_t message)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_SUSPEND);
	mutex_lock(&nxt->io_mutex);
	if (PMSG_IS_AUTO(message) && (nxt_in_flight(nxt) || !nxt_slot_free(nxt))) {
		mutex_unlock(&nxt->io_mutex);
		return -EBUSY;
	}
	nxt->suspended = true;
	if (!wait_event_timeout(nxt->wait, !nxt_in_flight(nxt),
				msecs_to_jiffies(NXT_SUSPEND_WAIT_MS)))
		dev_warn(&intf->dev, "suspended with a transaction in flight\n");
	nxt_stop_io(nxt, -EIO);
	mutex_unlock(&nxt->io_mutex);
	return 0;
}

static int nxt_usb_resume(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);
	int ret;

	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_RESUME);
	mutex_lock(&nxt->io_mutex);
	nxt->suspended = false;
	ret = nxt_reader_start_locked(nxt);
	mutex_unlock(&nxt->io_mutex);
	return ret;
}

static int nxt_usb_reset_resume(struct usb_interface *intf)
{
	struct nxt_usb *nxt = usb_get_intfdata(intf);

	/* The brick was reset: its endpoints are no longer halted. */
	trace_nxt_usb_reset(nxt_name(nxt), NXT_USB_TRACE_RESET_RESUME);
	nxt_forget_halts(nxt);
	nxt_info_invalidate(&nxt->info, true);
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

struct usb_driver nxt_usb_driver = {
	.name		= "lego_nxt_usb",
	.probe		= nxt_usb_probe,
	.disconnect	= nxt_usb_disconnect,
	.pre_reset	= nxt_usb_pre_reset,
	.post_reset	= nxt_usb_post_reset,
	.suspend	= nxt_usb_suspend,
	.resume		= nxt_usb_resume,
	.reset_resume	= nxt_usb_reset_resume,
	.id_table	= nxt_usb_ids,
	.dev_groups	= nxt_groups,
};

static int __init nxt_usb_init(void)
{
	int ret;

	nxt_debugfs_root = debugfs_create_dir(KBUILD_MODNAME, NULL);
	ret = usb_register(&nxt_usb_driver);
	if (ret)
		debugfs_remove_recursive(nxt_debugfs_root);
	return ret;
}
module_init(nxt_usb_init);

static void __exit nxt_usb_exit(void)
{
	usb_deregister(&nxt_usb_driver);
	debugfs_remove_recursive(nxt_debugfs_root);
}
module_exit(nxt_usb_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS NXT brick USB driver");
MODULE_LICENSE("GPL");
