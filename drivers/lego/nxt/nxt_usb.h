/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT brick over USB: what the transport (nxt_usb.c), the
 * char device (nxt_cdev.c) and the sysfs attributes (nxt_sysfs.c) share.
 *
 * Transactions
 * ------------
 * The brick answers one command at a time and its replies carry no sequence
 * number, so a brick has one transaction slot, @cur: a transaction claims
 * it, sends its telegram, and holds it until its reply has arrived, its
 * timeout has passed or it was cancelled. Callers waiting for the slot get
 * it in the order they came (@queue), so no client of a busy brick starves.
 * Each transaction has a wait queue of its own: its owner is woken for its
 * own progress only, and a freed slot wakes only the first in line, so the
 * waiters of a busy brick are not all woken at every step of every
 * transaction.
 * A 64-byte IN transfer is kept pending from the first transaction on (the
 * "reader"), so the brick never freezes waiting for a host to collect a
 * reply; a packet that does not answer the transaction in the slot is
 * dropped as stale.
 *
 * A transaction is live (a packet can answer it, its timer end it, a reset
 * fail it) only from when its telegram is submitted (@sent), not from when
 * it takes the slot: until then it only waits for the drain and @io_mutex.
 * When the reader starts, packets are drained for NXT_DRAIN_MS before the
 * next telegram goes out; when a sent transaction ends without its reply,
 * for as long as that reply may come late (nxt_reply_late_ms()), or until
 * it has come.
 *
 * Locking
 * -------
 * @io_mutex (sleeping) serialises everything that submits URBs from process
 * context against disconnect, reset and suspend: @intf (NULL once the brick
 * is gone), @suspended and @reader_wanted. It is held by pre_reset() until
 * post_reset().
 *
 * @lock (spinlock, taken in URB completions and the timer) protects the
 * slot @cur and the state of the transaction in it, the @queue of waiters
 * for it, @reader_running, @drain_until, @orphan, @stalls, the halt flags,
 * @gone, @info and the reply hand-off. Every write of a transaction's
 * @status is made under it, its first (nxt_xfer_run()) included, since
 * poll() reads it without the open file's lock.
 * Order: @io_mutex, then @lock.
 *
 * Lifetime
 * --------
 * struct nxt_usb is reference counted: probe() holds one reference and each
 * open file one. A struct nxt_xfer belongs to its caller, which must not
 * free it before nxt_xfer_start() has returned and, if that succeeded, the
 * transaction has finished (nxt_xfer_wait()) or been cancelled
 * (nxt_xfer_cancel()).
 */
#ifndef _NXT_USB_H
#define _NXT_USB_H

#include <linux/kref.h>
#include <linux/list.h>
#include <linux/mutex.h>
#include <linux/spinlock.h>
#include <linux/timer.h>
#include <linux/types.h>
#include <linux/usb.h>
#include <linux/wait.h>
#include <linux/workqueue.h>
#include <linux/lego_nxt.h>

#include "nxt_proto.h"

/* Stale packets are drained this long after a timeout or a (re)start. */
#define NXT_DRAIN_MS		20
/* Reply timeout of a new open file, and its limit. */
#define NXT_TIMEOUT_DEFAULT_MS	1000
#define NXT_TIMEOUT_MAX_MS	60000

/**
 * struct nxt_stats - a brick's counters, in debugfs (under &nxt_usb.lock)
 * @telegrams: telegrams submitted
 * @replies: replies received (that answered their transaction)
 * @transactions: transactions ended
 * @ok: of which without an error
 * @err_timedout: ended with -ETIMEDOUT
 * @err_proto: with -EPROTO (only malformed replies came)
 * @err_pipe: with -EPIPE (a stall)
 * @err_io: with -EIO (transfer errors, a reset, a suspend)
 * @err_nodev: with -ENODEV (unplugged)
 * @err_intr: with -EINTR (interrupted, cancelled)
 * @err_other: with another error
 * @stalls_in: IN endpoint stalls
 * @stalls_out: OUT endpoint stalls
 * @drains: drains of stale replies started
 * @drained: packets dropped while draining
 * @stale: packets dropped with no reply awaited
 * @mismatched: packets dropped that did not answer the transaction
 * @resets: USB resets of the brick
 */
struct nxt_stats {
	u64 telegrams;
	u64 replies;
	u64 transactions;
	u64 ok;
	u64 err_timedout;
	u64 err_proto;
	u64 err_pipe;
	u64 err_io;
	u64 err_nodev;
	u64 err_intr;
	u64 err_other;
	u64 stalls_in;
	u64 stalls_out;
	u64 drains;
	u64 drained;
	u64 stale;
	u64 mismatched;
	u64 resets;
};

/**
 * struct nxt_usb - one brick
 * @kref: references: probe() and each open file
 * @udev: the USB device, referenced while this structure lives
 * @intf: the bound interface; NULL once disconnected (@io_mutex)
 * @out_pipe: bulk OUT pipe (endpoint 0x01 on a LEGO brick)
 * @in_pipe: bulk IN pipe (endpoint 0x82)
 * @io_mutex: see the comment at the top of this file
 * @suspended: suspended or being reset: no URB may be submitted (@io_mutex)
 * @reader_wanted: the reader was started and runs when not suspended (@io_mutex)
 * @lock: see the comment at the top of this file
 * @cur: the transaction in the slot, or NULL (@lock)
 * @queue: transactions waiting for the slot, first come first (@lock)
 * @gone: disconnected; set with @intf cleared (@lock)
 * @reader_running: @in_urb is submitted (@lock)
 * @drain_until: 64-bit jiffies until which no telegram is sent (@lock)
 * @orphan: a transaction ended without the reply to its telegram, which
 *	the brick took: the drain ends when that reply comes (@lock)
 * @orphan_op: the opcode of that telegram (@lock)
 * @wait: woken when a transaction finishes, the queue changes, a drain
 *	ends or the brick goes away: for poll(), suspend() and drains (the
 *	owner of a transaction sleeps on its &nxt_xfer.wait)
 * @in_urb: the reader's URB
 * @in_buf: its 64-byte buffer
 * @out_anchor: telegrams in flight, killed on disconnect, reset, suspend
 * @timer: ends the transaction in the slot when its time is up
 * @recover_work: clears a halted endpoint and restarts the reader; sending a
 *	telegram does the same first (nxt_recover_locked())
 * @drain_work: wakes @wait when a drain ends
 * @halted_in: the IN endpoint stalled (@lock)
 * @halted_out: the OUT endpoint stalled (@lock)
 * @stalls: IN stalls in a row, with no packet in between (@lock)
 * @info: what the brick last said about itself, from the replies that
 *	passed (@lock): what the sysfs attributes show
 * @stats: counters (@lock)
 * @debugfs: the brick's directory in debugfs (lego_nxt_usb/USBDEV)
 */
struct nxt_usb {
	struct kref kref;
	struct usb_device *udev;
	struct usb_interface *intf;
	unsigned int out_pipe;
	unsigned int in_pipe;

	struct mutex io_mutex;	/* see the comment at the top */
	bool suspended;
	bool reader_wanted;

	spinlock_t lock;	/* see the comment at the top */
	struct nxt_xfer *cur;
	struct list_head queue;
	bool gone;
	bool reader_running;
	u64 drain_until;
	bool orphan;
	u8 orphan_op;
	wait_queue_head_t wait;

	struct urb *in_urb;
	u8 *in_buf;
	struct usb_anchor out_anchor;
	struct timer_list timer;
	struct delayed_work recover_work;
	struct delayed_work drain_work;
	bool halted_in;
	bool halted_out;
	u8 stalls;

	struct nxt_brick_info info;
	struct nxt_stats stats;
	struct dentry *debugfs;
};

/**
 * struct nxt_xfer - one telegram and its reply
 * @nxt: the brick it is sent to
 * @queue: its entry in the brick's queue while it waits for the slot (@lock)
 * @wait: its owner sleeps here: woken when the transaction may claim the
 *	slot, its telegram is sent, it finishes, or the brick goes away;
 *	always with @lock held, so that the owner, which checks under @lock,
 *	cannot free it before the wake-up is done
 * @reply_wait: the owner waits for the reply and the OUT URB together
 *	(nxt_transact()): the OUT URB's completion alone does not wake it
 * @tg: the telegram
 * @len: its length
 * @want_reply: the telegram's type asks for a reply
 * @urb: the OUT URB, while the telegram is being sent
 * @sent: the telegram was submitted: from then on only can a packet answer
 *	the transaction, its timer end it, or a reset fail it (@lock)
 * @delivered: the OUT URB completed without error: the brick has the
 *	telegram (@lock)
 * @deadline: jiffies by which the transaction must have finished
 * @out_done: the OUT URB has completed (@lock)
 * @timed_out: the timer unlinked the OUT URB (@lock)
 * @saw_bad: a packet that was not this telegram's reply came while its
 *	reply was awaited (@lock)
 * @link_error: an IN transfer failed while the reply was awaited (@lock)
 * @grace_used: the deadline was extended once after a link error (@lock)
 * @status: -%EINPROGRESS until finished; then 0 or a negative errno (@lock)
 * @reply: the reply, zero past @reply_len
 * @reply_len: its length; 0 if none
 */
struct nxt_xfer {
	struct nxt_usb *nxt;
	struct list_head queue;
	wait_queue_head_t wait;
	bool reply_wait;
	u8 tg[NXT_TELEGRAM_MAX];
	unsigned int len;
	bool want_reply;
	struct urb *urb;
	bool sent;
	bool delivered;
	unsigned long deadline;
	bool out_done;
	bool timed_out;
	bool saw_bad;
	bool link_error;
	bool grace_used;
	int status;
	u8 reply[NXT_TELEGRAM_MAX];
	unsigned int reply_len;
};

int nxt_xfer_start(struct nxt_usb *nxt, struct nxt_xfer *x, const u8 *tg,
		   size_t len, unsigned int timeout_ms, bool nonblock);
int nxt_xfer_wait(struct nxt_usb *nxt, struct nxt_xfer *x, bool nonblock);
void nxt_xfer_cancel(struct nxt_usb *nxt, struct nxt_xfer *x);
bool nxt_xfer_done(struct nxt_usb *nxt, struct nxt_xfer *x);
bool nxt_slot_free(struct nxt_usb *nxt);
int nxt_transact(struct nxt_usb *nxt, struct nxt_xfer *x, const u8 *tg,
		 size_t len, unsigned int timeout_ms, bool nonblock);
bool nxt_gone(struct nxt_usb *nxt);
int nxt_reader_ensure(struct nxt_usb *nxt);
void nxt_usb_get(struct nxt_usb *nxt);
void nxt_usb_put(struct nxt_usb *nxt);
extern struct usb_driver nxt_usb_driver;

/* nxt_cdev.c */
extern struct usb_class_driver nxt_usb_class;

/* nxt_sysfs.c */
extern const struct attribute_group *nxt_groups[];

#endif /* _NXT_USB_H */
