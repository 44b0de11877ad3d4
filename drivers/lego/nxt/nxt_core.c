// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: the transaction engine (see nxt_core.h).
 *
 * One telegram out, its reply (if its type asks for one) in, one brick at a
 * time and whatever the link: the transport only sends, receives and says
 * when it did. The engine owns the slot and its queue, the timeouts, the
 * drain of late replies, the brick's counters and what its replies say
 * about it. Telegram validation lives in nxt_proto.c.
 */
#include <linux/debugfs.h>
#include <linux/device.h>
#include <linux/err.h>
#include <linux/errno.h>
#include <linux/jiffies.h>
#include <linux/sched/signal.h>
#include <linux/seq_file.h>
#include <linux/slab.h>
#include <linux/string.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_usb_trace.h"

/*
 * Drains packets for @ms from now, unless a drain already lasts longer.
 * The drain clock is 64-bit jiffies: a drain that ended weeks ago on a
 * 32-bit machine stays ended. @lock held.
 */
static void nxt_drain_for(struct nxt_brick *b, unsigned int ms)
{
	u64 until = get_jiffies_64() + msecs_to_jiffies(ms);

	lockdep_assert_held(&b->lock);
	if (until <= b->drain_until)
		return;
	b->drain_until = until;
	b->stats.drains++;
	trace_nxt_usb_drain(b->name, ms, b->orphan, b->orphan_op);
	/* Nothing else may happen when it ends: poll() is woken then. */
	mod_delayed_work(system_percpu_wq, &b->drain_work, msecs_to_jiffies(ms) + 1);
}

/* The drain has ended (or ended early): writers and poll() may go on. */
static void nxt_drain_work(struct work_struct *work)
{
	struct nxt_brick *b = container_of(to_delayed_work(work), struct nxt_brick,
					   drain_work);

	wake_up_all(&b->wait);
}

/* Jiffies left of the drain; 0 when none. @lock held. */
static unsigned long nxt_drain_left(struct nxt_brick *b)
{
	lockdep_assert_held(&b->lock);
	return nxt_time_left(get_jiffies_64(), b->drain_until,
			     msecs_to_jiffies(NXT_SLOW_REPLY_MS));
}

static bool nxt_draining(struct nxt_brick *b)
{
	unsigned long left;

	spin_lock_irq(&b->lock);
	left = nxt_drain_left(b);
	spin_unlock_irq(&b->lock);
	return left;
}

/*
 * @x, which was sent, ended without its reply: the reply may still be on
 * its way, or queued in the brick. If the brick took the telegram, the
 * drain waits for the reply to its opcode (nxt_reply_late_ms()) and ends
 * when it comes; else it lasts NXT_DRAIN_MS. @lock held.
 */
static void nxt_orphan(struct nxt_brick *b, struct nxt_xfer *x)
{
	if (!x->delivered) {
		nxt_drain_for(b, NXT_DRAIN_MS);
		return;
	}
	b->orphan = true;
	b->orphan_op = x->tg[1];
	nxt_drain_for(b, nxt_reply_late_ms(x->tg, x->len));
}

/*
 * The slot is free, or the first in line changed: wakes the first in line,
 * the only one that may claim it (nxt_claim()). @lock held.
 */
static void nxt_wake_next(struct nxt_brick *b)
{
	struct nxt_xfer *next;

	lockdep_assert_held(&b->lock);
	if (b->cur)
		return;
	next = list_first_entry_or_null(&b->queue, struct nxt_xfer, queue);
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
static void nxt_finish(struct nxt_brick *b, struct nxt_xfer *x, int status)
{
	lockdep_assert_held(&b->lock);
	x->status = status;
	nxt_count_end(&b->stats, status);
	trace_nxt_usb_done(b->name, x, x->tg[1], status);
	if (b->cur == x) {
		b->cur = NULL;
		timer_delete(&b->timer);
		nxt_wake_next(b);
	}
	/* A telegram never sent has no reply to wait for. */
	if (status && x->want_reply && x->sent)
		nxt_orphan(b, x);
	wake_up(&x->wait);
	/* poll() and suspend; nobody else sleeps there. */
	wake_up_all(&b->wait);
}

/* A packet that came while draining: dropped; it may end the drain. @lock held. */
static void nxt_drain_packet(struct nxt_brick *b, const u8 *buf, unsigned int len)
{
	bool end;

	dev_dbg_ratelimited(b->dev, "dropped a stale packet (%u bytes)\n", len);
	b->stats.drained++;
	/*
	 * Replies come in the order of their commands, and the last command
	 * that lost its reply was sent last: once its reply is in, nothing
	 * stale is left to come.
	 */
	end = b->orphan && len >= 2 && buf[0] == NXT_REPLY && buf[1] == b->orphan_op;
	trace_nxt_usb_drop(b->name, NXT_USB_TRACE_DRAIN, buf, len, end);
	if (end) {
		b->orphan = false;
		b->drain_until = get_jiffies_64();
		wake_up_all(&b->wait);
	}
}

/**
 * nxt_brick_rx() - a packet from the brick
 * @b: the brick
 * @buf: the packet
 * @len: its length, at most NXT_TELEGRAM_MAX
 *
 * The awaited reply ends the transaction in the slot; anything else is
 * dropped. Called with @b->lock held, from any context.
 */
void nxt_brick_rx(struct nxt_brick *b, const u8 *buf, unsigned int len)
{
	struct nxt_xfer *x = b->cur;
	int ret;

	lockdep_assert_held(&b->lock);
	if (nxt_drain_left(b)) {
		nxt_drain_packet(b, buf, len);
		return;
	}
	b->orphan = false;
	/* Until its telegram is sent, nothing can answer a transaction. */
	if (!x || !x->sent || !x->want_reply || x->status != -EINPROGRESS) {
		dev_dbg_ratelimited(b->dev, "dropped a stale packet (%u bytes)\n", len);
		b->stats.stale++;
		trace_nxt_usb_drop(b->name, NXT_USB_TRACE_STALE, buf, len, false);
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
		b->stats.mismatched++;
		trace_nxt_usb_drop(b->name, NXT_USB_TRACE_MISMATCH, buf, len, false);
		dev_dbg_ratelimited(b->dev,
				    "packet %*ph... (%u bytes) does not answer opcode 0x%02x\n",
				    min(len, 4U), buf, len, x->tg[1]);
		return;
	}
	memcpy(x->reply, buf, len);
	x->reply_len = len;
	nxt_info_note_reply(&b->info, x->tg, x->len, buf, len);
	b->stats.replies++;
	trace_nxt_usb_rx(b->name, x, buf[0], buf[1], len > 2 ? buf[2] : 0, len);
	nxt_finish(b, x, 0);
}
EXPORT_SYMBOL_GPL(nxt_brick_rx);

/**
 * nxt_brick_in_stalled() - the brick refused to send (an IN stall)
 * @b: the brick
 *
 * The transaction waiting for its reply fails with -%EPIPE; one not sent
 * yet sends its telegram once the transport has recovered. @b->lock held.
 */
void nxt_brick_in_stalled(struct nxt_brick *b)
{
	lockdep_assert_held(&b->lock);
	if (b->cur && b->cur->sent && b->cur->want_reply &&
	    b->cur->status == -EINPROGRESS)
		nxt_finish(b, b->cur, -EPIPE);
}
EXPORT_SYMBOL_GPL(nxt_brick_in_stalled);

/**
 * nxt_brick_link_error() - a receive failed, perhaps an unplug under way
 * @b: the brick
 *
 * The transaction waiting for its reply gets NXT_UNPLUG_GRACE_MS past its
 * deadline for the transport to report the unplug, and ends with -%EIO
 * then. @b->lock held.
 */
void nxt_brick_link_error(struct nxt_brick *b)
{
	lockdep_assert_held(&b->lock);
	if (b->cur && b->cur->sent)
		b->cur->link_error = true;
}
EXPORT_SYMBOL_GPL(nxt_brick_link_error);

/**
 * nxt_brick_rx_started() - the transport started receiving
 * @b: the brick
 *
 * Whatever the brick still holds from before is stale: drained for
 * NXT_DRAIN_MS. @b->lock held.
 */
void nxt_brick_rx_started(struct nxt_brick *b)
{
	lockdep_assert_held(&b->lock);
	nxt_drain_for(b, NXT_DRAIN_MS);
}
EXPORT_SYMBOL_GPL(nxt_brick_rx_started);

/**
 * nxt_brick_sent() - a send ended
 * @b: the brick
 * @x: its transaction
 * @err: 0 if the brick has the telegram, else why not: -%EPIPE (a stall),
 *	-%ENODEV (unplugged), -%EINTR (stopped by nxt_transport_ops.unlink or
 *	.kill), -%EIO
 *
 * Any context, no lock held. The last touch of @x by the transport.
 */
void nxt_brick_sent(struct nxt_brick *b, struct nxt_xfer *x, int err)
{
	unsigned long flags;

	spin_lock_irqsave(&b->lock, flags);
	/* The brick has the telegram, even if it was late (timed out). */
	x->delivered = !err;
	if (x->status == -EINPROGRESS) {
		if (err && !x->timed_out && err != -EINTR)
			dev_warn_ratelimited(b->dev, "sending opcode 0x%02x failed: %d\n",
					     x->tg[1], err);
		/*
		 * Timed out: even if the unlink came too late to stop the
		 * send, the deadline has passed and the timer is done.
		 */
		if (err || x->timed_out)
			nxt_finish(b, x, x->timed_out ? -ETIMEDOUT : err);
		else if (!x->want_reply)
			nxt_finish(b, x, 0);
	}
	/* The last touch of @x: its owner may free it once it sees this. */
	x->out_done = true;
	/* An owner waiting for the reply too is woken when it comes. */
	if (!x->reply_wait || x->status != -EINPROGRESS)
		wake_up(&x->wait);
	spin_unlock_irqrestore(&b->lock, flags);
}
EXPORT_SYMBOL_GPL(nxt_brick_sent);

/* The transaction in the slot is out of time. */
static void nxt_timer_fn(struct timer_list *t)
{
	struct nxt_brick *b = timer_container_of(b, t, timer);
	struct nxt_xfer *x;
	unsigned long flags;
	void *unlink = NULL;

	spin_lock_irqsave(&b->lock, flags);
	x = b->cur;
	/* A timer meant for an earlier transaction cannot end one not yet sent. */
	if (x && x->sent && x->status == -EINPROGRESS) {
		if (time_before(jiffies, x->deadline)) {
			mod_timer(&b->timer, x->deadline);
		} else if (!x->out_done) {
			/* The brick did not take the telegram: stop the send. */
			trace_nxt_usb_timeout(b->name, x, x->tg[1], "telegram not taken");
			x->timed_out = true;
			unlink = x->handle;
			if (unlink)
				b->ops->get(unlink);
		} else if (x->link_error && !x->grace_used) {
			x->grace_used = true;
			x->deadline = jiffies + msecs_to_jiffies(NXT_UNPLUG_GRACE_MS);
			mod_timer(&b->timer, x->deadline);
		} else {
			trace_nxt_usb_timeout(b->name, x, x->tg[1],
					      x->link_error ? "transfer errors, no reply" :
					      x->saw_bad ? "malformed reply" : "no reply");
			dev_warn_ratelimited(b->dev, "%s reply to opcode 0x%02x\n",
					     x->link_error ? "transfer errors, no" :
					     x->saw_bad ? "malformed" : "no", x->tg[1]);
			nxt_finish(b, x, x->link_error ? -EIO :
					 x->saw_bad ? -EPROTO : -ETIMEDOUT);
		}
	}
	spin_unlock_irqrestore(&b->lock, flags);

	if (unlink) {
		b->ops->unlink(unlink);
		b->ops->put(unlink);
	}
}

/*
 * Claims the slot for @x, queued by nxt_enqueue(), once it is free and @x is
 * first in the queue. True when done (@x left the queue) or when the brick
 * is gone (@err).
 */
static bool nxt_claim(struct nxt_brick *b, struct nxt_xfer *x, int *err)
{
	bool done = true;

	spin_lock_irq(&b->lock);
	if (b->gone) {
		list_del_init(&x->queue);
		*err = -ENODEV;
	} else if (!b->cur && list_first_entry(&b->queue, struct nxt_xfer, queue) == x) {
		list_del_init(&x->queue);
		b->cur = x;
		x->status = -EINPROGRESS;
		*err = 0;
	} else {
		done = false;
	}
	spin_unlock_irq(&b->lock);
	return done;
}

/* Puts @x at the end of the queue for the slot. */
static void nxt_enqueue(struct nxt_brick *b, struct nxt_xfer *x)
{
	spin_lock_irq(&b->lock);
	list_add_tail(&x->queue, &b->queue);
	spin_unlock_irq(&b->lock);
}

/* Takes @x, interrupted, out of the queue: the next in line may go. */
static void nxt_dequeue(struct nxt_brick *b, struct nxt_xfer *x)
{
	spin_lock_irq(&b->lock);
	list_del_init(&x->queue);
	nxt_wake_next(b);
	spin_unlock_irq(&b->lock);
	wake_up_all(&b->wait);
}

/**
 * nxt_xfer_done() - whether a transaction has finished
 * @b: the brick
 * @x: the transaction
 *
 * Return: true once @x has finished (or was never started).
 */
bool nxt_xfer_done(struct nxt_brick *b, struct nxt_xfer *x)
{
	bool done;

	spin_lock_irq(&b->lock);
	done = x->status != -EINPROGRESS;
	spin_unlock_irq(&b->lock);
	return done;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_xfer_done);

/*
 * Whether the send of @x has ended and, if its owner waits for the reply
 * too (@reply_wait), whether @x has finished.
 */
static bool nxt_out_done(struct nxt_brick *b, struct nxt_xfer *x)
{
	bool done;

	spin_lock_irq(&b->lock);
	done = x->out_done && (!x->reply_wait || x->status != -EINPROGRESS);
	spin_unlock_irq(&b->lock);
	return done;
}

/**
 * nxt_slot_free() - whether a telegram could be sent now
 * @b: the brick
 *
 * Return: true if no transaction holds the brick or waits for it, and no
 * late reply is being drained.
 */
bool nxt_slot_free(struct nxt_brick *b)
{
	bool free;

	spin_lock_irq(&b->lock);
	free = !b->cur && list_empty(&b->queue) && !nxt_drain_left(b);
	spin_unlock_irq(&b->lock);
	return free;
}
EXPORT_SYMBOL_GPL(nxt_slot_free);

/**
 * nxt_gone() - whether the brick has been disconnected
 * @b: the brick
 *
 * Return: true once nxt_brick_disconnect() has run.
 */
bool nxt_gone(struct nxt_brick *b)
{
	bool gone;

	spin_lock_irq(&b->lock);
	gone = b->gone;
	spin_unlock_irq(&b->lock);
	return gone;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_gone);

/**
 * nxt_brick_info() - what the brick last said about itself
 * @b: the brick
 * @info: a copy, taken under @b->lock
 */
void nxt_brick_info(struct nxt_brick *b, struct nxt_brick_info *info)
{
	spin_lock_irq(&b->lock);
	*info = b->info;
	spin_unlock_irq(&b->lock);
}
EXPORT_SYMBOL_IF_KUNIT(nxt_brick_info);

/*
 * Waits until no packet is being drained. Nothing was sent: interrupted, it
 * asks for the call to be restarted.
 */
static int nxt_drain_wait(struct nxt_brick *b, bool nonblock)
{
	unsigned long left;
	long ret;

	for (;;) {
		spin_lock_irq(&b->lock);
		left = nxt_drain_left(b);
		spin_unlock_irq(&b->lock);
		if (!left)
			return 0;
		if (nonblock)
			return -EAGAIN;
		ret = wait_event_interruptible_timeout(b->wait,
						       !nxt_draining(b) || nxt_gone(b),
						       left);
		if (ret < 0)
			return -ERESTARTSYS;
		if (nxt_gone(b))
			return -ENODEV;
	}
}

/* Takes @tx_lock for a transaction; -EAGAIN rather than wait if @nonblock. */
static int nxt_tx_lock(struct nxt_brick *b, bool nonblock)
{
	if (nonblock)
		return mutex_trylock(&b->tx_lock) ? 0 : -EAGAIN;
	return mutex_lock_interruptible(&b->tx_lock) ? -ERESTARTSYS : 0;
}

/*
 * Hands the telegram of @x, which holds the slot, to the transport. @x is
 * live (can be answered, timed out, or failed by a reset) from here on
 * only: the timer is armed once the send has started, so that its unlink
 * cannot miss it. @tx_lock held.
 */
static int nxt_submit(struct nxt_brick *b, struct nxt_xfer *x, unsigned int timeout_ms)
{
	void *handle;
	int ret = 0;

	lockdep_assert_held(&b->tx_lock);
	spin_lock_irq(&b->lock);
	if (x->status != -EINPROGRESS) {
		/* Failed while it waited (the brick went away). */
		ret = x->status;
		spin_unlock_irq(&b->lock);
		return ret;
	}
	x->sent = true;
	x->deadline = jiffies + msecs_to_jiffies(timeout_ms);
	spin_unlock_irq(&b->lock);

	handle = b->ops->send(b, x);
	spin_lock_irq(&b->lock);
	if (IS_ERR(handle)) {
		ret = PTR_ERR(handle);
		x->sent = false;
	} else {
		/* The engine's reference, dropped by nxt_xfer_run(). */
		x->handle = handle;
		if (b->cur == x && x->status == -EINPROGRESS)
			mod_timer(&b->timer, x->deadline);
		b->stats.telegrams++;
		nxt_info_note_sent(&b->info, x->tg, x->len);
	}
	trace_nxt_usb_tx(b->name, x, x->tg[0], x->tg[1], x->len, ret);
	spin_unlock_irq(&b->lock);
	if (ret)
		dev_err_ratelimited(b->dev, "cannot send a telegram: %d\n", ret);
	return ret;
}

/* Sends the telegram of @x, which holds the slot. */
static int nxt_send(struct nxt_brick *b, struct nxt_xfer *x, unsigned int timeout_ms,
		    bool nonblock)
{
	int ret;

	/* Let stale packets come and be dropped before this telegram goes. */
	ret = nxt_drain_wait(b, nonblock);
	if (ret)
		return ret;
	/* Held across a reset of the link: O_NONBLOCK does not wait for one. */
	ret = nxt_tx_lock(b, nonblock);
	if (ret)
		return ret;
	if (!b->present) {
		ret = -ENODEV;
		goto out;
	}
	if (b->paused) {
		ret = -EIO;
		goto out;
	}
	/*
	 * An error of the last transaction may not be dealt with yet (a USB
	 * stall, say, whose recovery would otherwise run after this telegram
	 * has gone and clear the stall the brick sets instead of this
	 * telegram's reply): the transport makes the link ready first.
	 */
	ret = b->ops->start(b);
	if (ret)
		goto out;
	/* A receiver (re)started just now drains too. */
	ret = nxt_drain_wait(b, nonblock);
	if (ret)
		goto out;
	ret = nxt_submit(b, x, timeout_ms);
out:
	mutex_unlock(&b->tx_lock);
	return ret;
}

/* Sets up @x for @tg; -EINVAL or -EMSGSIZE for a bad telegram. */
static int nxt_xfer_init(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
			 size_t len, bool reply_wait)
{
	int want;

	want = nxt_telegram_check(tg, len);
	if (want < 0)
		return want;

	/* poll() reads @x->status under @lock alone: write it under @lock. */
	spin_lock_irq(&b->lock);
	memset(x, 0, sizeof(*x));
	x->brick = b;
	INIT_LIST_HEAD(&x->queue);
	init_waitqueue_head(&x->wait);
	memcpy(x->tg, tg, len);
	x->len = len;
	x->want_reply = want;
	x->reply_wait = reply_wait && want;
	spin_unlock_irq(&b->lock);
	return 0;
}

/* Waits for the slot, first come first; -EAGAIN at once if @nonblock. */
static int nxt_wait_slot(struct nxt_brick *b, struct nxt_xfer *x, bool nonblock)
{
	int err = 0;

	nxt_enqueue(b, x);
	if (nonblock) {
		if (!nxt_claim(b, x, &err)) {
			nxt_dequeue(b, x);
			err = -EAGAIN;
		}
	} else if (wait_event_interruptible(x->wait, nxt_claim(b, x, &err))) {
		nxt_dequeue(b, x);
		err = -ERESTARTSYS;
	}
	return err;
}

/*
 * Waits for the send of @x to end (and with @reply_wait, for its reply).
 * A signal stops a send the brick has not taken yet: @x ends with -EINTR.
 * If the brick took the telegram first, @x goes on: the caller is told it
 * was sent, and its reply is still to be read.
 */
static void nxt_wait_sent(struct nxt_brick *b, struct nxt_xfer *x)
{
	if (!wait_event_interruptible(x->wait, nxt_out_done(b, x)))
		return;
	/* The send ends (nxt_brick_sent()) before kill() returns. */
	b->ops->kill(x->handle);
	spin_lock_irq(&b->lock);
	if (x->status == -EINPROGRESS && !x->delivered)
		nxt_finish(b, x, -EINTR);
	spin_unlock_irq(&b->lock);
}

/*
 * nxt_xfer_start(), and with @reply_wait the reply's wait of nxt_transact()
 * too: then it returns once the reply has come as well (or a signal, which
 * ends the wait but not the transaction), so that its owner sleeps once per
 * transaction.
 */
static int nxt_xfer_run(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
			size_t len, unsigned int timeout_ms, bool nonblock,
			bool reply_wait)
{
	void *handle;
	int ret;

	ret = nxt_xfer_init(b, x, tg, len, reply_wait);
	if (ret)
		return ret;
	ret = nxt_wait_slot(b, x, nonblock);
	if (ret)
		return ret;

	ret = nxt_send(b, x, timeout_ms, nonblock);
	if (ret) {
		spin_lock_irq(&b->lock);
		x->out_done = true;
		if (x->status == -EINPROGRESS)
			nxt_finish(b, x, ret);
		spin_unlock_irq(&b->lock);
		return ret;
	}
	nxt_wait_sent(b, x);

	/*
	 * Once the brick has the telegram, sending it succeeded, whatever
	 * became of its reply meanwhile (a bad one, a stall): that is
	 * nxt_xfer_wait()'s to report. A caller told otherwise would send
	 * again a command the brick has run.
	 */
	spin_lock_irq(&b->lock);
	handle = x->handle;
	x->handle = NULL;
	ret = x->status == -EINPROGRESS || x->delivered ? 0 : x->status;
	spin_unlock_irq(&b->lock);
	b->ops->put(handle);
	return ret;
}

/**
 * nxt_xfer_start() - send a telegram
 * @b: the brick
 * @x: the transaction, owned by the caller (see nxt_core.h)
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
int nxt_xfer_start(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
		   size_t len, unsigned int timeout_ms, bool nonblock)
{
	return nxt_xfer_run(b, x, tg, len, timeout_ms, nonblock, false);
}
EXPORT_SYMBOL_IF_KUNIT(nxt_xfer_start);

/**
 * nxt_xfer_wait() - wait for a started transaction to finish
 * @b: the brick
 * @x: a transaction nxt_xfer_start() started
 * @nonblock: return -%EAGAIN instead of waiting
 *
 * Return: 0 when the reply is in @x, -%EAGAIN, -%ERESTARTSYS (the transaction
 * goes on), or the transaction's error: -%ETIMEDOUT, -%EPROTO, -%EPIPE,
 * -%ENODEV, -%EIO, -%EINTR.
 */
int nxt_xfer_wait(struct nxt_brick *b, struct nxt_xfer *x, bool nonblock)
{
	int status;

	if (nonblock) {
		if (!nxt_xfer_done(b, x))
			return -EAGAIN;
	} else if (wait_event_interruptible(x->wait, nxt_xfer_done(b, x))) {
		return -ERESTARTSYS;
	}
	spin_lock_irq(&b->lock);
	status = x->status;
	spin_unlock_irq(&b->lock);
	return status;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_xfer_wait);

/**
 * nxt_xfer_cancel() - stop waiting for a transaction's reply
 * @b: the brick
 * @x: a transaction nxt_xfer_start() started
 *
 * Frees the slot if @x still holds it; a reply that comes later is drained.
 * @x may be freed after this.
 */
void nxt_xfer_cancel(struct nxt_brick *b, struct nxt_xfer *x)
{
	spin_lock_irq(&b->lock);
	if (x->status == -EINPROGRESS)
		nxt_finish(b, x, -EINTR);
	spin_unlock_irq(&b->lock);
}
EXPORT_SYMBOL_IF_KUNIT(nxt_xfer_cancel);

/**
 * nxt_transact() - send a telegram and wait for its reply
 * @b: the brick
 * @x: the transaction, owned by the caller; the reply is in it on success
 * @tg: the telegram
 * @len: its length
 * @timeout_ms: reply timeout
 * @nonblock: fail with -%EAGAIN if the brick is busy
 *
 * Return: 0, or an error of nxt_xfer_start() or nxt_xfer_wait() (-%EINTR
 * when a signal came while the reply was awaited).
 */
int nxt_transact(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
		 size_t len, unsigned int timeout_ms, bool nonblock)
{
	int ret;

	ret = nxt_xfer_run(b, x, tg, len, timeout_ms, nonblock, true);
	if (ret || !x->want_reply)
		return ret;
	/* Not finished yet: a signal ended the wait. */
	ret = nxt_xfer_wait(b, x, true);
	if (ret == -EAGAIN) {
		nxt_xfer_cancel(b, x);
		ret = -EINTR;
	}
	return ret;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_transact);

/**
 * nxt_brick_open() - a file was opened
 * @b: the brick
 *
 * The first open asks the transport to start receiving the brick's replies
 * (&nxt_transport_ops.open), without @b->tx_lock: a transport may have to
 * resume its link first.
 *
 * Return: 0, -%ERESTARTSYS (a signal while waiting: nothing was done, and
 * the open may be restarted), or the transport's error.
 */
int nxt_brick_open(struct nxt_brick *b)
{
	int ret = 0;

	if (mutex_lock_interruptible(&b->open_lock))
		return -ERESTARTSYS;
	if (!b->opens)
		ret = b->ops->open(b);
	if (!ret)
		b->opens++;
	mutex_unlock(&b->open_lock);
	return ret;
}
EXPORT_SYMBOL_IF_KUNIT(nxt_brick_open);

/**
 * nxt_brick_close() - a file opened by nxt_brick_open() was closed
 * @b: the brick
 *
 * The last close lets the transport stop receiving (&nxt_transport_ops.close).
 */
void nxt_brick_close(struct nxt_brick *b)
{
	mutex_lock(&b->open_lock);
	if (!WARN_ON_ONCE(!b->opens) && !--b->opens)
		b->ops->close(b);
	mutex_unlock(&b->open_lock);
}
EXPORT_SYMBOL_IF_KUNIT(nxt_brick_close);

/**
 * nxt_brick_fail() - end the transaction in flight
 * @b: the brick
 * @err: its error: -%EIO for a reset or a suspend
 *
 * A transaction whose telegram is not sent yet (it waits for @b->tx_lock)
 * is left alone: it goes after a reset, and fails by itself after a
 * suspend or a disconnect. @b->tx_lock held.
 */
void nxt_brick_fail(struct nxt_brick *b, int err)
{
	lockdep_assert_held(&b->tx_lock);
	spin_lock_irq(&b->lock);
	if (b->cur && b->cur->sent && b->cur->status == -EINPROGRESS)
		nxt_finish(b, b->cur, err);
	spin_unlock_irq(&b->lock);
}
EXPORT_SYMBOL_GPL(nxt_brick_fail);

/**
 * nxt_brick_in_flight() - whether a sent transaction awaits its reply
 * @b: the brick
 *
 * Return: true if so.
 */
bool nxt_brick_in_flight(struct nxt_brick *b)
{
	bool busy;

	spin_lock_irq(&b->lock);
	busy = b->cur && b->cur->sent && b->cur->status == -EINPROGRESS;
	spin_unlock_irq(&b->lock);
	return busy;
}
EXPORT_SYMBOL_GPL(nxt_brick_in_flight);

/**
 * nxt_brick_disconnect() - the link is gone for good
 * @b: the brick
 *
 * Every waiter wakes with -%ENODEV and nothing is sent any more. The
 * transport stops its transfers after this, and drops its reference.
 * Process context, @b->tx_lock held.
 */
void nxt_brick_disconnect(struct nxt_brick *b)
{
	struct nxt_xfer *x;

	lockdep_assert_held(&b->tx_lock);
	b->present = false;
	spin_lock_irq(&b->lock);
	b->gone = true;
	if (b->cur && b->cur->status == -EINPROGRESS)
		nxt_finish(b, b->cur, -ENODEV);
	/* Those waiting for the slot see @gone (nxt_claim()). */
	list_for_each_entry(x, &b->queue, queue)
		wake_up(&x->wait);
	spin_unlock_irq(&b->lock);
	wake_up_all(&b->wait);
}
EXPORT_SYMBOL_GPL(nxt_brick_disconnect);

/**
 * nxt_brick_shutdown() - after nxt_brick_disconnect(), once the transport
 *	has stopped its transfers: nothing of the engine runs any more
 * @b: the brick
 *
 * Process context, no lock held. Removes the debugfs directory.
 */
void nxt_brick_shutdown(struct nxt_brick *b)
{
	debugfs_remove_recursive(b->debugfs);
	b->debugfs = NULL;
	cancel_delayed_work_sync(&b->drain_work);
	timer_delete_sync(&b->timer);
	wake_up_all(&b->wait);
}
EXPORT_SYMBOL_GPL(nxt_brick_shutdown);

/*
 * debugfs lego_nxt/NAME/counters: the brick's counters (struct
 * nxt_stats), one "name value" a line.
 */
static int nxt_counters_show(struct seq_file *m, void *unused)
{
	struct nxt_brick *b = m->private;
	struct nxt_stats st;

	spin_lock_irq(&b->lock);
	st = b->stats;
	spin_unlock_irq(&b->lock);

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

/* lego_nxt in debugfs: a directory per brick, whatever its link. */
static struct dentry *nxt_debugfs_root;

/**
 * nxt_brick_debugfs() - show the brick's counters in debugfs
 * @b: the brick
 *
 * In lego_nxt/NAME/counters; the directory goes with nxt_brick_shutdown().
 */
void nxt_brick_debugfs(struct nxt_brick *b)
{
	if (IS_ERR_OR_NULL(nxt_debugfs_root))
		return;
	b->debugfs = debugfs_create_dir(b->name, nxt_debugfs_root);
	debugfs_create_file("counters", 0400, b->debugfs, b, &nxt_counters_fops);
}
EXPORT_SYMBOL_GPL(nxt_brick_debugfs);

static void nxt_brick_free(struct kref *kref)
{
	struct nxt_brick *b = container_of(kref, struct nxt_brick, kref);

	/* A drain that a last transaction started after the disconnect. */
	cancel_delayed_work_sync(&b->drain_work);
	b->ops->release(b);
}

/**
 * nxt_brick_get() - take a reference to a brick
 * @b: the brick
 */
void nxt_brick_get(struct nxt_brick *b)
{
	kref_get(&b->kref);
}
EXPORT_SYMBOL_GPL(nxt_brick_get);

/**
 * nxt_brick_put() - drop a reference to a brick
 * @b: the brick
 */
void nxt_brick_put(struct nxt_brick *b)
{
	kref_put(&b->kref, nxt_brick_free);
}
EXPORT_SYMBOL_GPL(nxt_brick_put);

/**
 * nxt_brick_init() - set up a brick for its transport
 * @b: the brick, zeroed, inside the transport's structure
 * @ops: the transport
 * @dev: the device that log lines name
 * @name: the name of the trace events and of the debugfs directory
 *
 * The brick is present, with one reference: the transport's.
 */
void nxt_brick_init(struct nxt_brick *b, const struct nxt_transport_ops *ops,
		    struct device *dev, const char *name)
{
	kref_init(&b->kref);
	b->ops = ops;
	b->dev = dev;
	strscpy(b->name, name, sizeof(b->name));
	mutex_init(&b->open_lock);
	mutex_init(&b->tx_lock);
	b->present = true;
	spin_lock_init(&b->lock);
	INIT_LIST_HEAD(&b->queue);
	init_waitqueue_head(&b->wait);
	timer_setup(&b->timer, nxt_timer_fn, 0);
	INIT_DELAYED_WORK(&b->drain_work, nxt_drain_work);
}
EXPORT_SYMBOL_GPL(nxt_brick_init);

/** nxt_core_debugfs_init() - make lego_nxt in debugfs (module init) */
void nxt_core_debugfs_init(void)
{
	nxt_debugfs_root = debugfs_create_dir(KBUILD_MODNAME, NULL);
}

/** nxt_core_debugfs_exit() - remove it (module exit, every brick gone) */
void nxt_core_debugfs_exit(void)
{
	debugfs_remove_recursive(nxt_debugfs_root);
}
