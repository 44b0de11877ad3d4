/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT brick: the transaction engine, whatever the link.
 *
 * A transport (nxt_usb.c, nxt_serial.c) moves telegrams and replies; the views (the char
 * device, sysfs) run transactions. Both use the engine through this file
 * only, and the engine knows nothing of either: it calls the transport
 * through struct nxt_transport_ops.
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
 * transaction. A packet from the brick that does not answer the
 * transaction in the slot is dropped as stale.
 *
 * A transaction is live (a packet can answer it, its timer end it, a reset
 * fail it) only from when its telegram is handed to the transport (@sent),
 * not from when it takes the slot: until then it only waits for the drain
 * and @tx_lock. When the transport starts receiving, packets are drained
 * for NXT_DRAIN_MS before the next telegram goes out; when a sent
 * transaction ends without its reply, for as long as that reply may come
 * late (nxt_reply_late_ms()), or until it has come.
 *
 * Locking
 * -------
 * @tx_lock (a mutex) serialises every send against the transport's
 * disconnect, reset and suspend: @present and @paused are written under it,
 * and a transport holds it across a reset. The transport's
 * &nxt_transport_ops.start and &nxt_transport_ops.send run under it.
 *
 * @open_lock (a mutex) counts the open files (@opens); the transport's
 * &nxt_transport_ops.open and &nxt_transport_ops.close run under it, not
 * under @tx_lock, which they may take (to resume a suspended link, say).
 *
 * @lock (a spinlock, taken in the transport's completions and the timer)
 * protects the slot @cur and the state of the transaction in it, the
 * @queue, @gone, @drain_until, @orphan, @info, @stats and the reply
 * hand-off. Every write of a transaction's @status is made under it, since
 * poll() reads it without the open file's lock. A transport may keep state
 * of its own under it.
 * Order: @open_lock, then @tx_lock, then @lock.
 *
 * Lifetime
 * --------
 * struct nxt_brick is reference counted: the transport holds one reference
 * while the brick is bound and each open file one; the last put calls the
 * transport's &nxt_transport_ops.release, which frees the structure that
 * embeds it. A struct nxt_xfer belongs to its caller, which must not free
 * it before nxt_xfer_start() has returned and, if that succeeded, the
 * transaction has finished (nxt_xfer_wait()) or been cancelled
 * (nxt_xfer_cancel()).
 */
#ifndef _NXT_CORE_H
#define _NXT_CORE_H

#include <linux/kref.h>
#include <linux/list.h>
#include <linux/mutex.h>
#include <linux/spinlock.h>
#include <linux/timer.h>
#include <linux/types.h>
#include <linux/wait.h>
#include <linux/workqueue.h>
#include <linux/lego_nxt.h>

#include "nxt_proto.h"

/* Stale packets are drained this long after a timeout or a (re)start. */
#define NXT_DRAIN_MS		20
/* Reply timeout of a new open file, and its limit. */
#define NXT_TIMEOUT_DEFAULT_MS	1000
#define NXT_TIMEOUT_MAX_MS	60000
/*
 * An unplug shows as transfer errors before the transport reports it: after
 * such an error a transaction waits this much past its deadline for the
 * disconnect, so that it ends with -ENODEV rather than with a timeout.
 */
#define NXT_UNPLUG_GRACE_MS	1000

struct nxt_brick;
struct nxt_i2c;
struct nxt_xfer;

/**
 * struct nxt_stats - a brick's counters, in debugfs (under &nxt_brick.lock)
 * @telegrams: telegrams handed to the transport
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
 * @stalls_in: IN endpoint stalls (the transport's)
 * @stalls_out: OUT endpoint stalls (the transport's)
 * @drains: drains of stale replies started
 * @drained: packets dropped while draining
 * @stale: packets dropped with no reply awaited
 * @mismatched: packets dropped that did not answer the transaction
 * @resets: resets of the link (the transport's)
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
 * struct nxt_transport_ops - what a transport does for the engine
 * @open: the first file was opened: start receiving (&nxt_brick.open_lock
 *	held). 0 or a negative errno.
 * @close: the last file was closed: stop receiving (&nxt_brick.open_lock
 *	held)
 * @start: make the link ready to send (clear what an error left, restart
 *	receiving); called with &nxt_brick.tx_lock held before each telegram.
 *	0 or a negative errno.
 * @send: start sending @x->tg (@x->len bytes), with &nxt_brick.tx_lock
 *	held; may sleep. Returns a handle of the send, referenced for the
 *	engine, or an ERR_PTR() when nothing was sent. The transport calls
 *	nxt_brick_sent() exactly once when the send ends, after @send has
 *	returned or from within it.
 * @unlink: ask a send to stop, without waiting (the reply is late and the
 *	telegram was not taken); any context, no lock held
 * @kill: stop a send and wait until its nxt_brick_sent() has run
 *	(process context, no lock held)
 * @get: take a reference to a handle (&nxt_brick.lock held)
 * @put: drop a reference to a handle (any context, no lock held)
 * @release: the last reference to the brick is gone: free it
 * @owner: the transport's module (THIS_MODULE): each open file holds it,
 *	since the file may drop the brick's last reference
 */
struct nxt_transport_ops {
	int (*open)(struct nxt_brick *b);
	void (*close)(struct nxt_brick *b);
	int (*start)(struct nxt_brick *b);
	void *(*send)(struct nxt_brick *b, struct nxt_xfer *x);
	void (*unlink)(void *handle);
	void (*kill)(void *handle);
	void (*get)(void *handle);
	void (*put)(void *handle);
	void (*release)(struct nxt_brick *b);
	struct module *owner;
};

/**
 * struct nxt_brick - one brick, whatever its link
 * @kref: references: the transport's while bound, and each open file's
 * @ops: its transport
 * @dev: the device its log lines name (the transport's)
 * @name: its name in the trace events and debugfs (e.g. "1-1")
 * @open_lock: see the comment at the top of this file
 * @opens: open files (@open_lock)
 * @tx_lock: see the comment at the top of this file
 * @present: the transport is bound; false once it is gone (@tx_lock)
 * @paused: suspended or being reset: nothing may be sent (@tx_lock)
 * @lock: see the comment at the top of this file
 * @cur: the transaction in the slot, or NULL (@lock)
 * @queue: transactions waiting for the slot, first come first (@lock)
 * @gone: disconnected; set with @present cleared (@lock)
 * @drain_until: 64-bit jiffies until which no telegram is sent (@lock)
 * @orphan: a transaction ended without the reply to its telegram, which
 *	the brick took: the drain ends when that reply comes (@lock)
 * @orphan_op: the opcode of that telegram (@lock)
 * @wait: woken when a transaction finishes, the queue changes, a drain
 *	ends or the brick goes away: for poll(), suspend and drains (the
 *	owner of a transaction sleeps on its &nxt_xfer.wait)
 * @timer: ends the transaction in the slot when its time is up
 * @drain_work: wakes @wait when a drain ends
 * @info: what the brick last said about itself, from the replies that
 *	passed (@lock): what the sysfs attributes show
 * @stats: counters (@lock)
 * @debugfs: the brick's directory in debugfs, or NULL
 * @serial: its serial number, which the transport sets before it adds the
 *	brick's node (USB: the brick's iSerial, its Bluetooth address in hex),
 *	or empty: the views name the brick by it
 * @minor: the minor of its /dev/nxtN (nxt_cdev.c)
 * @node: the device of its /dev/nxtN, with the sysfs attributes
 *	(nxt_cdev.c); NULL when it has none
 * @i2c: the I2C adapters of its sensor ports (nxt_i2c.c), or NULL
 */
struct nxt_brick {
	struct kref kref;
	const struct nxt_transport_ops *ops;
	struct device *dev;
	char name[32];

	struct mutex open_lock;	/* see the comment at the top */
	unsigned int opens;
	struct mutex tx_lock;	/* see the comment at the top */
	bool present;
	bool paused;

	spinlock_t lock;	/* see the comment at the top */
	struct nxt_xfer *cur;
	struct list_head queue;
	bool gone;
	u64 drain_until;
	bool orphan;
	u8 orphan_op;
	wait_queue_head_t wait;
	struct timer_list timer;
	struct delayed_work drain_work;

	struct nxt_brick_info info;
	struct nxt_stats stats;
	struct dentry *debugfs;
	char serial[32];
	int minor;
	struct device *node;
	struct nxt_i2c *i2c;
};

/**
 * struct nxt_xfer - one telegram and its reply
 * @brick: the brick it is sent to
 * @queue: its entry in the brick's queue while it waits for the slot (@lock)
 * @wait: its owner sleeps here: woken when the transaction may claim the
 *	slot, its telegram is sent, it finishes, or the brick goes away;
 *	always with @lock held, so that the owner, which checks under @lock,
 *	cannot free it before the wake-up is done
 * @reply_wait: the owner waits for the reply and the send together
 *	(nxt_transact()): the end of the send alone does not wake it
 * @tg: the telegram
 * @len: its length
 * @want_reply: the telegram's type asks for a reply
 * @handle: the transport's handle of the send, while it runs (@lock)
 * @sent: the telegram was handed to the transport: from then on only can
 *	a packet answer the transaction, its timer end it, or a reset fail it
 *	(@lock)
 * @delivered: the send ended without error: the brick has the telegram
 *	(@lock)
 * @deadline: jiffies by which the transaction must have finished
 * @out_done: the send has ended (@lock)
 * @timed_out: the timer asked the send to stop (@lock)
 * @saw_bad: a packet that was not this telegram's reply came while its
 *	reply was awaited (@lock)
 * @link_error: a receive failed while the reply was awaited (@lock)
 * @grace_used: the deadline was extended once after a link error (@lock)
 * @status: -%EINPROGRESS until finished; then 0 or a negative errno (@lock)
 * @reply: the reply, zero past @reply_len
 * @reply_len: its length; 0 if none
 */
struct nxt_xfer {
	struct nxt_brick *brick;
	struct list_head queue;
	wait_queue_head_t wait;
	bool reply_wait;
	u8 tg[NXT_TELEGRAM_MAX];
	unsigned int len;
	bool want_reply;
	void *handle;
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

/* For the transport. */
void nxt_brick_init(struct nxt_brick *b, const struct nxt_transport_ops *ops,
		    struct device *dev, const char *name);
void nxt_brick_debugfs(struct nxt_brick *b);
void nxt_brick_rx(struct nxt_brick *b, const u8 *buf, unsigned int len);
void nxt_brick_in_stalled(struct nxt_brick *b);
void nxt_brick_link_error(struct nxt_brick *b);
void nxt_brick_rx_started(struct nxt_brick *b);
void nxt_brick_sent(struct nxt_brick *b, struct nxt_xfer *x, int err);
void nxt_brick_fail(struct nxt_brick *b, int err);
bool nxt_brick_in_flight(struct nxt_brick *b);
void nxt_brick_disconnect(struct nxt_brick *b);
void nxt_brick_shutdown(struct nxt_brick *b);

/* For the module's init and exit (nxt_main.c). */
void nxt_core_debugfs_init(void);
void nxt_core_debugfs_exit(void);

/* For the views. */
int nxt_brick_open(struct nxt_brick *b);
void nxt_brick_close(struct nxt_brick *b);
int nxt_xfer_start(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
		   size_t len, unsigned int timeout_ms, bool nonblock);
int nxt_xfer_wait(struct nxt_brick *b, struct nxt_xfer *x, bool nonblock);
void nxt_xfer_cancel(struct nxt_brick *b, struct nxt_xfer *x);
bool nxt_xfer_done(struct nxt_brick *b, struct nxt_xfer *x);
int nxt_transact(struct nxt_brick *b, struct nxt_xfer *x, const u8 *tg,
		 size_t len, unsigned int timeout_ms, bool nonblock);
bool nxt_slot_free(struct nxt_brick *b);
bool nxt_gone(struct nxt_brick *b);
void nxt_brick_info(struct nxt_brick *b, struct nxt_brick_info *info);
void nxt_brick_get(struct nxt_brick *b);
void nxt_brick_put(struct nxt_brick *b);

#endif /* _NXT_CORE_H */
