// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: tty line discipline.
 *
 * Attach it to any tty a sensor is wired to (N_LEGOEV3, e.g. with ldattach).
 * This file is the transport: it moves bytes between the tty and the sensor
 * core (ev3_uart_core.c), which runs the protocol, and sets the tty's speed
 * when the core asks (&struct ev3_uart_transport_ops). It also holds the
 * module's init, which registers the views (the lego-sensor class, IIO)
 * with the core.
 *
 * Locking: ev3_uart_ldisc.tx_mutex serialises writes to the tty (ACK, NACK,
 * SELECT, WRITE, SPEED), which all happen in process context, and protects
 * the transmit queue and its counters (see ev3_uart_tx()). The core's lock
 * is never held when the core calls in here.
 *
 * Attaching requires CAP_SYS_ADMIN: a user who could attach the discipline to
 * a pty could play a hostile "sensor" and make the kernel register devices of
 * its choosing.
 */
#define pr_fmt(fmt) KBUILD_MODNAME ": " fmt

#include <linux/build_bug.h>
#include <linux/capability.h>
#include <linux/debugfs.h>
#include <linux/lockdep.h>
#include <linux/module.h>
#include <linux/moduleparam.h>
#include <linux/mutex.h>
#include <linux/seq_file.h>
#include <linux/slab.h>
#include <linux/string.h>
#include <linux/tty.h>
#include <linux/tty_ldisc.h>
#include <linux/uaccess.h>
#include <linux/workqueue.h>
#include <linux/lego_ev3_uart.h>

#include "lego_compat.h"
#include "ev3_uart_core.h"
#include "ev3_uart_trace.h"
#include "ev3_uart_views.h"

#define EV3_UART_LDISC_NAME	"n_legoev3"

/*
 * N_LEGOEV3 from <linux/lego_ev3_uart.h>. There is no parameter to choose
 * another number: tty_register_ldisc() does not check that a number is
 * free, so any other would replace a discipline in use.
 */
#define EV3_UART_LDISC_NUM	N_LEGOEV3

/* lego_ev3_uart in debugfs, with a directory per port (ev3_uart_open()). */
static struct dentry *ev3_uart_debugfs_root;

static char *port_labels[8];
static int num_port_labels;
module_param_array(port_labels, charp, &num_port_labels, 0444);
MODULE_PARM_DESC(port_labels,
		 "port labels for the sensor address, as tty=label (e.g. ttyUSB0=in1,ttyAMA0=in2)");

/**
 * struct ev3_uart_tx_stats - what the discipline sent, for debugfs (under
 *	&ev3_uart_ldisc.tx_mutex)
 * @tx_ack: ACKs sent
 * @tx_nack: NACKs sent
 * @tx_select: SELECTs sent
 * @tx_write: WRITEs sent
 * @tx_speed: SPEEDs sent (the fast sync probes)
 * @tx_errors: messages the tty did not take
 */
struct ev3_uart_tx_stats {
	u64 tx_ack;
	u64 tx_nack;
	u64 tx_select;
	u64 tx_write;
	u64 tx_speed;
	u64 tx_errors;
};

/**
 * struct ev3_uart_ldisc - one tty with the discipline attached
 * @port: the sensor core's port
 * @tty: the tty
 * @tx_mutex: see "Locking" above
 * @tx_buf: bytes queued for the tty (under @tx_mutex)
 * @tx_pos: the first byte of @tx_buf not yet sent
 * @tx_len: bytes queued from @tx_pos on
 * @tx_work: sends what is queued once the tty has room again (on
 *	system_dfl_wq)
 * @tx_failed: the last write to the tty failed (under @tx_mutex): further
 *	errors are not logged until one succeeds
 * @stats: counters, for debugfs
 * @debugfs: the port's directory in debugfs (lego_ev3_uart/TTY)
 */
struct ev3_uart_ldisc {
	struct ev3_uart_port port;
	struct tty_struct *tty;
	struct mutex tx_mutex;		/* one writer to the tty at a time */
	u8 tx_buf[4 * EV3_UART_MAX_MSG_LEN];
	unsigned int tx_pos;
	unsigned int tx_len;
	struct work_struct tx_work;
	bool tx_failed;
	struct ev3_uart_tx_stats stats;
	struct dentry *debugfs;
};

static struct ev3_uart_ldisc *to_ldisc(struct ev3_uart_port *port)
{
	return container_of(port, struct ev3_uart_ldisc, port);
}

/*
 * Hand the queued bytes to the tty driver, as many as it takes. A driver
 * whose buffer is full takes part of a message or none of it: the rest
 * stays queued and goes out from write_wakeup, so a message is never cut
 * short on the wire (can327 does the same). The wakeup flag is set before
 * writing, so a wakeup for room made meanwhile is not lost.
 */
static int ev3_uart_tx_flush(struct ev3_uart_ldisc *ld)
{
	struct tty_struct *tty = ld->tty;
	int n;

	lockdep_assert_held(&ld->tx_mutex);
	set_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	while (ld->tx_len) {
		n = tty->ops->write(tty, ld->tx_buf + ld->tx_pos, ld->tx_len);
		if (n < 0) {
			/* The tty is gone or broken: what is queued is lost. */
			ld->tx_len = 0;
			clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
			return n;
		}
		if (!n)
			return 0;	/* full: write_wakeup sends the rest */
		ld->tx_pos += n;
		ld->tx_len -= n;
	}
	ld->tx_pos = 0;
	clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	return 0;
}

/* What a message sent starts with: ACK, NACK, SELECT, SPEED or WRITE. */
static u8 ev3_uart_tx_kind(u8 hdr)
{
	if (hdr == EV3_UART_SYS_ACK)
		return EV3_UART_TRACE_ACK;
	if (hdr == EV3_UART_SYS_NACK)
		return EV3_UART_TRACE_NACK;
	if (hdr == (EV3_UART_MSG_CMD | EV3_UART_CMD_SELECT))
		return EV3_UART_TRACE_SELECT;
	if ((hdr & ~EV3_UART_MSG_SIZE_MASK) == (EV3_UART_MSG_CMD | EV3_UART_CMD_SPEED))
		return EV3_UART_TRACE_SPEED;
	return EV3_UART_TRACE_WRITE;
}

/* Counts and traces a message sent (or not: @ret). @tx_mutex held. */
static void ev3_uart_tx_account(struct ev3_uart_ldisc *ld, const u8 *buf,
				size_t len, int ret)
{
	struct ev3_uart_tx_stats *st = &ld->stats;
	u8 kind = ev3_uart_tx_kind(buf[0]);

	lockdep_assert_held(&ld->tx_mutex);
	if (ret)
		st->tx_errors++;
	else if (kind == EV3_UART_TRACE_ACK)
		st->tx_ack++;
	else if (kind == EV3_UART_TRACE_NACK)
		st->tx_nack++;
	else if (kind == EV3_UART_TRACE_SELECT)
		st->tx_select++;
	else if (kind == EV3_UART_TRACE_SPEED)
		st->tx_speed++;
	else
		st->tx_write++;
	trace_ev3_uart_tx(ld->tty->name, kind, buf[0], len > 1 ? buf[1] : 0,
			  len, ret);
}

/*
 * Latch the tty's write errors, as can327 does: the first one is logged,
 * the others (a keep-alive every 100 ms) only counted, until a message goes
 * out again. @tx_mutex held. Return: what to log: 1 the first error, -1
 * the recovery, 0 nothing.
 */
static int ev3_uart_tx_latch(struct ev3_uart_ldisc *ld, int ret)
{
	bool was = ld->tx_failed;

	lockdep_assert_held(&ld->tx_mutex);
	ld->tx_failed = ret;
	if (ret && !was)
		return 1;
	return !ret && was ? -1 : 0;
}

static void ev3_uart_tx_log(struct ev3_uart_ldisc *ld, int what, int err)
{
	if (what > 0)
		pr_warn("%s: cannot send to the tty: %d (not logged again until a message goes out)\n",
			ld->tty->name, err);
	else if (what < 0)
		pr_info("%s: sending to the tty again\n", ld->tty->name);
}

/*
 * Drop what is queued and not yet on the wire: on a speed change (it was
 * meant for the old speed) and when a sensor is lost (a SELECT or a WRITE
 * for it must not reach the next one). Both what is still in @tx_buf and
 * what the tty driver holds and has not sent: a UART's buffer behind a
 * held transmitter, a USB adapter's, would else send it at the new speed
 * or to the next sensor. The ACK is waited for before its speed change
 * (ev3_uart_ack()), the probe's SPEED before the probe ends. Not on a pty: it
 * holds nothing, what is written is in the other end's input at once, and
 * its flush_buffer drops that (an ACK the sensor has not read yet).
 */
static void ev3_uart_tx_discard(struct ev3_uart_port *port)
{
	struct ev3_uart_ldisc *ld = to_ldisc(port);
	struct tty_struct *tty = ld->tty;

	mutex_lock(&ld->tx_mutex);
	ld->tx_len = 0;
	ld->tx_pos = 0;
	if (tty->driver->type != TTY_DRIVER_TYPE_PTY)
		tty_driver_flush_buffer(tty);
	mutex_unlock(&ld->tx_mutex);
}

/* Queue a whole message behind what is still queued, and send. */
static int ev3_uart_tx(struct ev3_uart_port *port, const u8 *buf, size_t len)
{
	struct ev3_uart_ldisc *ld = to_ldisc(port);
	int ret, log;

	mutex_lock(&ld->tx_mutex);
	if (ld->tx_pos) {
		memmove(ld->tx_buf, ld->tx_buf + ld->tx_pos, ld->tx_len);
		ld->tx_pos = 0;
	}
	if (len > sizeof(ld->tx_buf) - ld->tx_len) {
		ret = -ENOBUFS;
	} else {
		memcpy(ld->tx_buf + ld->tx_len, buf, len);
		ld->tx_len += len;
		ret = ev3_uart_tx_flush(ld);
	}
	ev3_uart_tx_account(ld, buf, len, ret);
	log = ev3_uart_tx_latch(ld, ret);
	mutex_unlock(&ld->tx_mutex);
	ev3_uart_tx_log(ld, log, ret);
	return ret;
}

static void ev3_uart_tx_work(struct work_struct *work)
{
	struct ev3_uart_ldisc *ld = container_of(work, struct ev3_uart_ldisc,
						  tx_work);
	int ret = 0, log = 0;

	mutex_lock(&ld->tx_mutex);
	if (ld->tx_len) {
		ret = ev3_uart_tx_flush(ld);
		log = ev3_uart_tx_latch(ld, ret);
	}
	mutex_unlock(&ld->tx_mutex);
	ev3_uart_tx_log(ld, log, ret);
}

/* The driver has room again: send the rest from process context. */
static void ev3_uart_write_wakeup(struct tty_struct *tty)
{
	struct ev3_uart_ldisc *ld = tty->disc_data;

	queue_work(system_dfl_wq, &ld->tx_work);
}

/*
 * Set new termios as TCSETS would (locked termios respected, the driver's
 * set_termios called). Not on a pty master: it has no line settings of its
 * own, and tty_set_termios() warns on one; its termios are only stored.
 */
static void ev3_uart_set_termios(struct tty_struct *tty, struct ktermios *t)
{
	if (tty->driver->type == TTY_DRIVER_TYPE_PTY &&
	    tty->driver->subtype == PTY_TYPE_MASTER) {
		down_write(&tty->termios_rwsem);
		tty->termios = *t;
		up_write(&tty->termios_rwsem);
		return;
	}
	tty_set_termios(tty, t);
}

/*
 * Through tty_set_termios(), like a TCSETS would: locked termios are
 * respected, and the driver writes back the speed it could set. What is
 * still queued for the tty is dropped first (ev3_uart_tx_discard()): sent
 * after the change it would go out at the wrong speed. A tty with
 * no set_termios (a pty master) has no speed to set. A speed within 2 % is
 * as good (the tty core itself rounds to a standard rate that close, and
 * UARTs tolerate more).
 *
 * Return: 0, or -%EINVAL if the tty runs at another speed than @baud.
 */
static int ev3_uart_set_speed(struct ev3_uart_port *port, u32 baud)
{
	struct tty_struct *tty = to_ldisc(port)->tty;
	struct ktermios t;
	speed_t got;

	ev3_uart_tx_discard(port);
	down_read(&tty->termios_rwsem);
	t = tty->termios;
	up_read(&tty->termios_rwsem);
	tty_termios_encode_baud_rate(&t, baud, baud);
	ev3_uart_set_termios(tty, &t);
	if (!tty->ops->set_termios)
		return 0;
	down_read(&tty->termios_rwsem);
	got = tty_termios_baud_rate(&tty->termios);
	up_read(&tty->termios_rwsem);
	return abs((int)got - (int)baud) <= baud / 50 ? 0 : -EINVAL;
}

/* Wait until what the tty holds is on the wire, @ms at most. */
static void ev3_uart_drain(struct ev3_uart_port *port, unsigned int ms)
{
	tty_wait_until_sent(to_ldisc(port)->tty, msecs_to_jiffies(ms));
}

static const struct ev3_uart_transport_ops ev3_uart_tty_ops = {
	.send		= ev3_uart_tx,
	.discard	= ev3_uart_tx_discard,
	.set_speed	= ev3_uart_set_speed,
	.drain		= ev3_uart_drain,
};

/* Raw 8N1 at 2400 baud, no flow control, errors reported as flags. */
static void ev3_uart_setup_tty(struct tty_struct *tty)
{
	struct ktermios t;

	down_read(&tty->termios_rwsem);
	t = tty->termios;
	up_read(&tty->termios_rwsem);
	t.c_iflag &= ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR |
		       ICRNL | IXON | IXOFF | IGNPAR);
	t.c_oflag &= ~OPOST;
	t.c_lflag &= ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
	t.c_cflag &= ~(CSIZE | PARENB | CSTOPB | CRTSCTS);
	t.c_cflag |= CS8 | CREAD | CLOCAL | HUPCL;
	tty_termios_encode_baud_rate(&t, EV3_UART_SPEED_MIN, EV3_UART_SPEED_MIN);
	ev3_uart_set_termios(tty, &t);
}

/* The label the port_labels parameter gives @tty, if any. */
static void ev3_uart_find_label(struct ev3_uart_ldisc *ld)
{
	size_t n = strlen(ld->tty->name);
	int i;

	for (i = 0; i < num_port_labels; i++) {
		const char *p = port_labels[i];

		if (p && !strncmp(p, ld->tty->name, n) && p[n] == '=') {
			ev3_uart_port_set_label(&ld->port, p + n + 1);
			return;
		}
	}
}

/*
 * A label ends up in the sensor's address and its uevents: ASCII letters,
 * digits and "_.-" only (the kernel's isalnum() also takes Latin-1 letters).
 */
static bool ev3_uart_label_ok(const char *label, size_t size)
{
	size_t i, n = strnlen(label, size);
	char c;

	if (n == size)
		return false;
	for (i = 0; i < n; i++) {
		c = label[i];
		if (!(c >= 'a' && c <= 'z') && !(c >= 'A' && c <= 'Z') &&
		    !(c >= '0' && c <= '9') && c != '_' && c != '.' && c != '-')
			return false;
	}
	return true;
}

/* Every port_labels entry must be "tty=label" with a valid label. */
static int ev3_uart_check_port_labels(void)
{
	const char *p, *eq;
	int i;

	for (i = 0; i < num_port_labels; i++) {
		p = port_labels[i];
		eq = p ? strchr(p, '=') : NULL;
		if (!eq || eq == p || !ev3_uart_label_ok(eq + 1, EV3_UART_LABEL_LEN)) {
			pr_err("port_labels: \"%s\" is not tty=label (label: up to %d of [A-Za-z0-9_.-])\n",
			       p ?: "", EV3_UART_LABEL_LEN - 1);
			return -EINVAL;
		}
	}
	return 0;
}

/*
 * debugfs lego_ev3_uart/TTY/counters: the port's counters (struct
 * ev3_uart_stats, then struct ev3_uart_tx_stats), one "name value" a line.
 */
static int ev3_uart_counters_show(struct seq_file *m, void *unused)
{
	struct ev3_uart_ldisc *ld = m->private;
	struct ev3_uart_tx_stats tx;
	struct ev3_uart_stats st;
	u8 state;

	state = ev3_uart_port_stats(&ld->port, &st);
	mutex_lock(&ld->tx_mutex);
	tx = ld->stats;
	mutex_unlock(&ld->tx_mutex);

	seq_printf(m, "state %u\n", state);
	seq_printf(m, "syncs %llu\n", st.syncs);
	seq_printf(m, "handshakes %llu\n", st.handshakes);
	seq_printf(m, "info_msgs %llu\n", st.info_msgs);
	seq_printf(m, "data_msgs %llu\n", st.data_msgs);
	seq_printf(m, "resyncs %llu\n", st.resyncs);
	seq_printf(m, "line_errors %llu\n", st.line_errors);
	seq_printf(m, "garbage %llu\n", st.garbage);
	seq_printf(m, "bad_frames %llu\n", st.bad_frames);
	seq_printf(m, "speed_changes %llu\n", st.speed_changes);
	seq_printf(m, "fast_syncs %llu\n", st.fast_syncs);
	seq_printf(m, "registered %llu\n", st.registered);
	seq_printf(m, "lost %llu\n", st.lost);
	seq_printf(m, "tx_ack %llu\n", tx.tx_ack);
	seq_printf(m, "tx_nack %llu\n", tx.tx_nack);
	seq_printf(m, "tx_select %llu\n", tx.tx_select);
	seq_printf(m, "tx_write %llu\n", tx.tx_write);
	seq_printf(m, "tx_speed %llu\n", tx.tx_speed);
	seq_printf(m, "tx_errors %llu\n", tx.tx_errors);
	return 0;
}
DEFINE_SHOW_ATTRIBUTE(ev3_uart_counters);

static int ev3_uart_ioctl(struct tty_struct *tty, unsigned int cmd,
			  unsigned long arg)
{
	struct ev3_uart_ldisc *ld = tty->disc_data;
	void __user *uarg = (void __user *)arg;
	struct lego_ev3_port_label pl;

	switch (cmd) {
	case LEGO_EV3_SET_PORT_LABEL:
		if (!capable(CAP_SYS_ADMIN))
			return -EPERM;
		if (copy_from_user(&pl, uarg, sizeof(pl)))
			return -EFAULT;
		if (!ev3_uart_label_ok(pl.label, sizeof(pl.label)))
			return -EINVAL;
		ev3_uart_port_set_label(&ld->port, pl.label);
		return 0;
	case LEGO_EV3_GET_PORT_LABEL:
		ev3_uart_port_get_label(&ld->port, pl.label);
		return copy_to_user(uarg, &pl, sizeof(pl)) ? -EFAULT : 0;
	default:
		/* termios ioctls (tcgetattr...) keep working. */
		return tty_mode_ioctl(tty, cmd, arg);
	}
}

/*
 * The tty's flags are the core's: a byte received without error is
 * TTY_NORMAL (0), a break TTY_BREAK; any other is a line error.
 */
static void ev3_uart_receive_buf(struct tty_struct *tty, const u8 *cp,
				 const LEGO_TTY_FLAG *fp,
				 LEGO_TTY_COUNT count)
{
	struct ev3_uart_ldisc *ld = tty->disc_data;

	BUILD_BUG_ON(TTY_NORMAL != EV3_UART_RX_OK || TTY_BREAK != EV3_UART_RX_BREAK);
	BUILD_BUG_ON(sizeof(*fp) != 1);
	ev3_uart_port_receive(&ld->port, cp, (const u8 *)fp, count);
}

static int ev3_uart_open(struct tty_struct *tty)
{
	struct ev3_uart_ldisc *ld;
	int ret;

	if (!capable(CAP_SYS_ADMIN))
		return -EPERM;

	/*
	 * The protocol needs to send ACK, NACK and SELECT. The other tty
	 * operations used are optional: set_termios is called only when
	 * present (a pty master has none); flush_buffer, chars_in_buffer and
	 * wait_until_sent only through the tty core's helpers, which check.
	 */
	if (!tty->ops->write)
		return -EOPNOTSUPP;

	ld = kzalloc_obj(*ld, GFP_KERNEL);
	if (!ld)
		return -ENOMEM;
	ret = ev3_uart_port_init(&ld->port, &ev3_uart_tty_ops, tty->name,
				 tty->dev, EV3_UART_SPEED_MIN);
	if (ret) {
		kfree(ld);
		return ret;
	}
	ld->tty = tty;
	mutex_init(&ld->tx_mutex);
	INIT_WORK(&ld->tx_work, ev3_uart_tx_work);
	ev3_uart_find_label(ld);

	ev3_uart_setup_tty(tty);
	ld->debugfs = debugfs_create_dir(tty->name, ev3_uart_debugfs_root);
	debugfs_create_file("counters", 0400, ld->debugfs, ld,
			    &ev3_uart_counters_fops);
	tty->disc_data = ld;
	tty->receive_room = 65536;
	tty_driver_flush_buffer(tty);
	ev3_uart_port_start(&ld->port);
	return 0;
}

static void ev3_uart_close(struct tty_struct *tty)
{
	struct ev3_uart_ldisc *ld = tty->disc_data;

	/* No more work of the core, which may send: then the tty's own. */
	ev3_uart_port_stop(&ld->port);
	debugfs_remove_recursive(ld->debugfs);

	/*
	 * No work or user writes any more: the last tx_work, which sets the
	 * wakeup flag when it writes, then the flag, which would else stay
	 * set for the next discipline. No write_wakeup comes meanwhile to
	 * queue tx_work again: the tty core holds the discipline locked
	 * around close(), and tty_wakeup() calls no discipline then.
	 */
	cancel_work_sync(&ld->tx_work);
	clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	tty->disc_data = NULL;
	kfree(ld);
}

static struct tty_ldisc_ops ev3_uart_ldisc = {
	.owner		= THIS_MODULE,
	.num		= EV3_UART_LDISC_NUM,
	.name		= EV3_UART_LDISC_NAME,
	.open		= ev3_uart_open,
	.close		= ev3_uart_close,
	.ioctl		= ev3_uart_ioctl,
	.receive_buf	= ev3_uart_receive_buf,
	.write_wakeup	= ev3_uart_write_wakeup,
};

/*
 * The views, the class first: its add names the sensor ("sensorN") for
 * the log lines and the LED names of the ones after it.
 */
static int ev3_uart_views_init(void)
{
	int ret = ev3_uart_class_init();

	if (ret)
		return ret;
	ret = ev3_uart_iio_init();
	if (ret)
		goto class_exit;
	ret = ev3_uart_leds_init();
	if (ret)
		goto iio_exit;
	return 0;

iio_exit:
	ev3_uart_iio_exit();
class_exit:
	ev3_uart_class_exit();
	return ret;
}

static void ev3_uart_views_exit(void)
{
	ev3_uart_leds_exit();
	ev3_uart_iio_exit();
	ev3_uart_class_exit();
}

static int __init ev3_uart_init(void)
{
	int ret;

	ret = ev3_uart_check_port_labels();
	if (ret)
		return ret;
	ret = ev3_uart_core_init();
	if (ret)
		return ret;
	ret = ev3_uart_views_init();
	if (ret)
		goto core_exit;

	ev3_uart_debugfs_root = debugfs_create_dir(KBUILD_MODNAME, NULL);
	ret = tty_register_ldisc(&ev3_uart_ldisc);
	if (ret) {
		pr_err("cannot register line discipline %d: %d\n",
		       EV3_UART_LDISC_NUM, ret);
		debugfs_remove_recursive(ev3_uart_debugfs_root);
		ev3_uart_views_exit();
		goto core_exit;
	}
	return 0;

core_exit:
	ev3_uart_core_exit();
	return ret;
}
module_init(ev3_uart_init);

static void __exit ev3_uart_exit(void)
{
	tty_unregister_ldisc(&ev3_uart_ldisc);
	debugfs_remove_recursive(ev3_uart_debugfs_root);
	ev3_uart_views_exit();
	ev3_uart_core_exit();
}
module_exit(ev3_uart_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS EV3 UART sensor line discipline");
MODULE_LICENSE("GPL");
MODULE_ALIAS_LDISC(EV3_UART_LDISC_NUM);
