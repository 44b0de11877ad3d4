// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: tty line discipline.
 *
 * Attach it to any tty a sensor is wired to (N_LEGOEV3, e.g. with ldattach).
 * This file is the transport glue: it owns the tty, the work items and the
 * sensor's lifetime. The protocol itself lives in ev3_uart_proto.c, the
 * lego-sensor class in ev3_uart_class.c; locking is described in ev3_uart.h.
 *
 * Life of a connection:
 *  - when the discipline is attached, when a device resets (its TX held
 *    low: a break) and when a sensor was lost, the fast sync probe first
 *    (ev3_uart_probe()): SPEED 115200 at 115200 baud; a Powered Up device
 *    that answers ACK sends its handshake at 115200, else the line goes
 *    back to 2400 baud 30 ms later;
 *  - at 2400 baud the parser hunts for a TYPE message and reads the
 *    handshake;
 *  - on the sensor's ACK, ack_timer fires 10 ms later (the sensor waits
 *    80 ms at most; a delayed work would wait 0 to 10 ms at HZ=100) and
 *    ack_work answers ACK, switches the tty to the sensor's speed and
 *    registers the sensor;
 *  - keepalive_work sends NACK every 100 ms from the moment the speed is
 *    switched, registration included (the sensor resets itself after
 *    about a second without one) and declares the sensor lost after about
 *    700 ms without data;
 *  - reset_work unregisters a lost sensor and goes back to 2400 baud, where
 *    a new handshake brings it back.
 * Nothing sleeps or waits in the receive path.
 *
 * Attaching requires CAP_SYS_ADMIN: a user who could attach the discipline to
 * a pty could play a hostile "sensor" and make the kernel register devices of
 * its choosing.
 */
#define pr_fmt(fmt) KBUILD_MODNAME ": " fmt

#include <linux/capability.h>
#include <linux/debugfs.h>
#include <linux/hrtimer.h>
#include <linux/jiffies.h>
#include <linux/log2.h>
#include <linux/lockdep.h>
#include <linux/module.h>
#include <linux/moduleparam.h>
#include <linux/ratelimit.h>
#include <linux/sched.h>
#include <linux/seq_file.h>
#include <linux/slab.h>
#include <linux/string.h>
#include <linux/sysfs.h>
#include <linux/tty.h>
#include <linux/tty_ldisc.h>
#include <linux/uaccess.h>
#include <linux/workqueue.h>
#include <linux/lego_ev3_uart.h>

#include "lego_compat.h"
#include "ev3_uart.h"
#include "ev3_uart_chan.h"
#include "ev3_uart_trace.h"

#define EV3_UART_LDISC_NAME	"n_legoev3"
#define EV3_UART_ACK_DELAY_MS	10	/* like LEGO's firmware; the sensor allows 80 */
#define EV3_UART_KEEPALIVE_MS	100
#define EV3_UART_SELECT_WAIT_MS	250	/* > 62 ms, the slowest first reply */
#define EV3_UART_SELECT_TRIES	3
#define EV3_UART_RESTORE_GRACE	(2 * HZ)
#define EV3_UART_RESTORE_EVERY	3	/* keep-alive periods between SELECTs */
#define EV3_UART_RESTORE_TICKS	15	/* give up after that many periods */
#define EV3_UART_PROBE_WAIT_MS	30	/* for the ACK to SPEED, once it is out */
#define EV3_UART_FAST_SYNC_MS	500	/* from that ACK to the handshake's */
#define EV3_UART_PROBE_HOLDOFF	(HZ / 10)	/* between probes breaks ask for */

/*
 * N_LEGOEV3 from <linux/lego_ev3_uart.h>. There is no parameter to choose
 * another number: tty_register_ldisc() does not check that a number is
 * free, so any other would replace a discipline in use.
 */
#define EV3_UART_LDISC_NUM	N_LEGOEV3

/* lego_ev3_uart in debugfs, with a directory per port (ev3_uart_open()). */
static struct dentry *ev3_uart_debugfs_root;

/*
 * The keep-alives' workqueue: high priority and unbound, so that a NACK
 * does not wait for a worker of the shared unbound pool, whose workers may
 * all be blocked registering sensors (each port's own work items run
 * there too): one keep-alive was measured 194 ms late in the test VM with
 * its CPUs running, while other ports registered sensors.
 */
static struct workqueue_struct *ev3_uart_keepalive_wq;

static char *port_labels[8];
static int num_port_labels;
module_param_array(port_labels, charp, &num_port_labels, 0444);
MODULE_PARM_DESC(port_labels,
		 "port labels for the sensor address, as tty=label (e.g. ttyUSB0=in1,ttyAMA0=in2)");

/*
 * How long a new mode's first values may be stale: the infrared sensor
 * returns leftovers for about 1.1 s after a switch (LEGO's firmware ignores
 * its data for 1100 ms); the colour sensor for a few ms. Powered Up: the
 * colour sensors 30 ms, the SPIKE distance sensor 50 ms (what Pybricks
 * waits).
 */
static unsigned int ev3_uart_settle_ms(const struct ev3_uart_sensor *desc)
{
	if (desc->lump) {
		switch (desc->type) {
		case EV3_UART_TYPE_BOOST_CDS:
		case EV3_UART_TYPE_SPIKE_COLOR:
			return 30;
		case EV3_UART_TYPE_SPIKE_DIST:
			return 50;
		default:
			return 0;
		}
	}
	switch (desc->type) {
	case EV3_UART_TYPE_IR:
		return 1100;
	case EV3_UART_TYPE_COLOR:
		return 30;
	default:
		return 0;
	}
}

/*
 * Hand the queued bytes to the tty driver, as many as it takes. A driver
 * whose buffer is full takes part of a message or none of it: the rest
 * stays queued and goes out from write_wakeup, so a message is never cut
 * short on the wire (can327 does the same). The wakeup flag is set before
 * writing, so a wakeup for room made meanwhile is not lost.
 */
static int ev3_uart_tx_flush(struct ev3_uart_port *port)
{
	struct tty_struct *tty = port->tty;
	int n;

	lockdep_assert_held(&port->tx_mutex);
	set_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	while (port->tx_len) {
		n = tty->ops->write(tty, port->tx_buf + port->tx_pos, port->tx_len);
		if (n < 0) {
			/* The tty is gone or broken: what is queued is lost. */
			port->tx_len = 0;
			clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
			return n;
		}
		if (!n)
			return 0;	/* full: write_wakeup sends the rest */
		port->tx_pos += n;
		port->tx_len -= n;
	}
	port->tx_pos = 0;
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
static void ev3_uart_tx_account(struct ev3_uart_port *port, const u8 *buf,
				size_t len, int ret)
{
	struct ev3_uart_stats *st = &port->stats;
	u8 kind = ev3_uart_tx_kind(buf[0]);

	lockdep_assert_held(&port->tx_mutex);
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
	trace_ev3_uart_tx(port->tty->name, kind, buf[0], len > 1 ? buf[1] : 0,
			  len, ret);
}

/*
 * Latch the tty's write errors, as can327 does: the first one is logged,
 * the others (a keep-alive every 100 ms) only counted, until a message goes
 * out again. @tx_mutex held. Return: what to log: 1 the first error, -1
 * the recovery, 0 nothing.
 */
static int ev3_uart_tx_latch(struct ev3_uart_port *port, int ret)
{
	bool was = port->tx_failed;

	lockdep_assert_held(&port->tx_mutex);
	port->tx_failed = ret;
	if (ret && !was)
		return 1;
	return !ret && was ? -1 : 0;
}

static void ev3_uart_tx_log(struct ev3_uart_port *port, int what, int err)
{
	if (what > 0)
		pr_warn("%s: cannot send to the tty: %d (not logged again until a message goes out)\n",
			port->tty->name, err);
	else if (what < 0)
		pr_info("%s: sending to the tty again\n", port->tty->name);
}

/*
 * Drop what is queued and not yet on the wire: on a speed change (it was
 * meant for the old speed) and when a sensor is lost (a SELECT or a WRITE
 * for it must not reach the next one). Both what is still in @tx_buf and
 * what the tty driver holds and has not sent: a UART's buffer behind a
 * held transmitter, a USB adapter's, would else send it at the new speed
 * or to the next sensor. The ACK is waited for before its speed change
 * (ack_work), the probe's SPEED before the probe ends. Not on a pty: it
 * holds nothing, what is written is in the other end's input at once, and
 * its flush_buffer drops that (an ACK the sensor has not read yet).
 */
static void ev3_uart_tx_discard(struct ev3_uart_port *port)
{
	struct tty_struct *tty = port->tty;

	mutex_lock(&port->tx_mutex);
	port->tx_len = 0;
	port->tx_pos = 0;
	if (tty->driver->type != TTY_DRIVER_TYPE_PTY)
		tty_driver_flush_buffer(tty);
	mutex_unlock(&port->tx_mutex);
}

/* Queue a whole message behind what is still queued, and send. */
static int ev3_uart_tx(struct ev3_uart_port *port, const u8 *buf, size_t len)
{
	int ret, log;

	mutex_lock(&port->tx_mutex);
	if (port->tx_pos) {
		memmove(port->tx_buf, port->tx_buf + port->tx_pos, port->tx_len);
		port->tx_pos = 0;
	}
	if (len > sizeof(port->tx_buf) - port->tx_len) {
		ret = -ENOBUFS;
	} else {
		memcpy(port->tx_buf + port->tx_len, buf, len);
		port->tx_len += len;
		ret = ev3_uart_tx_flush(port);
	}
	ev3_uart_tx_account(port, buf, len, ret);
	log = ev3_uart_tx_latch(port, ret);
	mutex_unlock(&port->tx_mutex);
	ev3_uart_tx_log(port, log, ret);
	return ret;
}

static void ev3_uart_tx_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(work, struct ev3_uart_port,
						  tx_work);
	int ret = 0, log = 0;

	mutex_lock(&port->tx_mutex);
	if (port->tx_len) {
		ret = ev3_uart_tx_flush(port);
		log = ev3_uart_tx_latch(port, ret);
	}
	mutex_unlock(&port->tx_mutex);
	ev3_uart_tx_log(port, log, ret);
}

/* The driver has room again: send the rest from process context. */
static void ev3_uart_write_wakeup(struct tty_struct *tty)
{
	struct ev3_uart_port *port = tty->disc_data;

	queue_work(system_dfl_wq, &port->tx_work);
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
 * Only from the work items on the port's ordered workqueue (and open()),
 * which keep @port->speed.
 *
 * Return: 0, or -%EINVAL if the tty runs at another speed than @baud.
 */
static int ev3_uart_set_speed(struct ev3_uart_port *port, unsigned int baud)
{
	struct tty_struct *tty = port->tty;
	struct ktermios t;
	speed_t got;
	int ret;

	ev3_uart_tx_discard(port);
	down_read(&tty->termios_rwsem);
	t = tty->termios;
	up_read(&tty->termios_rwsem);
	tty_termios_encode_baud_rate(&t, baud, baud);
	ev3_uart_set_termios(tty, &t);
	ret = 0;
	if (tty->ops->set_termios) {
		down_read(&tty->termios_rwsem);
		got = tty_termios_baud_rate(&tty->termios);
		up_read(&tty->termios_rwsem);
		ret = abs((int)got - (int)baud) <= baud / 50 ? 0 : -EINVAL;
	}
	port->speed = ret ? 0 : baud;
	spin_lock(&port->lock);
	port->stats.speed_changes++;
	spin_unlock(&port->lock);
	trace_ev3_uart_speed(tty->name, baud, ret);
	return ret;
}

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

/*
 * The lines a port logs for each connection, loss and protocol error: a
 * device that keeps failing must not flood the log (its reconnects are
 * also held off, see ev3_uart_backoff_lost()).
 */
#define ev3_uart_info(port, fmt, ...)					\
	do {								\
		if (__ratelimit(&(port)->log_rs))			\
			pr_info(fmt, ##__VA_ARGS__);			\
	} while (0)

static void ev3_uart_queue(struct ev3_uart_port *port, struct work_struct *work)
{
	lockdep_assert_held(&port->lock);
	if (!port->closing)
		queue_work(port->wq, work);
}

/*
 * The parser left state @from: trace it, with @why or the reason @ev gives.
 * @lock held.
 */
static void ev3_uart_trace_state(struct ev3_uart_port *port, u8 from,
				 const struct ev3_uart_event *ev,
				 const char *why)
{
	u8 to = port->parser.state;

	if (from == to)
		return;
	if (!why && ev && ev->type == EV3_UART_EV_ERROR)
		why = ev->reason;
	else if (!why && ev && ev->type == EV3_UART_EV_SYNC)
		why = "TYPE message";
	else if (!why && ev && ev->type == EV3_UART_EV_HANDSHAKE)
		why = "ACK from the sensor";
	else if (!why && ev && ev->type == EV3_UART_EV_FAST)
		why = "ACK to SPEED: fast sync";
	trace_ev3_uart_state(port->tty->name, from, to, why ?: "");
}

/*
 * How the DATA message of @ev was accepted: all have a good checksum but
 * the colour sensor's RGB-RAW ones, whose checksum is not checked (see
 * ev3_uart_rgb_raw_quirk()); the ultrasonic sensor's US-DC-IN ones come
 * tagged with the wrong mode.
 */
static u8 ev3_uart_accepted_by(const struct ev3_uart_port *port,
			       const struct ev3_uart_event *ev)
{
	if (ev->us_dc_in)
		return EV3_UART_TRACE_QUIRK_US_DC_IN;
	if (port->parser.sensor.type == EV3_UART_TYPE_COLOR && ev->mode == 4 &&
	    ev->len == 8)
		return EV3_UART_TRACE_QUIRK_RGB_RAW;
	return EV3_UART_TRACE_CSUM;
}

/* The header the DATA message of @ev had (mode 5 for a US-DC-IN one). */
static u8 ev3_uart_data_hdr(const struct ev3_uart_event *ev)
{
	u8 mode = ev->us_dc_in ? 5 : ev->mode;

	return EV3_UART_MSG_DATA |
	       (ilog2(ev->len ?: 1) << EV3_UART_MSG_SIZE_SHIFT) |
	       (mode & EV3_UART_MSG_CMD_MASK);
}

/*
 * Called under port->lock, in the receive path (and from keepalive_work).
 * @rest: bytes received after the message that caused @ev, in the same batch.
 * @from: the parser's state before it made @ev.
 */
static void ev3_uart_event(struct ev3_uart_port *port,
			   const struct ev3_uart_event *ev, size_t rest,
			   u8 from)
{
	struct ev3_uart_sensor_dev *sd = port->sensor;
	const struct ev3_uart_sensor *s = &port->parser.sensor;

	lockdep_assert_held(&port->lock);
	if (trace_ev3_uart_state_enabled())
		ev3_uart_trace_state(port, from, ev, NULL);
	switch (ev->type) {
	case EV3_UART_EV_SYNC:
		port->probe_missed = false;
		/* A TYPE at 2400 during the probe: no need to wait for it. */
		if (from == EV3_UART_STATE_PROBE)
			complete(&port->probe_done);
		pr_debug("%s: sensor type %u syncing\n", port->tty->name,
			 port->parser.sensor.type);
		port->stats.syncs++;
		trace_ev3_uart_rx(port->tty->name, EV3_UART_TRACE_TYPE,
				  EV3_UART_MSG_CMD | EV3_UART_CMD_TYPE, s->type, 0,
				  3, EV3_UART_TRACE_CSUM, false);
		break;
	case EV3_UART_EV_MSG:
		/* Only while ev3_uart_rx is enabled (see receive_buf()). */
		port->stats.info_msgs++;
		trace_ev3_uart_rx(port->tty->name,
				  (ev->mode & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_INFO ?
				  EV3_UART_TRACE_INFO : EV3_UART_TRACE_CMD,
				  ev->mode, ev->mode & EV3_UART_MSG_CMD_MASK,
				  port->parser.msg_info, ev->len,
				  EV3_UART_TRACE_CSUM, false);
		break;
	case EV3_UART_EV_HANDSHAKE:
		port->stats.handshakes++;
		trace_ev3_uart_rx(port->tty->name, EV3_UART_TRACE_ACK,
				  EV3_UART_SYS_ACK, s->num_modes, 0, 1,
				  EV3_UART_TRACE_NONE, false);
		trace_ev3_uart_handshake(port->tty->name, s->type, s->num_modes,
					 s->num_view_modes, s->speed);
		if (!port->closing)
			hrtimer_start(&port->ack_timer,
				      ms_to_ktime(EV3_UART_ACK_DELAY_MS),
				      HRTIMER_MODE_REL);
		break;
	case EV3_UART_EV_DATA:
		port->stats.data_msgs++;
		if (trace_ev3_uart_rx_enabled())
			trace_ev3_uart_rx(port->tty->name, EV3_UART_TRACE_DATA,
					  ev3_uart_data_hdr(ev),
					  ev->mode, 0, ev->len,
					  ev3_uart_accepted_by(port, ev),
					  ev->mode_changed);
		if (!sd)
			break;
		/*
		 * Not only on ev->mode_changed: a SELECT written through sysfs
		 * between the sensor's registration and ack_work publishing it
		 * in port->sensor is confirmed by DATA nobody passed on.
		 */
		if (ev->mode != sd->mode) {
			sd->mode = ev->mode;
			sd->settle_until = jiffies +
				msecs_to_jiffies(ev3_uart_settle_ms(&sd->desc));
			ev3_uart_queue(port, &sd->mode_work);
		}
		memcpy(sd->data, port->parser.data, ev->len);
		memset(sd->data + ev->len, 0, sizeof(sd->data) - ev->len);
		sd->data_len = ev->len;
		ev3_uart_iio_push(sd, ev->mode, sd->data, ev->len, rest);
		if (port->select_mode == ev->mode &&
		    port->parser.pending_mode == EV3_UART_NO_MODE) {
			port->select_mode = EV3_UART_NO_MODE;
			complete(&port->select_done);
		}
		break;
	case EV3_UART_EV_ERROR:
		port->stats.resyncs++;
		port->last_error = ev->reason;
		ev3_uart_info(port, "%s: %s\n", port->tty->name, ev->reason);
		ev3_uart_queue(port, &port->reset_work);
		break;
	case EV3_UART_EV_FAST:
		/* The probe's answer: ev3_uart_probe() waits for it. */
		port->stats.fast_syncs++;
		port->probe_missed = false;
		complete(&port->probe_done);
		break;
	case EV3_UART_EV_NONE:
		break;
	}
}

/*
 * A break while hunting for a sensor (or probing): a device that resets
 * holds its TX low for about 500 ms, and a Powered Up device listens for
 * the fast sync probe meanwhile (Pybricks' hubs probe when they detect a
 * device, on pins a tty does not have). Some UARTs report a break again
 * and again while the line is low: one probe every 100 ms at most, the
 * next one put off until then rather than skipped (a break during a probe
 * may be a device that was not listening yet). But not after a break whose
 * probe was not answered and no handshake followed. @lock held.
 */
static void ev3_uart_break(struct ev3_uart_port *port)
{
	unsigned long next = port->probed_at + EV3_UART_PROBE_HOLDOFF;

	lockdep_assert_held(&port->lock);
	if (READ_ONCE(port->no_probe) || port->closing)
		return;
	if (port->parser.state == EV3_UART_STATE_SYNC &&
	    port->parser.sync_speed != EV3_UART_SPEED_MIN)
		return;		/* answered: its handshake comes */
	/*
	 * The last break's probe went unanswered and no handshake followed:
	 * maybe a device whose ACK reached us too late, which resets when
	 * its fast handshake is not answered. Let it go on at 2400 this time
	 * rather than catch it in its fast sync again and again.
	 */
	if (port->probe_missed) {
		port->probe_missed = false;
		return;
	}
	port->break_probe = true;
	queue_delayed_work(port->wq, &port->probe_work,
			   port->probed_at && time_before(jiffies, next) ?
			   next - jiffies : 0);
}

static void ev3_uart_receive_buf(struct tty_struct *tty, const u8 *cp,
				 const LEGO_TTY_FLAG *fp,
				 LEGO_TTY_COUNT count)
{
	struct ev3_uart_port *port = tty->disc_data;
	struct ev3_uart_event ev;
	size_t run, used;
	u8 from;

	spin_lock(&port->lock);
	/* The handshake's messages one by one, for ev3_uart_rx. */
	port->parser.report_msgs = trace_ev3_uart_rx_enabled();
	while (count > 0) {
		from = port->parser.state;
		if (fp && *fp != TTY_NORMAL) {
			if (*fp == TTY_BREAK && (from == EV3_UART_STATE_SYNC ||
						 from == EV3_UART_STATE_PROBE))
				ev3_uart_break(port);
			port->stats.line_errors++;
			ev3_uart_parser_line_error(&port->parser, &ev);
			cp++;
			fp++;
			count--;
			ev3_uart_event(port, &ev, count, from);
			continue;
		}
		/* Feed the run of bytes received without error. */
		for (run = 1; run < count && (!fp || fp[run] == TTY_NORMAL); run++)
			;
		used = ev3_uart_parser_feed(&port->parser, cp, run, &ev);
		cp += used;
		if (fp)
			fp += used;
		count -= used;
		/* The event's message ended @count bytes before the batch did. */
		ev3_uart_event(port, &ev, count, from);
	}
	spin_unlock(&port->lock);
}

/*
 * Hard interrupt context: only queue the work. close() cancels the timer
 * before the work, so the work queue still exists here.
 */
static enum hrtimer_restart ev3_uart_ack_timer(struct hrtimer *timer)
{
	struct ev3_uart_port *port = container_of(timer, struct ev3_uart_port,
						  ack_timer);

	queue_work(port->wq, &port->ack_work);
	return HRTIMER_NORESTART;
}

/* Hard interrupt context, as the ACK's timer: only queue the keep-alive. */
static enum hrtimer_restart ev3_uart_keepalive_timer(struct hrtimer *timer)
{
	struct ev3_uart_port *port = container_of(timer, struct ev3_uart_port,
						  keepalive_timer);

	queue_work(ev3_uart_keepalive_wq, &port->keepalive_work);
	return HRTIMER_NORESTART;
}

/*
 * Stop the keep-alive: its timer queues its work, and its work starts the
 * timer again, so each is cancelled until neither is pending or running.
 * Not from the keep-alive work itself.
 */
static void ev3_uart_keepalive_stop(struct ev3_uart_port *port)
{
	do {
		hrtimer_cancel(&port->keepalive_timer);
	} while (cancel_work_sync(&port->keepalive_work) ||
		 hrtimer_active(&port->keepalive_timer));
}

/*
 * Restore the mode the user chose before the sensor was lost. A user who is
 * choosing a mode right now (holding select_mutex) wins: no restore then.
 */
static void ev3_uart_restore_mode(struct ev3_uart_port *port,
				  const struct ev3_uart_sensor *desc)
{
	u8 select[3], mode = EV3_UART_NO_MODE;

	if (!mutex_trylock(&port->select_mutex))
		return;
	spin_lock(&port->lock);
	if (port->requested_mode != EV3_UART_NO_MODE &&
	    port->requested_type == desc->type &&
	    port->requested_lump == desc->lump &&
	    port->requested_mode < desc->num_modes &&
	    !ev3_uart_parser_select(&port->parser, port->requested_mode)) {
		mode = port->requested_mode;
		port->restored_at = jiffies;
		port->restore_mode = mode;
		port->restore_ticks = 0;
	}
	spin_unlock(&port->lock);
	if (mode != EV3_UART_NO_MODE)
		ev3_uart_tx(port, select, ev3_uart_build_select(select, mode));
	mutex_unlock(&port->select_mutex);
}

/*
 * Starts the parser again, hunting for a sensor at 2400 baud, after @why;
 * its counts go to the port's. @lock held.
 */
static void ev3_uart_parser_restart(struct ev3_uart_port *port, const char *why)
{
	u8 from = port->parser.state;

	lockdep_assert_held(&port->lock);
	port->stats.garbage += port->parser.garbage;
	port->stats.bad_frames += port->parser.bad_frames;
	ev3_uart_parser_init(&port->parser);
	ev3_uart_trace_state(port, from, NULL, why);
}

/* A sensor was registered, lost, or could not be; for the trace. */
static void ev3_uart_trace_sensor(struct ev3_uart_port *port, u8 what,
				  const struct ev3_uart_sensor *desc,
				  struct ev3_uart_sensor_dev *sd)
{
	trace_ev3_uart_sensor(port->tty->name, what, desc->type,
			      sd ? sd->driver_name : "",
			      sd ? dev_name(&sd->dev) : "", desc->speed);
}

/*
 * The fast sync probe (SPEED 115200 at 115200 baud): Powered Up devices
 * that can send their handshake at 115200 answer ACK within a millisecond
 * and send it then, a few hundred bytes in tens of milliseconds instead of
 * seconds at 2400. The others (EV3 sensors, the BOOST colour and distance
 * sensor, devices busy with something else) do not answer: after 30 ms
 * the line goes back to 2400 baud, where the parser hunts as before. The
 * parser hunts for a TYPE at 2400 meanwhile too: on a line that carries
 * bytes whatever the speed (a pty) an EV3 sensor's TYPE ends the wait, and
 * its handshake goes on at 2400. On a UART, bytes sent at 2400 meanwhile
 * arrive garbled and are lost (an EV3 sensor caught in its handshake
 * repeats it). After the answer, the handshake must come within 500 ms
 * (ev3_uart_fast_work()). Only from the port's workqueue, with the parser
 * in SYNC at 2400 baud (else nothing is done).
 *
 * Return: true if the probe was made (the line is then at the speed the
 * parser hunts at), false if not (the line is as it was). @on_break: for
 * a break (see ev3_uart_break()).
 */
static bool ev3_uart_probe(struct ev3_uart_port *port, bool on_break)
{
	u8 msg[EV3_UART_SPEED_MSG_LEN], from;
	const char *why = "no answer to SPEED";
	u32 speed;
	int ret;

	if (port->no_probe)
		return false;
	cancel_delayed_work(&port->fast_work);
	spin_lock(&port->lock);
	from = port->parser.state;
	ret = port->closing ? -ESHUTDOWN :
	      ev3_uart_parser_probe(&port->parser, EV3_UART_SPEED_FAST);
	if (!ret) {
		reinit_completion(&port->probe_done);
		port->probed_at = jiffies ?: 1;
		ev3_uart_trace_state(port, from, NULL, "fast sync probe");
	}
	spin_unlock(&port->lock);
	if (ret)
		return false;

	if (ev3_uart_set_speed(port, EV3_UART_SPEED_FAST)) {
		pr_info("%s: cannot set %u baud: no fast sync for Powered Up devices\n",
			port->tty->name, EV3_UART_SPEED_FAST);
		WRITE_ONCE(port->no_probe, true);
		why = "no fast sync on this tty";
	} else if (!ev3_uart_tx(port, msg,
				ev3_uart_build_speed(msg, EV3_UART_SPEED_FAST))) {
		/*
		 * From when it is out. Pybricks waits 10 ms, on a UART of its
		 * own; a USB serial adapter may hold the ACK 16 ms (an FTDI
		 * chip's latency timer) before the tty sees it.
		 */
		tty_wait_until_sent(port->tty, msecs_to_jiffies(50));
		wait_for_completion_timeout(&port->probe_done,
					    msecs_to_jiffies(EV3_UART_PROBE_WAIT_MS) + 1);
	}

	spin_lock(&port->lock);
	from = port->parser.state;
	speed = ev3_uart_parser_probe_end(&port->parser);
	ev3_uart_trace_state(port, from, NULL, why);
	port->probe_missed = on_break && speed == EV3_UART_SPEED_MIN &&
			     port->parser.state == EV3_UART_STATE_SYNC;
	if (speed != EV3_UART_SPEED_MIN && !port->closing)
		queue_delayed_work(port->wq, &port->fast_work,
				   msecs_to_jiffies(EV3_UART_FAST_SYNC_MS));
	spin_unlock(&port->lock);
	if (speed != port->speed)
		ev3_uart_set_speed(port, speed);
	return true;
}

/* Listen for the next device: the fast sync probe, else 2400 baud. */
static void ev3_uart_hunt(struct ev3_uart_port *port)
{
	if (!ev3_uart_probe(port, false) && port->speed != EV3_UART_SPEED_MIN)
		ev3_uart_set_speed(port, EV3_UART_SPEED_MIN);
}

static void ev3_uart_probe_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(to_delayed_work(work),
						  struct ev3_uart_port,
						  probe_work);
	bool on_break;

	spin_lock(&port->lock);
	on_break = port->break_probe;
	port->break_probe = false;
	spin_unlock(&port->lock);
	ev3_uart_probe(port, on_break);
}

/* A device answered the probe, and its handshake did not follow in time. */
static void ev3_uart_fast_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(to_delayed_work(work),
						  struct ev3_uart_port,
						  fast_work);
	bool late;

	spin_lock(&port->lock);
	late = port->parser.sync_speed != EV3_UART_SPEED_MIN &&
	       (port->parser.state == EV3_UART_STATE_SYNC ||
		port->parser.state == EV3_UART_STATE_INFO);
	if (late)
		ev3_uart_parser_restart(port, "no handshake after the fast sync");
	spin_unlock(&port->lock);
	if (late)
		ev3_uart_set_speed(port, EV3_UART_SPEED_MIN);
}

static void ev3_uart_ack_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(work, struct ev3_uart_port,
						  ack_work);
	struct tty_struct *tty = port->tty;
	struct ev3_uart_sensor_dev *sd;
	/* In the port: 16 modes are too much for the stack. */
	struct ev3_uart_sensor *desc = &port->ack_desc;
	const char *last_error, *why;
	u8 ack, from;

	spin_lock(&port->lock);
	if (port->closing || port->parser.state != EV3_UART_STATE_ACKED) {
		spin_unlock(&port->lock);
		return;
	}
	*desc = port->parser.sensor;
	spin_unlock(&port->lock);
	cancel_delayed_work(&port->fast_work);

	/*
	 * A device whose sensors keep failing right after they are
	 * registered: not before the back-off is over (it resets and comes
	 * again, as when its ACK is not answered).
	 */
	if (port->backoff_until && time_before(jiffies, port->backoff_until)) {
		pr_debug("%s: sensor type %u keeps failing; not answered yet\n",
			 tty->name, desc->type);
		why = "backing off a device that keeps failing";
		goto fail;
	}
	port->backoff_until = 0;

	/* Not again a speed this tty could not do (see below). */
	if (desc->speed == port->bad_speed) {
		pr_debug("%s: sensor type %u wants %u baud again; not answered\n",
			 tty->name, desc->type, desc->speed);
		why = "speed not supported by the tty";
		goto fail;
	}

	why = "ACK not sent";
	if (ev3_uart_tx(port, &ack, ev3_uart_build_ack(&ack)))
		goto fail;
	/*
	 * The sensor switches speed once it has our ACK: so do we. Not after
	 * a fast sync: the handshake came at the sensor's speed.
	 */
	if (desc->speed != port->speed)
		tty_wait_until_sent(tty, msecs_to_jiffies(50));
	if (desc->speed != port->speed && ev3_uart_set_speed(port, desc->speed)) {
		/*
		 * The UART cannot run at the sensor's speed, or its speed is
		 * locked (TIOCSLCKTRMIOS): the sensor would be lost and come
		 * back for ever. Say so once and leave its handshakes
		 * unanswered from now on.
		 */
		pr_err("%s: cannot set %u baud for sensor type %u: not connecting it\n",
		       tty->name, desc->speed, desc->type);
		port->bad_speed = desc->speed;
		why = "speed not supported by the tty";
		goto fail;
	}

	spin_lock(&port->lock);
	from = port->parser.state;
	ev3_uart_parser_start_data(&port->parser);
	ev3_uart_trace_state(port, from, NULL, "ACK answered, speed switched");
	spin_unlock(&port->lock);
	/*
	 * Keep the sensor alive from now on: it resets after about a second
	 * without NACK, and registering a sensor with many values can take
	 * that long on a slow or debug kernel. On an unbound workqueue, so
	 * that another CPU sends the NACKs while this one registers (without
	 * kernel preemption a per-CPU worker would wait for this one).
	 */
	queue_work(ev3_uart_keepalive_wq, &port->keepalive_work);

	sd = ev3_uart_sensor_create(port, desc);
	if (IS_ERR(sd)) {
		pr_err_ratelimited("%s: cannot register sensor: %pe\n",
				   tty->name, sd);
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_FAILED, desc, NULL);
		why = "sensor not registered";
		goto fail;
	}

	spin_lock(&port->lock);
	port->sensor = sd;
	port->stats.registered++;
	last_error = port->last_error;
	port->last_error = NULL;
	spin_unlock(&port->lock);
	port->registered_at = jiffies;
	ev3_uart_trace_sensor(port, EV3_UART_TRACE_REGISTERED, desc, sd);

	ev3_uart_info(port, "%s: %s connected as %s at %u baud\n", tty->name,
		      sd->driver_name, dev_name(&sd->dev), desc->speed);
	if (last_error)
		ev3_uart_info(port, "%s: reconnected after: %s\n", tty->name,
			      last_error);

	ev3_uart_restore_mode(port, desc);
	return;

fail:
	/* Started before a failed registration: done before the probe. */
	ev3_uart_keepalive_stop(port);
	spin_lock(&port->lock);
	ev3_uart_parser_restart(port, why);
	spin_unlock(&port->lock);
	ev3_uart_tx_discard(port);
	ev3_uart_hunt(port);
}

static void ev3_uart_keepalive_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(work, struct ev3_uart_port,
						  keepalive_work);
	struct ev3_uart_event ev;
	u8 nack, select[3], restore, from;
	bool alive;

	spin_lock(&port->lock);
	from = port->parser.state;
	if (ev3_uart_parser_tick(&port->parser, &ev))
		ev3_uart_event(port, &ev, 0, from);
	alive = port->parser.state == EV3_UART_STATE_DATA;
	/*
	 * The SELECT restoring the user's mode after a reconnect can arrive
	 * while the sensor still listens at 2400 baud: send it again now and
	 * then until a DATA message of that mode confirms it.
	 */
	restore = port->restore_mode;
	if (restore != EV3_UART_NO_MODE &&
	    port->parser.pending_mode != restore) {
		restore = EV3_UART_NO_MODE;
		port->restore_mode = EV3_UART_NO_MODE;
	} else if (restore != EV3_UART_NO_MODE &&
		   ++port->restore_ticks > EV3_UART_RESTORE_TICKS) {
		restore = EV3_UART_NO_MODE;	/* give up */
		port->restore_mode = EV3_UART_NO_MODE;
	} else if (port->restore_ticks % EV3_UART_RESTORE_EVERY) {
		restore = EV3_UART_NO_MODE;	/* not this period */
	}
	spin_unlock(&port->lock);
	if (!alive)
		return;

	/* Not while a user selects a mode: theirs wins (see set_mode). */
	if (restore != EV3_UART_NO_MODE && mutex_trylock(&port->select_mutex)) {
		spin_lock(&port->lock);
		if (port->restore_mode != restore ||
		    port->parser.pending_mode != restore)
			restore = EV3_UART_NO_MODE;
		spin_unlock(&port->lock);
		if (restore != EV3_UART_NO_MODE)
			ev3_uart_tx(port, select,
				    ev3_uart_build_select(select, restore));
		mutex_unlock(&port->select_mutex);
	}
	ev3_uart_tx(port, &nack, ev3_uart_build_nack(&nack));
	if (!READ_ONCE(port->closing))
		hrtimer_start(&port->keepalive_timer,
			      ms_to_ktime(EV3_UART_KEEPALIVE_MS), HRTIMER_MODE_REL);
}

/*
 * @sd was lost: hold off the next connections if the sensors on this line
 * keep failing right after they are registered. Only from reset_work.
 */
static void ev3_uart_backoff(struct ev3_uart_port *port,
			     const struct ev3_uart_sensor_dev *sd)
{
	unsigned int lived = jiffies_to_msecs(jiffies - port->registered_at);
	unsigned int wait = ev3_uart_backoff_lost(&port->backoff, lived);

	if (!wait)
		return;
	port->backoff_until = (jiffies + msecs_to_jiffies(wait)) ?: 1;
	ev3_uart_info(port, "%s: %s lost %u ms after it connected, %u times in a row: next connection in %u ms at the earliest\n",
		      port->tty->name, sd->driver_name, lived,
		      port->backoff.failures, wait);
}

static void ev3_uart_reset_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(work, struct ev3_uart_port,
						  reset_work);
	struct ev3_uart_sensor_dev *sd;

	/*
	 * A keep-alive that is running must be done before the line changes
	 * speed for the probe below: its NACK would go out at 115200, into
	 * the probe. It does not wait for this work.
	 */
	ev3_uart_keepalive_stop(port);

	spin_lock(&port->lock);
	sd = port->sensor;
	port->sensor = NULL;
	if (sd) {
		WRITE_ONCE(sd->gone, true);
		port->stats.lost++;
	}
	/* A sensor lost right after a restored mode does not get it again. */
	if (port->restored_at &&
	    time_before(jiffies, port->restored_at + EV3_UART_RESTORE_GRACE))
		port->requested_mode = EV3_UART_NO_MODE;
	port->restored_at = 0;
	port->restore_mode = EV3_UART_NO_MODE;
	port->select_mode = EV3_UART_NO_MODE;
	complete_all(&port->select_done);
	spin_unlock(&port->lock);

	ev3_uart_tx_discard(port);
	ev3_uart_hunt(port);
	if (sd) {
		ev3_uart_info(port, "%s: %s disconnected\n", port->tty->name,
			      sd->driver_name);
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_LOST, &sd->desc, sd);
		ev3_uart_backoff(port, sd);
		ev3_uart_sensor_destroy(sd);
	}
}

/**
 * ev3_uart_get_data() - read a sensor's current mode and last values
 * @sd: the sensor
 * @mode: its current mode
 * @data: %EV3_UART_MAX_PAYLOAD bytes for the last DATA payload
 *
 * Both are read together under the port lock, so they always match.
 *
 * Return: the payload length, or -%ENODEV if the sensor is gone.
 */
int ev3_uart_get_data(struct ev3_uart_sensor_dev *sd, u8 *mode, u8 *data)
{
	struct ev3_uart_port *port = sd->port;
	int len;

	spin_lock(&port->lock);
	if (sd->gone) {
		spin_unlock(&port->lock);
		return -ENODEV;
	}
	*mode = sd->mode;
	memcpy(data, sd->data, EV3_UART_MAX_PAYLOAD);
	len = sd->data_len;
	spin_unlock(&port->lock);
	return len;
}

/*
 * Wait until a new mode's values can be trusted: until @settle, then for one
 * DATA message received after it (the last one before may be stale too).
 * A lost sensor ends the wait at once: the sysfs write waiting here would
 * otherwise hold up reset_work's unregistering of the sensor, and with it
 * every work item of the port (the next sensor's ACK among them).
 */
static int ev3_uart_settle(struct ev3_uart_sensor_dev *sd, u8 mode,
			   unsigned long settle, unsigned long wait)
{
	struct ev3_uart_port *port = sd->port;
	long left, t;

	/* From now on only a loss (or close) completes select_done... */
	spin_lock(&port->lock);
	if (sd->gone) {
		spin_unlock(&port->lock);
		return -ENODEV;
	}
	reinit_completion(&port->select_done);
	spin_unlock(&port->lock);

	t = (long)(settle - jiffies);
	if (t > 0) {
		left = wait_for_completion_interruptible_timeout(&port->select_done, t);
		if (left)
			return left < 0 ? left : -ENODEV;
	}

	/* ...and now also the first DATA message of @mode. */
	spin_lock(&port->lock);
	if (sd->gone) {
		spin_unlock(&port->lock);
		return -ENODEV;
	}
	port->select_mode = mode;
	spin_unlock(&port->lock);

	left = wait_for_completion_interruptible_timeout(&port->select_done, wait);

	spin_lock(&port->lock);
	port->select_mode = EV3_UART_NO_MODE;
	spin_unlock(&port->lock);
	if (left < 0)
		return left;
	return READ_ONCE(sd->gone) ? -ENODEV : 0;
}

/*
 * ev3_uart_set_mode(), and for @iio not NULL the start of its buffer on
 * @mode once the mode is set, before select_mutex is released: a mode
 * write waiting for the mutex then finds the buffer holding the mode
 * (-EBUSY), rather than switch the sensor away from it.
 */
static int ev3_uart_select(struct ev3_uart_sensor_dev *sd, u8 mode,
			   struct ev3_uart_iio *iio);

/**
 * ev3_uart_set_mode() - switch a sensor to another mode
 * @sd: the sensor
 * @mode: the mode, 0 to num_modes - 1
 *
 * Sends SELECT and waits for the first DATA message of the new mode, which
 * is the only confirmation the protocol has. SELECT is sent again only after
 * 250 ms without an answer, so that slow one-shot modes (the ultrasonic
 * sensor answers after 62 ms) are not restarted. Then waits until the new
 * mode's values can be trusted (about 1.1 s for the infrared sensor).
 * Selecting the current mode returns at once.
 *
 * Return: 0, -%EINVAL for a mode the sensor does not have, -%EBUSY while an
 * IIO buffer captures another mode, -%ENODEV if the sensor is gone,
 * -%ETIMEDOUT if it never confirmed, -%ERESTARTSYS if interrupted.
 */
int ev3_uart_set_mode(struct ev3_uart_sensor_dev *sd, u8 mode)
{
	return ev3_uart_select(sd, mode, NULL);
}

/**
 * ev3_uart_set_buffer_mode() - switch a sensor to the mode an IIO buffer
 *	captures, and start the buffer on it
 * @sd: the sensor
 * @iio: its IIO front end, whose buffer is being enabled
 * @mode: the mode of the buffer's channels
 *
 * As ev3_uart_set_mode(); on success the buffer holds the sensor to @mode
 * (ev3_uart_iio_buffer_on()) from before any other mode change can start.
 *
 * Return: see ev3_uart_set_mode().
 */
int ev3_uart_set_buffer_mode(struct ev3_uart_sensor_dev *sd,
			     struct ev3_uart_iio *iio, u8 mode)
{
	return ev3_uart_select(sd, mode, iio);
}

static int ev3_uart_select(struct ev3_uart_sensor_dev *sd, u8 mode,
			   struct ev3_uart_iio *iio)
{
	unsigned long wait = msecs_to_jiffies(EV3_UART_SELECT_WAIT_MS);
	struct ev3_uart_port *port = sd->port;
	unsigned long settle = 0;
	long left = 0;
	u8 msg[3];
	int ret, i;

	if (mode >= sd->desc.num_modes)
		return -EINVAL;
	ret = mutex_lock_interruptible(&port->select_mutex);
	if (ret)
		return ret;

	spin_lock(&port->lock);
	if (sd->gone) {
		ret = -ENODEV;
	} else if (ev3_uart_iio_mode_busy(sd, mode)) {
		ret = -EBUSY;
	} else if (sd->mode == mode &&
		   port->parser.pending_mode == EV3_UART_NO_MODE) {
		/*
		 * Nothing to send, but the user's choice: a restore of an
		 * older choice must not come after it (see restore_mode()).
		 */
		port->requested_type = sd->desc.type;
		port->requested_lump = sd->desc.lump;
		port->requested_mode = mode;
		port->restore_mode = EV3_UART_NO_MODE;
		ret = 1;
	} else {
		ret = ev3_uart_parser_select(&port->parser, mode);
		if (!ret) {
			/* A restore in progress gives way to the user's mode. */
			port->restore_mode = EV3_UART_NO_MODE;
			port->select_mode = mode;
			reinit_completion(&port->select_done);
		}
	}
	spin_unlock(&port->lock);
	if (ret)
		goto out;

	for (i = 0; i < EV3_UART_SELECT_TRIES; i++) {
		/*
		 * Every SELECT (re)arms the parser: a DATA message of a mode
		 * that is neither the current nor the pending one is dropped
		 * as a leftover, so a retry must make @mode pending again.
		 */
		spin_lock(&port->lock);
		ret = sd->gone ? -ENODEV : ev3_uart_parser_select(&port->parser, mode);
		spin_unlock(&port->lock);
		if (!ret)
			ret = ev3_uart_tx(port, msg, ev3_uart_build_select(msg, mode));
		if (ret)
			break;
		left = wait_for_completion_interruptible_timeout(&port->select_done,
								 wait);
		if (left)
			break;
	}

	spin_lock(&port->lock);
	if (sd->gone) {
		ret = -ENODEV;
	} else if (left > 0 && !ret) {
		port->requested_type = sd->desc.type;
		port->requested_lump = sd->desc.lump;
		port->requested_mode = mode;
		settle = sd->settle_until;
	} else if (!ret) {
		ret = left < 0 ? left : -ETIMEDOUT;
	}
	if (ret)
		port->select_mode = EV3_UART_NO_MODE;
	spin_unlock(&port->lock);

	if (ret == -ETIMEDOUT)
		dev_warn_ratelimited(&sd->dev, "mode %s not confirmed by the sensor\n",
				     sd->desc.modes[mode].name);
	else if (!ret && settle && time_before(jiffies, settle))
		ret = ev3_uart_settle(sd, mode, settle, wait);
out:
	if (iio && ret >= 0) {
		spin_lock(&port->lock);
		ev3_uart_iio_buffer_on(iio, mode);
		spin_unlock(&port->lock);
	}
	mutex_unlock(&port->select_mutex);
	/* An error, or success: 1 (nothing to send) or the bytes the tty took. */
	return min(ret, 0);
}

/**
 * ev3_uart_set_mode_by_name() - switch a sensor to the mode a user named
 * @sd: the sensor
 * @name: as written to a sysfs attribute: see ev3_uart_find_mode()
 *
 * Return: 0, -%EINVAL if the sensor has no such mode, or the errors of
 * ev3_uart_set_mode().
 */
int ev3_uart_set_mode_by_name(struct ev3_uart_sensor_dev *sd, const char *name)
{
	int mode = ev3_uart_find_mode(&sd->desc, name);

	return mode < 0 ? mode : ev3_uart_set_mode(sd, mode);
}

/**
 * ev3_uart_show_modes() - the names of a sensor's modes, for sysfs
 * @sd: the sensor
 * @buf: the sysfs page
 *
 * Return: the length written: the modes' tokens (ev3_uart_mode_token())
 * separated by spaces, then a newline.
 */
int ev3_uart_show_modes(struct ev3_uart_sensor_dev *sd, char *buf)
{
	char tok[EV3_UART_TOKEN_LEN + 1];
	int i, len = 0;

	for (i = 0; i < sd->desc.num_modes; i++) {
		if (ev3_uart_mode_token(&sd->desc, i, tok, sizeof(tok)) < 0)
			return -EINVAL;
		len += sysfs_emit_at(buf, len, "%s%s", i ? " " : "", tok);
	}
	len += sysfs_emit_at(buf, len, "\n");
	return len;
}

/**
 * ev3_uart_show_mode() - the current mode of a sensor, for sysfs
 * @sd: the sensor
 * @buf: the sysfs page
 *
 * Return: the length written (the mode's token and a newline), or
 * -%ENODEV if the sensor is gone.
 */
int ev3_uart_show_mode(struct ev3_uart_sensor_dev *sd, char *buf)
{
	char tok[EV3_UART_TOKEN_LEN + 1];
	u8 data[EV3_UART_MAX_PAYLOAD], mode;
	int ret = ev3_uart_get_data(sd, &mode, data);

	if (ret < 0)
		return ret;
	ret = ev3_uart_mode_token(&sd->desc, mode, tok, sizeof(tok));
	if (ret < 0)
		return ret;
	return sysfs_emit(buf, "%s\n", tok);
}

/**
 * ev3_uart_write() - send a WRITE message to a sensor
 * @sd: the sensor
 * @data: the bytes, e.g. 0x11 to reset the gyro's angle
 * @len: 1 to 32; shorter writes are padded with zeros to a power of two
 *
 * Return: 0, -%EINVAL for a bad length, -%ENODEV if the sensor is gone, or
 * the tty's error.
 */
int ev3_uart_write(struct ev3_uart_sensor_dev *sd, const u8 *data, size_t len)
{
	u8 msg[EV3_UART_MAX_PAYLOAD + 2];
	int n;

	n = ev3_uart_build_write(msg, data, len);
	if (n < 0)
		return n;
	if (READ_ONCE(sd->gone))
		return -ENODEV;
	return ev3_uart_tx(sd->port, msg, n);
}

static void ev3_uart_find_label(struct ev3_uart_port *port)
{
	size_t n = strlen(port->tty->name);
	int i;

	for (i = 0; i < num_port_labels; i++) {
		const char *p = port_labels[i];

		if (p && !strncmp(p, port->tty->name, n) && p[n] == '=') {
			strscpy(port->label, p + n + 1, sizeof(port->label));
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
 * ev3_uart_stats), one "name value" a line.
 */
static int ev3_uart_counters_show(struct seq_file *m, void *unused)
{
	struct ev3_uart_port *port = m->private;
	struct ev3_uart_stats st;
	u8 state;

	spin_lock(&port->lock);
	st = port->stats;
	st.garbage += port->parser.garbage;
	st.bad_frames += port->parser.bad_frames;
	state = port->parser.state;
	spin_unlock(&port->lock);
	mutex_lock(&port->tx_mutex);
	st.tx_ack = port->stats.tx_ack;
	st.tx_nack = port->stats.tx_nack;
	st.tx_select = port->stats.tx_select;
	st.tx_write = port->stats.tx_write;
	st.tx_speed = port->stats.tx_speed;
	st.tx_errors = port->stats.tx_errors;
	mutex_unlock(&port->tx_mutex);

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
	seq_printf(m, "tx_ack %llu\n", st.tx_ack);
	seq_printf(m, "tx_nack %llu\n", st.tx_nack);
	seq_printf(m, "tx_select %llu\n", st.tx_select);
	seq_printf(m, "tx_write %llu\n", st.tx_write);
	seq_printf(m, "tx_speed %llu\n", st.tx_speed);
	seq_printf(m, "tx_errors %llu\n", st.tx_errors);
	return 0;
}
DEFINE_SHOW_ATTRIBUTE(ev3_uart_counters);

static int ev3_uart_ioctl(struct tty_struct *tty, unsigned int cmd,
			  unsigned long arg)
{
	struct ev3_uart_port *port = tty->disc_data;
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
		spin_lock(&port->lock);
		strscpy(port->label, pl.label, sizeof(port->label));
		spin_unlock(&port->lock);
		return 0;
	case LEGO_EV3_GET_PORT_LABEL:
		memset(&pl, 0, sizeof(pl));
		spin_lock(&port->lock);
		strscpy(pl.label, port->label, sizeof(pl.label));
		spin_unlock(&port->lock);
		return copy_to_user(uarg, &pl, sizeof(pl)) ? -EFAULT : 0;
	default:
		/* termios ioctls (tcgetattr...) keep working. */
		return tty_mode_ioctl(tty, cmd, arg);
	}
}

static int ev3_uart_open(struct tty_struct *tty)
{
	struct ev3_uart_port *port;

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

	port = kzalloc_obj(*port, GFP_KERNEL);
	if (!port)
		return -ENOMEM;

	port->wq = alloc_ordered_workqueue("ev3-uart-%s", WQ_HIGHPRI, tty->name);
	if (!port->wq) {
		kfree(port);
		return -ENOMEM;
	}

	port->tty = tty;
	spin_lock_init(&port->lock);
	mutex_init(&port->select_mutex);
	mutex_init(&port->tx_mutex);
	init_completion(&port->select_done);
	hrtimer_setup(&port->ack_timer, ev3_uart_ack_timer, CLOCK_MONOTONIC,
		      HRTIMER_MODE_REL);
	INIT_WORK(&port->ack_work, ev3_uart_ack_work);
	hrtimer_setup(&port->keepalive_timer, ev3_uart_keepalive_timer,
		      CLOCK_MONOTONIC, HRTIMER_MODE_REL);
	INIT_WORK(&port->keepalive_work, ev3_uart_keepalive_work);
	INIT_WORK(&port->reset_work, ev3_uart_reset_work);
	INIT_DELAYED_WORK(&port->probe_work, ev3_uart_probe_work);
	INIT_DELAYED_WORK(&port->fast_work, ev3_uart_fast_work);
	init_completion(&port->probe_done);
	INIT_WORK(&port->tx_work, ev3_uart_tx_work);
	ratelimit_state_init(&port->log_rs, DEFAULT_RATELIMIT_INTERVAL,
			     DEFAULT_RATELIMIT_BURST);
	ev3_uart_parser_init(&port->parser);
	port->select_mode = EV3_UART_NO_MODE;
	port->requested_mode = EV3_UART_NO_MODE;
	port->restore_mode = EV3_UART_NO_MODE;
	ev3_uart_find_label(port);

	ev3_uart_setup_tty(tty);
	port->speed = EV3_UART_SPEED_MIN;
	port->debugfs = debugfs_create_dir(tty->name, ev3_uart_debugfs_root);
	debugfs_create_file("counters", 0400, port->debugfs, port,
			    &ev3_uart_counters_fops);
	tty->disc_data = port;
	tty->receive_room = 65536;
	tty_driver_flush_buffer(tty);
	/* A Powered Up device that has just been powered may answer. */
	queue_delayed_work(port->wq, &port->probe_work, 0);

	return 0;
}

static void ev3_uart_close(struct tty_struct *tty)
{
	struct ev3_uart_port *port = tty->disc_data;
	struct ev3_uart_sensor_dev *sd;

	spin_lock(&port->lock);
	WRITE_ONCE(port->closing, true);
	if (port->sensor)
		WRITE_ONCE(port->sensor->gone, true);
	complete_all(&port->select_done);
	spin_unlock(&port->lock);

	/*
	 * An ack_work already running registers its sensor whatever
	 * @closing says, and a pending reset_work still runs: take the
	 * sensor only once no work can run any more. @closing keeps the
	 * receive path from starting the timer again; a timer that fired
	 * has queued its work before hrtimer_cancel() returns.
	 */
	hrtimer_cancel(&port->ack_timer);
	cancel_work_sync(&port->ack_work);
	ev3_uart_keepalive_stop(port);
	/* Queued on the work queue; with @closing set, not again. */
	cancel_delayed_work_sync(&port->probe_work);
	cancel_delayed_work_sync(&port->fast_work);
	destroy_workqueue(port->wq);

	spin_lock(&port->lock);
	sd = port->sensor;
	port->sensor = NULL;
	if (sd)
		WRITE_ONCE(sd->gone, true);
	/*
	 * A sensor ack_work published after the first complete_all() may
	 * have a mode change waiting: wake it, or the unregistering below
	 * waits for it (up to 250 ms).
	 */
	complete_all(&port->select_done);
	spin_unlock(&port->lock);
	if (sd) {
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_CLOSED, &sd->desc, sd);
		ev3_uart_sensor_destroy(sd);
	}
	debugfs_remove_recursive(port->debugfs);

	/*
	 * No work or user writes any more: the last tx_work, which sets the
	 * wakeup flag when it writes, then the flag, which would else stay
	 * set for the next discipline. No write_wakeup comes meanwhile to
	 * queue tx_work again: the tty core holds the discipline locked
	 * around close(), and tty_wakeup() calls no discipline then.
	 */
	cancel_work_sync(&port->tx_work);
	clear_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
	tty->disc_data = NULL;
	kfree(port);
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

static int __init ev3_uart_init(void)
{
	int ret;

	ret = ev3_uart_check_port_labels();
	if (ret)
		return ret;
	ev3_uart_keepalive_wq = alloc_workqueue("lego_ev3_keepalive",
						WQ_UNBOUND | WQ_HIGHPRI, 0);
	if (!ev3_uart_keepalive_wq)
		return -ENOMEM;
	ret = ev3_uart_class_init();
	if (ret)
		goto destroy_wq;

	ev3_uart_debugfs_root = debugfs_create_dir(KBUILD_MODNAME, NULL);
	ret = tty_register_ldisc(&ev3_uart_ldisc);
	if (ret) {
		pr_err("cannot register line discipline %d: %d\n",
		       EV3_UART_LDISC_NUM, ret);
		debugfs_remove_recursive(ev3_uart_debugfs_root);
		ev3_uart_class_exit();
		goto destroy_wq;
	}
	return 0;

destroy_wq:
	destroy_workqueue(ev3_uart_keepalive_wq);
	return ret;
}
module_init(ev3_uart_init);

static void __exit ev3_uart_exit(void)
{
	tty_unregister_ldisc(&ev3_uart_ldisc);
	debugfs_remove_recursive(ev3_uart_debugfs_root);
	ev3_uart_class_exit();
	destroy_workqueue(ev3_uart_keepalive_wq);
}
module_exit(ev3_uart_exit);

MODULE_DESCRIPTION("LEGO MINDSTORMS EV3 UART sensor line discipline");
MODULE_LICENSE("GPL");
MODULE_ALIAS_LDISC(EV3_UART_LDISC_NUM);
