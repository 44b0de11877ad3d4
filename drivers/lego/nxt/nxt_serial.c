// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: serial transport, a line discipline.
 *
 * A brick on Bluetooth is a byte stream, its serial port profile (RFCOMM
 * channel 1), which Linux shows as a tty (/dev/rfcommN). Attaching
 * N_LEGONXT to that tty (`nxtctl connect` or `nxtctl attach`, or TIOCSETD)
 * gives the brick its /dev/nxtN: the same node, sysfs attributes, trace
 * events and counters as on USB, through the same engine (nxt_core.c). Any
 * other tty that carries the brick's Bluetooth framing works too; the
 * tests use a pty. The connection itself (pairing, RFCOMM) stays with the
 * Bluetooth stack and userspace, as for hci_uart.
 *
 * On the line each telegram follows a 2-byte little-endian length
 * (nxt_proto.c makes and reads the frames, and survives lengths that lie).
 * What the link does, and what the driver does about it:
 *
 *  - the brick answers in 30 ms or more, and wants about 30 ms between a
 *    reply and the next command (LEGO's Bluetooth developer kit): a
 *    telegram goes out no sooner than NXT_SERIAL_GAP_MS after the last
 *    reply came;
 *  - nothing that came before a telegram can answer it: the reader forgets
 *    a frame it was reading when the next telegram goes out;
 *  - a hangup of the tty (the RFCOMM link lost, the pty's other end closed)
 *    closes the discipline: the brick goes as on a USB unplug.
 */
#include <linux/delay.h>
#include <linux/jiffies.h>
#include <linux/module.h>
#include <linux/slab.h>
#include <linux/spinlock.h>
#include <linux/tty.h>
#include <linux/tty_ldisc.h>
#include <linux/uaccess.h>
#include <linux/workqueue.h>
#include <linux/lego_nxt.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_views.h"

/* The least time between a reply and the next telegram. */
#define NXT_SERIAL_GAP_MS	30

/**
 * struct nxt_serial - one brick on a tty
 * @brick: the brick, for the engine and the views
 * @tty: the tty; NULL once the discipline is closing (@tx_mutex)
 * @tx_mutex: one writer of the tty at a time (a send, @tx_work); protects
 *	@tty and the bytes of @frame. Order: @brick.tx_lock, then @tx_mutex.
 * @tx_lock: protects @tx_x, @frame_len and @frame_pos; taken by unlink,
 *	which may run in the engine's timer
 * @tx_x: the transaction whose frame is going out, or NULL (@tx_lock)
 * @frame: its frame (@tx_mutex)
 * @frame_len: the frame's length (@tx_lock)
 * @frame_pos: the bytes of it the tty took (@tx_lock)
 * @tx_work: writes the rest of a frame when the tty has room again
 * @rx: the reader of the brick's frames (@brick.lock, which the engine's
 *	nxt_brick_rx() wants held anyway)
 * @last_rx: jiffies when the last reply came (@brick.lock)
 * @rx_seen: a reply came (@brick.lock)
 */
struct nxt_serial {
	struct nxt_brick brick;
	struct tty_struct *tty;
	struct mutex tx_mutex;	/* see above */
	spinlock_t tx_lock;	/* see above */
	struct nxt_xfer *tx_x;
	u8 frame[NXT_BT_FRAME_MAX];
	unsigned int frame_len;
	unsigned int frame_pos;
	struct work_struct tx_work;
	struct nxt_bt_rx rx;
	unsigned long last_rx;
	bool rx_seen;
};

static struct nxt_serial *to_nxt_serial(struct nxt_brick *b)
{
	return container_of(b, struct nxt_serial, brick);
}

/*
 * Ends the send going out, if any, with @err: the engine is told once,
 * without @tx_lock. Any context.
 */
static void nxt_serial_end(struct nxt_serial *s, int err)
{
	struct nxt_xfer *x;
	unsigned long flags;

	spin_lock_irqsave(&s->tx_lock, flags);
	x = s->tx_x;
	s->tx_x = NULL;
	spin_unlock_irqrestore(&s->tx_lock, flags);
	if (x)
		nxt_brick_sent(&s->brick, x, err);
}

/*
 * Writes what the tty takes of the frame going out; the rest goes from
 * @tx_work when the tty calls write_wakeup. @tx_mutex held.
 */
static void nxt_serial_write(struct nxt_serial *s)
{
	struct tty_struct *tty = s->tty;
	struct nxt_xfer *x, *done = NULL;
	unsigned int pos, len;
	int err = 0;
	ssize_t n;

	lockdep_assert_held(&s->tx_mutex);
	spin_lock_irq(&s->tx_lock);
	x = s->tx_x;
	pos = s->frame_pos;
	len = s->frame_len;
	spin_unlock_irq(&s->tx_lock);
	if (!x)
		return;
	if (!tty) {
		nxt_serial_end(s, -ENODEV);
		return;
	}

	set_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	n = tty->ops->write(tty, s->frame + pos, len - pos);

	spin_lock_irq(&s->tx_lock);
	if (s->tx_x == x) {
		if (n < 0) {
			err = -EIO;
			done = x;
		} else {
			s->frame_pos += min_t(unsigned int, n, len - pos);
			if (s->frame_pos == len)
				done = x;
		}
		if (done)
			s->tx_x = NULL;
	}
	spin_unlock_irq(&s->tx_lock);
	if (done) {
		clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
		if (err)
			dev_warn_ratelimited(s->brick.dev, "tty write failed: %zd\n", n);
		nxt_brick_sent(&s->brick, done, err);
	}
}

static void nxt_serial_tx_work(struct work_struct *work)
{
	struct nxt_serial *s = container_of(work, struct nxt_serial, tx_work);

	mutex_lock(&s->tx_mutex);
	nxt_serial_write(s);
	mutex_unlock(&s->tx_mutex);
}

/*
 * The engine's handle of a send is the brick's transport itself: one send
 * at a time, and it lives as long as the brick, which every transaction's
 * owner holds. Nothing to count.
 */
static void nxt_serial_handle_get(void *handle)
{
}

static void nxt_serial_handle_put(void *handle)
{
}

static void *nxt_serial_send(struct nxt_brick *b, struct nxt_xfer *x)
{
	struct nxt_serial *s = to_nxt_serial(b);
	unsigned int len;

	mutex_lock(&s->tx_mutex);
	len = nxt_bt_frame(s->frame, x->tg, x->len);
	spin_lock_irq(&s->tx_lock);
	s->tx_x = x;
	s->frame_len = len;
	s->frame_pos = 0;
	spin_unlock_irq(&s->tx_lock);
	nxt_serial_write(s);
	mutex_unlock(&s->tx_mutex);
	return s;
}

/*
 * The reply is late: what the tty has not taken of the frame is dropped.
 * A frame cut short would confuse the brick, but the tty takes a whole
 * frame at once unless its buffer is full, and then the link is stuck.
 */
static void nxt_serial_unlink(void *handle)
{
	nxt_serial_end(handle, -EINTR);
}

static void nxt_serial_kill(void *handle)
{
	nxt_serial_unlink(handle);
}

/*
 * Before each telegram: forget a frame being read (nothing before this
 * telegram can answer it), and keep the brick's gap after its last reply.
 * @brick.tx_lock held.
 */
static int nxt_serial_start(struct nxt_brick *b)
{
	struct nxt_serial *s = to_nxt_serial(b);
	unsigned long next = 0;
	bool wait;

	spin_lock_irq(&b->lock);
	nxt_bt_rx_reset(&s->rx);
	wait = s->rx_seen;
	if (wait)
		next = s->last_rx + msecs_to_jiffies(NXT_SERIAL_GAP_MS);
	spin_unlock_irq(&b->lock);
	if (wait && time_before(jiffies, next))
		msleep(jiffies_to_msecs(next - jiffies));
	return 0;
}

/* The tty delivers bytes whether a file is open or not: drain what came. */
static int nxt_serial_open_brick(struct nxt_brick *b)
{
	spin_lock_irq(&b->lock);
	nxt_brick_rx_started(b);
	spin_unlock_irq(&b->lock);
	return 0;
}

static void nxt_serial_close_brick(struct nxt_brick *b)
{
}

static void nxt_serial_release(struct nxt_brick *b)
{
	put_device(b->dev);
	kfree(to_nxt_serial(b));
}

static const struct nxt_transport_ops nxt_serial_ops = {
	.open		= nxt_serial_open_brick,
	.close		= nxt_serial_close_brick,
	.start		= nxt_serial_start,
	.send		= nxt_serial_send,
	.unlink		= nxt_serial_unlink,
	.kill		= nxt_serial_kill,
	.get		= nxt_serial_handle_get,
	.put		= nxt_serial_handle_put,
	.release	= nxt_serial_release,
	.owner		= THIS_MODULE,
};

/*
 * Feeds the reader, and gives the engine each reply that is complete. A
 * byte the tty flags (a framing or parity error, a break, an overrun)
 * breaks the frame being read.
 */
static void nxt_serial_receive_buf(struct tty_struct *tty, const u8 *cp,
				   const LEGO_TTY_FLAG *fp, LEGO_TTY_COUNT count)
{
	struct nxt_serial *s = tty->disc_data;
	struct nxt_brick *b = &s->brick;
	size_t left = count;

	spin_lock_irq(&b->lock);
	while (left) {
		unsigned int len = 0;
		const u8 *r;
		size_t n = 1, used;

		/* The bytes up to the next flagged one, or that one alone. */
		if (!fp || fp[0] == TTY_NORMAL)
			while (n < left && (!fp || fp[n] == TTY_NORMAL))
				n++;
		if (fp && fp[0] != TTY_NORMAL) {
			nxt_bt_rx_reset(&s->rx);
			s->rx.dropped++;
			used = 1;
		} else {
			used = nxt_bt_rx_feed(&s->rx, cp, n, &r, &len);
		}
		if (len) {
			s->last_rx = jiffies;
			s->rx_seen = true;
			nxt_brick_rx(b, r, len);
		}
		cp += used;
		if (fp)
			fp += used;
		left -= used;
	}
	spin_unlock_irq(&b->lock);
}

static void nxt_serial_write_wakeup(struct tty_struct *tty)
{
	struct nxt_serial *s = tty->disc_data;

	queue_work(system_dfl_wq, &s->tx_work);
}

static int nxt_serial_ldisc_ioctl(struct tty_struct *tty, unsigned int cmd,
				  unsigned long arg)
{
	struct nxt_serial *s = tty->disc_data;
	u32 minor;

	switch (cmd) {
	case NXT_IOC_TTY_MINOR:
		minor = s->brick.minor;
		return put_user(minor, (u32 __user *)arg);
	default:
		return tty_mode_ioctl(tty, cmd, arg);
	}
}

static int nxt_serial_ldisc_open(struct tty_struct *tty)
{
	struct nxt_serial *s;
	int ret;

	/* It makes a device: as for the other disciplines that do. */
	if (!capable(CAP_SYS_ADMIN))
		return -EPERM;
	if (!tty->ops->write)
		return -EOPNOTSUPP;

	s = kzalloc_obj(*s, GFP_KERNEL);
	if (!s)
		return -ENOMEM;
	nxt_brick_init(&s->brick, &nxt_serial_ops, NULL, tty->name);
	s->tty = tty;
	mutex_init(&s->tx_mutex);
	spin_lock_init(&s->tx_lock);
	INIT_WORK(&s->tx_work, nxt_serial_tx_work);
	tty->disc_data = s;
	tty->receive_room = 65536;
	tty_driver_flush_buffer(tty);

	ret = nxt_node_add(&s->brick, tty->dev);
	if (ret) {
		pr_err_ratelimited("%s: cannot get a minor: %d\n", tty->name, ret);
		tty->disc_data = NULL;
		nxt_brick_put(&s->brick);
		return ret;
	}
	/*
	 * The device the log lines name: the tty's, or the brick's node where
	 * the tty has none (a pty). Either may go before the brick (a hung-up
	 * RFCOMM tty, a removed node, while files keep the brick): held until
	 * the brick is released.
	 */
	s->brick.dev = get_device(tty->dev ? tty->dev : s->brick.node);
	nxt_brick_debugfs(&s->brick);
	dev_info(s->brick.dev, "LEGO NXT brick on %s now at %s\n", tty->name,
		 dev_name(s->brick.node));
	return 0;
}

/* The tty is closed or hung up (the link is lost): the brick goes. */
static void nxt_serial_ldisc_close(struct tty_struct *tty)
{
	struct nxt_serial *s = tty->disc_data;

	/* No new opens; then no new sends; then none going out. */
	nxt_node_remove(&s->brick);
	mutex_lock(&s->brick.tx_lock);
	nxt_brick_disconnect(&s->brick);
	mutex_lock(&s->tx_mutex);
	s->tty = NULL;
	mutex_unlock(&s->tx_mutex);
	mutex_unlock(&s->brick.tx_lock);
	cancel_work_sync(&s->tx_work);
	nxt_serial_end(s, -ENODEV);
	clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	nxt_brick_shutdown(&s->brick);

	pr_info("%s: LEGO NXT brick gone\n", tty->name);
	tty->disc_data = NULL;
	nxt_brick_put(&s->brick);
}

static struct tty_ldisc_ops nxt_serial_ldisc = {
	.owner		= THIS_MODULE,
	.num		= N_LEGONXT,
	.name		= "n_legonxt",
	.open		= nxt_serial_ldisc_open,
	.close		= nxt_serial_ldisc_close,
	.ioctl		= nxt_serial_ldisc_ioctl,
	.receive_buf	= nxt_serial_receive_buf,
	.write_wakeup	= nxt_serial_write_wakeup,
};

static int __init nxt_serial_init(void)
{
	int ret = tty_register_ldisc(&nxt_serial_ldisc);

	if (ret)
		pr_err("cannot register line discipline %d: %d\n", N_LEGONXT, ret);
	return ret;
}
module_init(nxt_serial_init);

static void __exit nxt_serial_exit(void)
{
	tty_unregister_ldisc(&nxt_serial_ldisc);
}
module_exit(nxt_serial_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS NXT brick on a serial line (Bluetooth)");
MODULE_LICENSE("GPL");
MODULE_ALIAS_LDISC(N_LEGONXT);
