// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensors: the sensor core.
 *
 * Runs the protocol on a line whatever carries it (the tty line discipline,
 * ev3_uart_ldisc.c, is the transport; the parser itself is the pure code of
 * ev3_uart_proto.c) and keeps the sensor on it for its views (the
 * lego-sensor class and IIO). Layering and locking are described in
 * ev3_uart_core.h.
 *
 * Life of a connection:
 *  - when the port starts, when a device resets (its TX held low: a break)
 *    and when a sensor was lost, the fast sync probe first
 *    (ev3_uart_probe()): SPEED 115200 at 115200 baud; a Powered Up device
 *    that answers ACK sends its handshake at 115200, else the line goes
 *    back to 2400 baud 30 ms later;
 *  - at 2400 baud the parser hunts for a TYPE message and reads the
 *    handshake;
 *  - on the sensor's ACK, ack_timer fires 10 ms later (the sensor waits
 *    80 ms at most; a delayed work would wait 0 to 10 ms at HZ=100) and
 *    the port's work answers ACK, switches the line to the sensor's speed
 *    and registers the sensor with the views (ev3_uart_ack());
 *  - keepalive_work sends NACK every 100 ms from the moment the speed is
 *    switched, registration included (the sensor resets itself after
 *    about a second without one) and declares the sensor lost after about
 *    700 ms without data;
 *  - the port's work removes a lost sensor and goes back to 2400 baud,
 *    where a new handshake brings it back (ev3_uart_reset()).
 * One work item, ev3_uart_work(), makes every change of the line's state
 * but the keep-alive's, one at a time: the receive path, the keep-alive
 * and the timers only ask it for them (ev3_uart_ask()). Nothing sleeps or
 * waits in the receive path.
 */
#define pr_fmt(fmt) KBUILD_MODNAME ": " fmt

#include <linux/device.h>
#include <linux/hrtimer.h>
#include <linux/jiffies.h>
#include <linux/log2.h>
#include <linux/lockdep.h>
#include <linux/slab.h>
#include <linux/string.h>
#include <linux/sysfs.h>
#include <linux/workqueue.h>

#include "lego_compat.h"
#include "ev3_uart_core.h"
#include "ev3_uart_chan.h"
#include "ev3_uart_trace.h"

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
#define EV3_UART_DRAIN_MS	50	/* for an ACK or a SPEED to go out */

/*
 * The keep-alives' workqueue: high priority and unbound, so that a NACK
 * does not wait for a worker of the shared unbound pool, whose workers may
 * all be blocked registering sensors (each port's own work items run
 * there too): one keep-alive was measured 194 ms late in the test VM with
 * its CPUs running, while other ports registered sensors.
 */
static struct workqueue_struct *ev3_uart_keepalive_wq;

/*
 * The views, in the order they registered: added in that order, removed
 * in the reverse one. Registered at the module's init before any port
 * starts, unregistered at its exit after the last one stopped: no lock.
 */
static const struct ev3_uart_view_ops *ev3_uart_views[EV3_UART_MAX_VIEWS];

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
 * The lines a port logs for each connection, loss and protocol error: a
 * device that keeps failing must not flood the log (its reconnects are
 * also held off, see ev3_uart_backoff_lost()).
 */
#define ev3_uart_info(port, fmt, ...)					\
	do {								\
		if (__ratelimit(&(port)->log_rs))			\
			pr_info(fmt, ##__VA_ARGS__);			\
	} while (0)

/*
 * What the port's work is asked to do (bits of ev3_uart_port.todo), in the
 * order it does them when several are asked (ev3_uart_work()).
 */
enum ev3_uart_todo {
	EV3_UART_DO_RESET,	/* an error or a lost sensor: hunt again */
	EV3_UART_DO_ACK,	/* 10 ms after the sensor's ACK: answer it */
	EV3_UART_DO_FAST_LATE,	/* a fast sync's handshake did not come */
	EV3_UART_DO_PROBE,	/* the fast sync probe */
};

/*
 * Ask the port's work for @what. From any context (the timers' hard
 * interrupt included): it takes no lock. Nothing is asked once the port is
 * closing but from a timer, which ev3_uart_port_stop() cancels before the
 * work.
 */
static void ev3_uart_kick(struct ev3_uart_port *port, enum ev3_uart_todo what)
{
	set_bit(what, &port->todo);
	queue_work(port->wq, &port->work);
}

/* As ev3_uart_kick(), but not once the port is closing. @lock held. */
static void ev3_uart_ask(struct ev3_uart_port *port, enum ev3_uart_todo what)
{
	lockdep_assert_held(&port->lock);
	if (!port->closing)
		ev3_uart_kick(port, what);
}

/*
 * The parser left state @from: trace it, with @why or the reason @ev gives.
 * @lock held.
 */
static void ev3_uart_trace_state(struct ev3_uart_port *port, u8 from,
				 const struct ev3_uart_event *ev,
				 const char *why)
{
	u8 to = ev3_uart_parser_state(&port->parser);

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
	trace_ev3_uart_state(port->name, from, to, why ?: "");
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
	if (ev3_uart_parser_sensor(&port->parser)->type == EV3_UART_TYPE_COLOR &&
	    ev->mode == 4 &&
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
 * DATA of @mode came: if it is the mode a SELECT waits for and the parser
 * has no switch pending any more, the SELECT is confirmed. @lock held.
 */
static void ev3_uart_select_confirm(struct ev3_uart_port *port, u8 mode)
{
	if (port->select_mode == mode &&
	    ev3_uart_parser_pending(&port->parser) == EV3_UART_NO_MODE) {
		port->select_mode = EV3_UART_NO_MODE;
		complete(&port->select_done);
	}
}

/*
 * A DATA message of the mode a write of values borrows the sensor in
 * (ev3_uart_set_mode_data()): it confirms the SELECT of that mode, but
 * the user's mode and values stay. Return: true if @ev was one. @lock held.
 */
static bool ev3_uart_lent_data(struct ev3_uart_port *port,
			       struct ev3_uart_sensor_dev *sd,
			       const struct ev3_uart_event *ev)
{
	if (sd->lent_mode == EV3_UART_NO_MODE || ev->mode != sd->lent_mode)
		return false;
	ev3_uart_select_confirm(port, ev->mode);
	return true;
}

/*
 * A DATA message: the sensor's values, pushed to the views, and the
 * confirmation of a SELECT. @lock held.
 */
static void ev3_uart_data_event(struct ev3_uart_port *port,
				const struct ev3_uart_event *ev, size_t rest)
{
	struct ev3_uart_sensor_dev *sd = port->sensor;
	const struct ev3_uart_view_ops *v;
	bool changed = false;
	unsigned int settle_ms;
	int i;

	port->stats.data_msgs++;
	if (trace_ev3_uart_rx_enabled())
		trace_ev3_uart_rx(port->name, EV3_UART_TRACE_DATA,
				  ev3_uart_data_hdr(ev), ev->mode, 0, ev->len,
				  ev3_uart_accepted_by(port, ev), ev->mode_changed);
	if (!sd || ev3_uart_lent_data(port, sd, ev))
		return;
	/*
	 * Not only on ev->mode_changed: a SELECT written through sysfs
	 * between the sensor's registration and ev3_uart_ack() publishing it in
	 * port->sensor is confirmed by DATA nobody passed on.
	 */
	if (ev->mode != sd->mode) {
		sd->mode = ev->mode;
		/* A whole settle time at least: one jiffy more. */
		settle_ms = ev3_uart_settle_ms(&sd->desc);
		sd->settle_until = jiffies + (settle_ms ?
			msecs_to_jiffies(settle_ms) + 1 : 0);
		WRITE_ONCE(sd->fresh, !settle_ms);
		changed = true;
	}
	memcpy(sd->data, ev3_uart_parser_data(&port->parser), ev->len);
	memset(sd->data + ev->len, 0, sizeof(sd->data) - ev->len);
	sd->data_len = ev->len;
	/*
	 * Readers wait for a new mode's values until they can be trusted.
	 * Compared only until then: jiffies wrap around.
	 */
	if (!sd->fresh && !time_before(jiffies, sd->settle_until)) {
		WRITE_ONCE(sd->fresh, true);
		wake_up_all(&sd->fresh_wait);
	}
	for (i = 0; i < EV3_UART_MAX_VIEWS && ev3_uart_views[i]; i++) {
		v = ev3_uart_views[i];
		if (changed && v->mode_changed)
			v->mode_changed(sd);
		if (sd->fresh && v->data)
			v->data(sd, ev->mode, sd->data, ev->len, rest);
	}
	ev3_uart_select_confirm(port, ev->mode);
}

/* The sensor's ACK ended its handshake: ours goes 10 ms later. @lock held. */
static void ev3_uart_handshake_event(struct ev3_uart_port *port)
{
	const struct ev3_uart_sensor *s = ev3_uart_parser_sensor(&port->parser);

	port->stats.handshakes++;
	trace_ev3_uart_rx(port->name, EV3_UART_TRACE_ACK, EV3_UART_SYS_ACK,
			  s->num_modes, 0, 1, EV3_UART_TRACE_NONE, false);
	trace_ev3_uart_handshake(port->name, s->type, s->num_modes,
				 s->num_view_modes, s->speed);
	if (!port->closing)
		hrtimer_start(&port->ack_timer,
			      ms_to_ktime(EV3_UART_ACK_DELAY_MS), HRTIMER_MODE_REL);
}

/* A TYPE message started a handshake. @lock held. */
static void ev3_uart_sync_event(struct ev3_uart_port *port, u8 from)
{
	const struct ev3_uart_sensor *s = ev3_uart_parser_sensor(&port->parser);

	port->probe_missed = false;
	/* A TYPE at 2400 during the probe: no need to wait for it. */
	if (from == EV3_UART_STATE_PROBE)
		complete(&port->probe_done);
	pr_debug("%s: sensor type %u syncing\n", port->name, s->type);
	port->stats.syncs++;
	trace_ev3_uart_rx(port->name, EV3_UART_TRACE_TYPE,
			  EV3_UART_MSG_CMD | EV3_UART_CMD_TYPE, s->type, 0, 3,
			  EV3_UART_TRACE_CSUM, false);
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
	lockdep_assert_held(&port->lock);
	if (trace_ev3_uart_state_enabled())
		ev3_uart_trace_state(port, from, ev, NULL);
	switch (ev->type) {
	case EV3_UART_EV_SYNC:
		ev3_uart_sync_event(port, from);
		break;
	case EV3_UART_EV_MSG:
		/* Only while ev3_uart_rx is enabled (see ev3_uart_port_receive()). */
		port->stats.info_msgs++;
		trace_ev3_uart_rx(port->name,
				  (ev->mode & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_INFO ?
				  EV3_UART_TRACE_INFO : EV3_UART_TRACE_CMD,
				  ev->mode, ev->mode & EV3_UART_MSG_CMD_MASK,
				  ev3_uart_parser_msg_info(&port->parser), ev->len,
				  EV3_UART_TRACE_CSUM, false);
		break;
	case EV3_UART_EV_HANDSHAKE:
		ev3_uart_handshake_event(port);
		break;
	case EV3_UART_EV_DATA:
		ev3_uart_data_event(port, ev, rest);
		break;
	case EV3_UART_EV_ERROR:
		port->stats.resyncs++;
		port->last_error = ev->reason;
		ev3_uart_info(port, "%s: %s\n", port->name, ev->reason);
		ev3_uart_ask(port, EV3_UART_DO_RESET);
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
	if (ev3_uart_parser_fast_handshake(&port->parser))
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
	if (hrtimer_is_queued(&port->probe_timer))
		return;		/* the probe already put off comes */
	if (port->probed_at && time_before(jiffies, next))
		hrtimer_start(&port->probe_timer,
			      ms_to_ktime(jiffies_to_msecs(next - jiffies)),
			      HRTIMER_MODE_REL);
	else
		ev3_uart_ask(port, EV3_UART_DO_PROBE);
}

/**
 * ev3_uart_port_receive() - what the line received
 * @port: the port
 * @cp: the bytes
 * @flags: for each byte, %EV3_UART_RX_OK if it was received without
 *	error, %EV3_UART_RX_BREAK for a break, anything else for another
 *	line error (a tty's TTY_NORMAL, TTY_BREAK...); NULL if all are good
 * @count: how many
 *
 * Never sleeps; the transport calls it in the order the bytes came, from
 * one context at a time.
 */
void ev3_uart_port_receive(struct ev3_uart_port *port, const u8 *cp,
			   const u8 *flags, size_t count)
{
	struct ev3_uart_event ev;
	size_t run, used;
	u8 from;

	spin_lock(&port->lock);
	/* The handshake's messages one by one, for ev3_uart_rx. */
	ev3_uart_parser_report_msgs(&port->parser, trace_ev3_uart_rx_enabled());
	while (count > 0) {
		from = ev3_uart_parser_state(&port->parser);
		if (flags && *flags != EV3_UART_RX_OK) {
			if (*flags == EV3_UART_RX_BREAK &&
			    (from == EV3_UART_STATE_SYNC || from == EV3_UART_STATE_PROBE))
				ev3_uart_break(port);
			port->stats.line_errors++;
			ev3_uart_parser_line_error(&port->parser, &ev);
			cp++;
			flags++;
			count--;
			ev3_uart_event(port, &ev, count, from);
			continue;
		}
		/* Feed the run of bytes received without error. */
		for (run = 1; run < count && (!flags || flags[run] == EV3_UART_RX_OK); run++)
			;
		used = ev3_uart_parser_feed(&port->parser, cp, run, &ev);
		cp += used;
		if (flags)
			flags += used;
		count -= used;
		/* The event's message ended @count bytes before the batch did. */
		ev3_uart_event(port, &ev, count, from);
	}
	spin_unlock(&port->lock);
}

/*
 * The port's timers, in hard interrupt context: each only asks the port's
 * work for its task. ev3_uart_port_stop() cancels them before the work, so
 * the work queue still exists here.
 */
static enum hrtimer_restart ev3_uart_ack_timer(struct hrtimer *timer)
{
	ev3_uart_kick(container_of(timer, struct ev3_uart_port, ack_timer),
		      EV3_UART_DO_ACK);
	return HRTIMER_NORESTART;
}

static enum hrtimer_restart ev3_uart_probe_timer(struct hrtimer *timer)
{
	ev3_uart_kick(container_of(timer, struct ev3_uart_port, probe_timer),
		      EV3_UART_DO_PROBE);
	return HRTIMER_NORESTART;
}

static enum hrtimer_restart ev3_uart_fast_timer(struct hrtimer *timer)
{
	ev3_uart_kick(container_of(timer, struct ev3_uart_port, fast_timer),
		      EV3_UART_DO_FAST_LATE);
	return HRTIMER_NORESTART;
}

/* A fast sync's handshake came (or the probe starts again): no time-out. */
static void ev3_uart_fast_cancel(struct ev3_uart_port *port)
{
	hrtimer_try_to_cancel(&port->fast_timer);
	clear_bit(EV3_UART_DO_FAST_LATE, &port->todo);
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
		port->ops->send(port, select, ev3_uart_build_select(select, mode));
	mutex_unlock(&port->select_mutex);
}

/*
 * Starts the parser again, hunting for a sensor at 2400 baud, after @why;
 * its counts go to the port's. @lock held.
 */
static void ev3_uart_parser_restart(struct ev3_uart_port *port, const char *why)
{
	u8 from = ev3_uart_parser_state(&port->parser);

	lockdep_assert_held(&port->lock);
	port->stats.garbage += ev3_uart_parser_garbage(&port->parser);
	port->stats.bad_frames += ev3_uart_parser_bad_frames(&port->parser);
	ev3_uart_parser_init(&port->parser);
	ev3_uart_trace_state(port, from, NULL, why);
}

/* A sensor was registered, lost, or could not be; for the trace. */
static void ev3_uart_trace_sensor(struct ev3_uart_port *port, u8 what,
				  const struct ev3_uart_sensor *desc,
				  struct ev3_uart_sensor_dev *sd)
{
	trace_ev3_uart_sensor(port->name, what, desc->type,
			      sd ? sd->driver_name : "",
			      sd ? sd->name : "", desc->speed);
}

/*
 * Run the line at @baud (the transport drops what is still queued for the
 * old speed first). Only from the work items on the port's ordered
 * workqueue, which keep @port->speed. Return: 0, or -%EINVAL if the line
 * runs at another speed (@port->speed is then 0: unknown).
 */
static int ev3_uart_set_speed(struct ev3_uart_port *port, u32 baud)
{
	int ret = port->ops->set_speed(port, baud);

	port->speed = ret ? 0 : baud;
	spin_lock(&port->lock);
	port->stats.speed_changes++;
	spin_unlock(&port->lock);
	trace_ev3_uart_speed(port->name, baud, ret);
	return ret;
}

static void ev3_uart_sensor_release(struct kref *ref)
{
	kfree(container_of(ref, struct ev3_uart_sensor_dev, ref));
}

/**
 * ev3_uart_sensor_get() - take a reference to a sensor
 * @sd: the sensor
 */
void ev3_uart_sensor_get(struct ev3_uart_sensor_dev *sd)
{
	kref_get(&sd->ref);
}

/**
 * ev3_uart_sensor_put() - drop a reference to a sensor
 * @sd: the sensor; freed with its last reference
 */
void ev3_uart_sensor_put(struct ev3_uart_sensor_dev *sd)
{
	kref_put(&sd->ref, ev3_uart_sensor_release);
}

/**
 * ev3_uart_sensor_name() - what the log calls a sensor
 * @sd: the sensor
 *
 * Return: the name the first view gave it ("sensor3"), else its driver
 * name.
 */
const char *ev3_uart_sensor_name(const struct ev3_uart_sensor_dev *sd)
{
	return sd->name[0] ? sd->name : sd->driver_name;
}

/**
 * ev3_uart_sensor_log_ok() - whether a view may log a line about a sensor
 * @sd: the sensor
 *
 * The port's lines for each connection are rate limited together: a
 * device that keeps failing must not flood the log.
 *
 * Return: true if the line may be logged.
 */
bool ev3_uart_sensor_log_ok(struct ev3_uart_sensor_dev *sd)
{
	return __ratelimit(&sd->port->log_rs);
}

/* Remove the sensor from the first @n views, the last first. */
static void ev3_uart_views_remove(struct ev3_uart_sensor_dev *sd, int n)
{
	while (n-- > 0)
		if (ev3_uart_views[n]->remove)
			ev3_uart_views[n]->remove(sd);
}

/*
 * A sensor after its handshake, with its views (not published yet). Not
 * inlined: every allocation of a registration has it on its stack, for
 * failslab's stack filter (require-start/require-end) to fail them alone.
 */
static noinline struct ev3_uart_sensor_dev *
ev3_uart_sensor_create(struct ev3_uart_port *port,
		       const struct ev3_uart_sensor *desc)
{
	const char *name = desc->lump ? ev3_uart_lump_driver_name(desc->type) :
					ev3_uart_driver_name(desc->type);
	struct ev3_uart_sensor_dev *sd;
	int i, ret = 0;

	sd = kzalloc_obj(*sd, GFP_KERNEL);
	if (!sd)
		return ERR_PTR(-ENOMEM);
	kref_init(&sd->ref);
	sd->port = port;
	sd->desc = *desc;
	sd->held_mode = EV3_UART_NO_MODE;
	sd->lent_mode = EV3_UART_NO_MODE;
	sd->settle_until = jiffies;
	sd->fresh = true;
	init_waitqueue_head(&sd->fresh_wait);
	if (name)
		strscpy(sd->driver_name, name, sizeof(sd->driver_name));
	else
		snprintf(sd->driver_name, sizeof(sd->driver_name), "%s-uart-%u",
			 desc->lump ? "lump" : "ev3", desc->type);
	spin_lock(&port->lock);
	if (port->label[0])
		snprintf(sd->address, sizeof(sd->address), "%s:%s", port->name,
			 port->label);
	else
		strscpy(sd->address, port->name, sizeof(sd->address));
	spin_unlock(&port->lock);

	for (i = 0; i < EV3_UART_MAX_VIEWS && ev3_uart_views[i]; i++) {
		ret = ev3_uart_views[i]->add ? ev3_uart_views[i]->add(sd) : 0;
		if (ret)
			break;
	}
	if (ret) {
		ev3_uart_views_remove(sd, i);
		ev3_uart_sensor_put(sd);
		return ERR_PTR(ret);
	}
	return sd;
}

/* @sd is marked gone and unpublished: remove it from its views. */
static void ev3_uart_sensor_destroy(struct ev3_uart_sensor_dev *sd)
{
	int n = 0;

	/* Readers waiting for fresh values: it is gone (their views go). */
	wake_up_all(&sd->fresh_wait);
	while (n < EV3_UART_MAX_VIEWS && ev3_uart_views[n])
		n++;
	ev3_uart_views_remove(sd, n);
	ev3_uart_sensor_put(sd);
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
 * (ev3_uart_fast_late()). Only from the port's work, with the parser
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
	ev3_uart_fast_cancel(port);
	spin_lock(&port->lock);
	from = ev3_uart_parser_state(&port->parser);
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
			port->name, EV3_UART_SPEED_FAST);
		WRITE_ONCE(port->no_probe, true);
		why = "no fast sync on this tty";
	} else if (!port->ops->send(port, msg,
				    ev3_uart_build_speed(msg, EV3_UART_SPEED_FAST))) {
		/*
		 * From when it is out. Pybricks waits 10 ms, on a UART of its
		 * own; a USB serial adapter may hold the ACK 16 ms (an FTDI
		 * chip's latency timer) before the tty sees it.
		 */
		port->ops->drain(port, EV3_UART_DRAIN_MS);
		wait_for_completion_timeout(&port->probe_done,
					    msecs_to_jiffies(EV3_UART_PROBE_WAIT_MS) + 1);
	}

	spin_lock(&port->lock);
	from = ev3_uart_parser_state(&port->parser);
	speed = ev3_uart_parser_probe_end(&port->parser);
	ev3_uart_trace_state(port, from, NULL, why);
	port->probe_missed = on_break && speed == EV3_UART_SPEED_MIN &&
			     ev3_uart_parser_syncing(&port->parser);
	if (speed != EV3_UART_SPEED_MIN && !port->closing)
		hrtimer_start(&port->fast_timer,
			      ms_to_ktime(EV3_UART_FAST_SYNC_MS), HRTIMER_MODE_REL);
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

/* The probe the port's start or a break asked for. */
static void ev3_uart_probe_asked(struct ev3_uart_port *port)
{
	bool on_break;

	spin_lock(&port->lock);
	on_break = port->break_probe;
	port->break_probe = false;
	spin_unlock(&port->lock);
	ev3_uart_probe(port, on_break);
}

/* A device answered the probe, and its handshake did not follow in time. */
static void ev3_uart_fast_late(struct ev3_uart_port *port)
{
	bool late;

	spin_lock(&port->lock);
	late = ev3_uart_parser_fast_handshake(&port->parser);
	if (late)
		ev3_uart_parser_restart(port, "no handshake after the fast sync");
	spin_unlock(&port->lock);
	if (late)
		ev3_uart_set_speed(port, EV3_UART_SPEED_MIN);
}

/*
 * Whether the handshake of @desc is left unanswered: the reason, or NULL
 * to answer it.
 */
static const char *ev3_uart_ack_refused(struct ev3_uart_port *port,
					const struct ev3_uart_sensor *desc)
{
	/*
	 * A device whose sensors keep failing right after they are
	 * registered: not before the back-off is over (it resets and comes
	 * again, as when its ACK is not answered).
	 */
	if (port->backoff_until && time_before(jiffies, port->backoff_until)) {
		pr_debug("%s: sensor type %u keeps failing; not answered yet\n",
			 port->name, desc->type);
		return "backing off a device that keeps failing";
	}
	port->backoff_until = 0;

	/* Not again a speed this line could not do (see below). */
	if (desc->speed == port->bad_speed) {
		pr_debug("%s: sensor type %u wants %u baud again; not answered\n",
			 port->name, desc->type, desc->speed);
		return "speed not supported by the tty";
	}
	return NULL;
}

/* Send our ACK and switch to the sensor's speed. Return: NULL, or why not. */
static const char *ev3_uart_ack_answer(struct ev3_uart_port *port,
				       const struct ev3_uart_sensor *desc)
{
	u8 ack;

	if (port->ops->send(port, &ack, ev3_uart_build_ack(&ack)))
		return "ACK not sent";
	/*
	 * The sensor switches speed once it has our ACK: so do we. Not after
	 * a fast sync: the handshake came at the sensor's speed.
	 */
	if (desc->speed == port->speed)
		return NULL;
	port->ops->drain(port, EV3_UART_DRAIN_MS);
	if (ev3_uart_set_speed(port, desc->speed)) {
		/*
		 * The UART cannot run at the sensor's speed, or its speed is
		 * locked (TIOCSLCKTRMIOS): the sensor would be lost and come
		 * back for ever. Say so once and leave its handshakes
		 * unanswered from now on.
		 */
		pr_err("%s: cannot set %u baud for sensor type %u: not connecting it\n",
		       port->name, desc->speed, desc->type);
		port->bad_speed = desc->speed;
		return "speed not supported by the tty";
	}
	return NULL;
}

/* Register the sensor and publish it. Return: NULL, or why not. */
static const char *ev3_uart_ack_register(struct ev3_uart_port *port,
					 const struct ev3_uart_sensor *desc)
{
	struct ev3_uart_sensor_dev *sd;
	const char *last_error;

	sd = ev3_uart_sensor_create(port, desc);
	if (IS_ERR(sd)) {
		pr_err_ratelimited("%s: cannot register sensor: %pe\n",
				   port->name, sd);
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_FAILED, desc, NULL);
		return "sensor not registered";
	}

	spin_lock(&port->lock);
	port->sensor = sd;
	port->stats.registered++;
	last_error = port->last_error;
	port->last_error = NULL;
	spin_unlock(&port->lock);
	port->registered_at = jiffies;
	ev3_uart_trace_sensor(port, EV3_UART_TRACE_REGISTERED, desc, sd);

	if (sd->name[0])
		ev3_uart_info(port, "%s: %s connected as %s at %u baud\n",
			      port->name, sd->driver_name, sd->name, desc->speed);
	else
		ev3_uart_info(port, "%s: %s connected at %u baud\n", port->name,
			      sd->driver_name, desc->speed);
	if (last_error)
		ev3_uart_info(port, "%s: reconnected after: %s\n", port->name,
			      last_error);
	return NULL;
}

/*
 * Answer the sensor's ACK, switch to its speed, start the keep-alive and
 * register the sensor; or, if it cannot be, hunt again.
 */
static void ev3_uart_ack(struct ev3_uart_port *port)
{
	/* In the port: 16 modes are too much for the stack. */
	struct ev3_uart_sensor *desc = &port->ack_desc;
	const char *why;
	u8 from;

	spin_lock(&port->lock);
	if (port->closing || !ev3_uart_parser_acked(&port->parser)) {
		spin_unlock(&port->lock);
		return;
	}
	*desc = *ev3_uart_parser_sensor(&port->parser);
	spin_unlock(&port->lock);
	ev3_uart_fast_cancel(port);

	why = ev3_uart_ack_refused(port, desc) ?: ev3_uart_ack_answer(port, desc);
	if (why)
		goto fail;

	spin_lock(&port->lock);
	from = ev3_uart_parser_state(&port->parser);
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

	why = ev3_uart_ack_register(port, desc);
	if (why)
		goto fail;
	ev3_uart_restore_mode(port, desc);
	return;

fail:
	/* Started before a failed registration: done before the probe. */
	ev3_uart_keepalive_stop(port);
	spin_lock(&port->lock);
	ev3_uart_parser_restart(port, why);
	spin_unlock(&port->lock);
	port->ops->discard(port);
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
	from = ev3_uart_parser_state(&port->parser);
	if (ev3_uart_parser_tick(&port->parser, &ev))
		ev3_uart_event(port, &ev, 0, from);
	alive = ev3_uart_parser_in_data(&port->parser);
	/*
	 * The SELECT restoring the user's mode after a reconnect can arrive
	 * while the sensor still listens at 2400 baud: send it again now and
	 * then until a DATA message of that mode confirms it.
	 */
	restore = port->restore_mode;
	if (restore != EV3_UART_NO_MODE &&
	    ev3_uart_parser_pending(&port->parser) != restore) {
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
		    ev3_uart_parser_pending(&port->parser) != restore)
			restore = EV3_UART_NO_MODE;
		spin_unlock(&port->lock);
		if (restore != EV3_UART_NO_MODE)
			port->ops->send(port, select,
					ev3_uart_build_select(select, restore));
		mutex_unlock(&port->select_mutex);
	}
	port->ops->send(port, &nack, ev3_uart_build_nack(&nack));
	if (!READ_ONCE(port->closing))
		hrtimer_start(&port->keepalive_timer,
			      ms_to_ktime(EV3_UART_KEEPALIVE_MS), HRTIMER_MODE_REL);
}

/*
 * @sd was lost: hold off the next connections if the sensors on this line
 * keep failing right after they are registered. Only from ev3_uart_reset().
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
		      port->name, sd->driver_name, lived,
		      port->backoff.failures, wait);
}

/* Drop a lost sensor (if any) and hunt for the next one. */
static void ev3_uart_reset(struct ev3_uart_port *port)
{
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

	port->ops->discard(port);
	ev3_uart_hunt(port);
	if (sd) {
		ev3_uart_info(port, "%s: %s disconnected\n", port->name,
			      sd->driver_name);
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_LOST, &sd->desc, sd);
		ev3_uart_backoff(port, sd);
		ev3_uart_sensor_destroy(sd);
	}
}

/*
 * The port's one work item, on its ordered workqueue: whatever the receive
 * path, the keep-alive and the timers asked for, in the order of enum
 * ev3_uart_todo. A reset comes first: it hunts again, so that an ACK asked
 * before it finds the parser hunting and is dropped, rather than a sensor
 * registered to be removed at once.
 */
static void ev3_uart_work(struct work_struct *work)
{
	struct ev3_uart_port *port = container_of(work, struct ev3_uart_port,
						  work);

	if (test_and_clear_bit(EV3_UART_DO_RESET, &port->todo))
		ev3_uart_reset(port);
	if (test_and_clear_bit(EV3_UART_DO_ACK, &port->todo))
		ev3_uart_ack(port);
	if (test_and_clear_bit(EV3_UART_DO_FAST_LATE, &port->todo))
		ev3_uart_fast_late(port);
	if (test_and_clear_bit(EV3_UART_DO_PROBE, &port->todo))
		ev3_uart_probe_asked(port);
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

/**
 * ev3_uart_get_values() - read a sensor's current mode and values, once
 *	they can be trusted
 * @sd: the sensor
 * @mode: its current mode
 * @data: %EV3_UART_MAX_PAYLOAD bytes for the last DATA payload
 *
 * As ev3_uart_get_data(), but right after the sensor switched to a mode
 * whose first values may be stale (the infrared sensor's for 1.1 s, the
 * colour sensor's for 30 ms: ev3_uart_settle_ms()) it sleeps until the
 * first DATA message after that time, as a read of a converter waits for
 * its conversion: a value read is never one the sensor sent before its new
 * mode's values were good. Until the sensor confirms a SELECT its old mode
 * is the current one, with its values: no wait then.
 *
 * Return: the payload length, -%ENODEV if the sensor is gone, -%EAGAIN if
 * no DATA message came in the settle time and 250 ms after it,
 * -%ERESTARTSYS if interrupted.
 */
int ev3_uart_get_values(struct ev3_uart_sensor_dev *sd, u8 *mode, u8 *data)
{
	struct ev3_uart_port *port = sd->port;
	long left = msecs_to_jiffies(ev3_uart_settle_ms(&sd->desc) +
				     EV3_UART_SELECT_WAIT_MS) + 1;
	int len;

	for (;;) {
		spin_lock(&port->lock);
		if (sd->gone) {
			spin_unlock(&port->lock);
			return -ENODEV;
		}
		if (sd->fresh) {
			*mode = sd->mode;
			memcpy(data, sd->data, EV3_UART_MAX_PAYLOAD);
			len = sd->data_len;
			spin_unlock(&port->lock);
			return len;
		}
		spin_unlock(&port->lock);
		if (!left)
			return -EAGAIN;
		left = wait_event_interruptible_timeout(sd->fresh_wait,
							READ_ONCE(sd->fresh) ||
							READ_ONCE(sd->gone),
							left);
		if (left < 0)
			return left;
	}
}

/*
 * Wait until a new mode's values can be trusted: until @settle, then for one
 * DATA message received after it (the last one before may be stale too).
 * A lost sensor ends the wait at once: the sysfs write waiting here would
 * otherwise hold up ev3_uart_reset()'s unregistering of the sensor, and with it
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
 * The user chose @mode: a restore after a reconnect brings it back, and a
 * restore of an older choice in progress gives way. @lock held.
 */
static void ev3_uart_requested(struct ev3_uart_port *port,
			       const struct ev3_uart_sensor_dev *sd, u8 mode)
{
	lockdep_assert_held(&port->lock);
	port->requested_type = sd->desc.type;
	port->requested_lump = sd->desc.lump;
	port->requested_mode = mode;
	port->restore_mode = EV3_UART_NO_MODE;
}

/*
 * Whether a SELECT of @mode is to be sent: 0 to send it (the parser armed
 * for it), 1 if the sensor is in @mode already, or an error. select_mutex
 * held.
 */
static int ev3_uart_select_start(struct ev3_uart_sensor_dev *sd, u8 mode)
{
	struct ev3_uart_port *port = sd->port;
	int ret;

	spin_lock(&port->lock);
	if (sd->gone) {
		ret = -ENODEV;
	} else if (sd->held_mode != EV3_UART_NO_MODE && sd->held_mode != mode) {
		/* An IIO buffer captures another mode's values. */
		ret = -EBUSY;
	} else if (sd->mode == mode &&
		   ev3_uart_parser_pending(&port->parser) == EV3_UART_NO_MODE) {
		/* Nothing to send, but the user's choice all the same. */
		ev3_uart_requested(port, sd, mode);
		ret = 1;
	} else {
		ret = ev3_uart_parser_select(&port->parser, mode);
		if (!ret) {
			port->restore_mode = EV3_UART_NO_MODE;
			port->select_mode = mode;
			reinit_completion(&port->select_done);
		}
	}
	spin_unlock(&port->lock);
	return ret;
}

/*
 * Send SELECT until the first DATA message of @mode confirms it, up to
 * EV3_UART_SELECT_TRIES times, @wait jiffies each. Return: 0 (confirmed,
 * @settle: until when its values may be stale), or an error. select_mutex
 * held.
 */
static int ev3_uart_select_send(struct ev3_uart_sensor_dev *sd, u8 mode,
				unsigned long wait, unsigned long *settle)
{
	struct ev3_uart_port *port = sd->port;
	long left = 0;
	int ret, i;
	u8 msg[3];

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
			ret = port->ops->send(port, msg, ev3_uart_build_select(msg, mode));
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
		ev3_uart_requested(port, sd, mode);
		/* Nothing to wait out once fresh (and jiffies wrap around). */
		*settle = sd->fresh ? 0 : sd->settle_until;
	} else if (!ret) {
		ret = left < 0 ? left : -ETIMEDOUT;
	}
	if (ret)
		port->select_mode = EV3_UART_NO_MODE;
	spin_unlock(&port->lock);
	return ret;
}

/*
 * ev3_uart_set_mode(), and with @hold the sensor held to @mode once it is
 * set (an IIO buffer), before select_mutex is released: a mode write
 * waiting for the mutex then finds the mode held (-EBUSY), rather than
 * switch the sensor away from it.
 */
static int ev3_uart_select(struct ev3_uart_sensor_dev *sd, u8 mode, bool hold)
{
	unsigned long wait = msecs_to_jiffies(EV3_UART_SELECT_WAIT_MS);
	struct ev3_uart_port *port = sd->port;
	unsigned long settle = 0;
	int ret;

	if (mode >= sd->desc.num_modes)
		return -EINVAL;
	ret = mutex_lock_interruptible(&port->select_mutex);
	if (ret)
		return ret;

	ret = ev3_uart_select_start(sd, mode);
	if (!ret)
		ret = ev3_uart_select_send(sd, mode, wait, &settle);
	if (ret == -ETIMEDOUT)
		pr_warn_ratelimited("%s: %s: mode %s not confirmed by the sensor\n",
				    sd->address, ev3_uart_sensor_name(sd),
				    sd->desc.modes[mode].name);
	else if (!ret && settle && time_before(jiffies, settle))
		ret = ev3_uart_settle(sd, mode, settle, wait);
	if (hold && ret >= 0) {
		spin_lock(&port->lock);
		sd->held_mode = mode;
		spin_unlock(&port->lock);
	}
	mutex_unlock(&port->select_mutex);
	/* An error, or success: 1 (nothing to send) or 0. */
	return min(ret, 0);
}

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
	return ev3_uart_select(sd, mode, false);
}

/**
 * ev3_uart_hold_mode() - switch a sensor to a mode and hold it there
 * @sd: the sensor
 * @mode: the mode of an IIO buffer's channels
 *
 * As ev3_uart_set_mode(); on success no other mode can be set
 * (-%EBUSY) until ev3_uart_release_mode(), from before any other mode
 * change can start.
 *
 * Return: see ev3_uart_set_mode().
 */
int ev3_uart_hold_mode(struct ev3_uart_sensor_dev *sd, u8 mode)
{
	return ev3_uart_select(sd, mode, true);
}

/**
 * ev3_uart_release_mode() - let other modes be set again
 * @sd: the sensor
 */
void ev3_uart_release_mode(struct ev3_uart_sensor_dev *sd)
{
	spin_lock(&sd->port->lock);
	sd->held_mode = EV3_UART_NO_MODE;
	spin_unlock(&sd->port->lock);
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
	return sd->port->ops->send(sd->port, msg, n);
}

/* ---- Powered Up: values for a mode, combined modes ---- */

/*
 * SELECT @mode whatever mode the parser thinks the sensor is in, and wait
 * for its confirmation; the user's choice of a mode (restored after a
 * reconnect) stays. select_mutex held.
 */
static int ev3_uart_select_force(struct ev3_uart_sensor_dev *sd, u8 mode)
{
	unsigned long wait = msecs_to_jiffies(EV3_UART_SELECT_WAIT_MS);
	struct ev3_uart_port *port = sd->port;
	unsigned long settle;
	u8 rq_type, rq_mode;
	bool rq_lump;
	int ret;

	spin_lock(&port->lock);
	rq_type = port->requested_type;
	rq_lump = port->requested_lump;
	rq_mode = port->requested_mode;
	ret = sd->gone ? -ENODEV : ev3_uart_parser_select(&port->parser, mode);
	if (!ret) {
		port->select_mode = mode;
		reinit_completion(&port->select_done);
	}
	spin_unlock(&port->lock);
	if (!ret)
		ret = ev3_uart_select_send(sd, mode, wait, &settle);

	spin_lock(&port->lock);
	port->requested_type = rq_type;
	port->requested_lump = rq_lump;
	port->requested_mode = rq_mode;
	spin_unlock(&port->lock);
	return ret;
}

/**
 * ev3_uart_set_mode_data() - give a Powered Up device's mode its values
 * @sd: the sensor
 * @mode: a mode that takes values (ev3_uart_lump_data_len())
 * @data: the values, as the mode's FORMAT lays them out
 * @len: their size, exactly the mode's
 *
 * Pybricks sends values (EXT_MODE, then a DATA message of @mode) only once
 * the device sends DATA of @mode, and selects it first if need be
 * (lib/pbio/src/port_lump.c, pbio_port_lump_set_mode_with_data()): so does
 * this, and then selects the mode the sensor was in back. Meanwhile the
 * user's mode and values stay as they were: the DATA of @mode only confirm
 * the SELECT (ev3_uart_lent_data()). Waits for both confirmations.
 *
 * Return: 0, -%EINVAL if @mode takes no values or not @len bytes, -%EBUSY
 * while an IIO buffer captures another mode, -%ENODEV if the sensor is gone,
 * -%ETIMEDOUT if it did not confirm a SELECT, -%EINTR or the tty's error.
 */
int ev3_uart_set_mode_data(struct ev3_uart_sensor_dev *sd, u8 mode,
			   const u8 *data, size_t len)
{
	struct ev3_uart_port *port = sd->port;
	u8 msg[EV3_UART_MAX_PAYLOAD + 5], back;
	int n, ret, ret2;

	n = ev3_uart_lump_data_len(&sd->desc, mode);
	if (n < 0 || n != len)
		return -EINVAL;
	n = ev3_uart_build_lump_data(msg, mode, data, len);
	if (n < 0)
		return n;
	if (mutex_lock_interruptible(&port->select_mutex))
		return -EINTR;

	spin_lock(&port->lock);
	back = sd->mode;
	if (sd->gone)
		ret = -ENODEV;
	else if (sd->held_mode != EV3_UART_NO_MODE && sd->held_mode != mode)
		ret = -EBUSY;
	else
		ret = 0;
	if (!ret && back != mode)
		sd->lent_mode = mode;
	spin_unlock(&port->lock);

	if (!ret && back != mode)
		ret = ev3_uart_select_force(sd, mode);
	if (!ret)
		ret = port->ops->send(port, msg, n);
	if (back != mode && sd->lent_mode == mode) {
		ret2 = ev3_uart_select_force(sd, back);
		spin_lock(&port->lock);
		sd->lent_mode = EV3_UART_NO_MODE;
		spin_unlock(&port->lock);
		if (!ret)
			ret = ret2;
	}
	mutex_unlock(&port->select_mutex);
	if (ret == -ERESTARTSYS)
		ret = -EINTR;
	if (ret && ret != -ENODEV)
		pr_warn_ratelimited("%s: %s: values for mode %s not sent: %d\n",
				    sd->address, ev3_uart_sensor_name(sd),
				    sd->desc.modes[mode].name, ret);
	return ret;
}

/**
 * ev3_uart_hold_combo() - set up a combined mode and hold the sensor in it
 * @sd: the sensor, a Powered Up device
 * @e: the values to receive together, in the order wanted
 * @n: their number
 *
 * Finds the combination the device offers for @e (ev3_uart_combo_find()),
 * switches the sensor to mode 0, in which the only recorded combined mode
 * was set up, and sends the WRITE that sets it up (ev3_uart_build_combo()).
 * From then on each DATA message of mode 0 that is longer than mode 0's
 * own carries the values of @e; the sensor is held in mode 0 (no other
 * mode can be set, -%EBUSY) until ev3_uart_release_combo().
 *
 * Return: 0, -%EINVAL if no combination has the values, -%EBUSY while an
 * IIO buffer holds a mode, or the errors of ev3_uart_set_mode().
 */
int ev3_uart_hold_combo(struct ev3_uart_sensor_dev *sd,
			const struct ev3_uart_combo_entry *e, unsigned int n)
{
	struct ev3_uart_port *port = sd->port;
	u8 msg[EV3_UART_COMBO_MSG_LEN];
	unsigned int len;
	int combo, mlen, ret;

	combo = ev3_uart_combo_find(&sd->desc, e, n, &len);
	if (combo < 0)
		return combo;
	mlen = ev3_uart_build_combo(msg, combo, e, n);
	if (mlen < 0)
		return mlen;
	if (mutex_lock_interruptible(&port->select_mutex))
		return -EINTR;
	spin_lock(&port->lock);
	if (sd->gone)
		ret = -ENODEV;
	else if (sd->held_mode != EV3_UART_NO_MODE)
		ret = -EBUSY;
	else
		ret = 0;
	spin_unlock(&port->lock);
	if (!ret)
		ret = ev3_uart_select_force(sd, 0);
	if (!ret)
		ret = port->ops->send(port, msg, mlen);
	if (!ret) {
		spin_lock(&port->lock);
		sd->held_mode = 0;
		sd->combo_len = len;
		spin_unlock(&port->lock);
	}
	mutex_unlock(&port->select_mutex);
	return ret == -ERESTARTSYS ? -EINTR : ret;
}

/**
 * ev3_uart_release_combo() - end a combined mode
 * @sd: the sensor, held by ev3_uart_hold_combo()
 *
 * Lets other modes be set again and selects the user's mode (or mode 0):
 * a SELECT ends a combined mode.
 */
void ev3_uart_release_combo(struct ev3_uart_sensor_dev *sd)
{
	struct ev3_uart_port *port = sd->port;
	bool gone;
	u8 mode = 0;

	/* Not under select_mutex: a lost sensor's views go without it. */
	spin_lock(&port->lock);
	sd->held_mode = EV3_UART_NO_MODE;
	sd->combo_len = 0;
	gone = sd->gone;
	spin_unlock(&port->lock);
	if (gone)
		return;
	mutex_lock(&port->select_mutex);
	spin_lock(&port->lock);
	if (port->requested_mode < sd->desc.num_modes &&
	    port->requested_type == sd->desc.type &&
	    port->requested_lump == sd->desc.lump)
		mode = port->requested_mode;
	spin_unlock(&port->lock);
	ev3_uart_select_force(sd, mode);
	mutex_unlock(&port->select_mutex);
}

/**
 * ev3_uart_port_init() - set up a port (nothing runs yet)
 * @port: the port, zeroed, in the transport's own structure
 * @ops: the transport's operations
 * @name: the line's name (copied), for the log and the sensor's address
 * @parent: the line's device, parent of the sensor's devices
 * @speed: the line's speed now
 *
 * Return: 0 or -%ENOMEM.
 */
int ev3_uart_port_init(struct ev3_uart_port *port,
		       const struct ev3_uart_transport_ops *ops,
		       const char *name, struct device *parent, u32 speed)
{
	port->wq = alloc_ordered_workqueue("ev3-uart-%s", WQ_HIGHPRI, name);
	if (!port->wq)
		return -ENOMEM;
	port->ops = ops;
	strscpy(port->name, name, sizeof(port->name));
	port->parent = parent;
	port->speed = speed;
	spin_lock_init(&port->lock);
	mutex_init(&port->select_mutex);
	init_completion(&port->select_done);
	INIT_WORK(&port->work, ev3_uart_work);
	hrtimer_setup(&port->ack_timer, ev3_uart_ack_timer, CLOCK_MONOTONIC,
		      HRTIMER_MODE_REL);
	hrtimer_setup(&port->probe_timer, ev3_uart_probe_timer,
		      CLOCK_MONOTONIC, HRTIMER_MODE_REL);
	hrtimer_setup(&port->fast_timer, ev3_uart_fast_timer, CLOCK_MONOTONIC,
		      HRTIMER_MODE_REL);
	hrtimer_setup(&port->keepalive_timer, ev3_uart_keepalive_timer,
		      CLOCK_MONOTONIC, HRTIMER_MODE_REL);
	INIT_WORK(&port->keepalive_work, ev3_uart_keepalive_work);
	init_completion(&port->probe_done);
	ratelimit_state_init(&port->log_rs, DEFAULT_RATELIMIT_INTERVAL,
			     DEFAULT_RATELIMIT_BURST);
	ev3_uart_parser_init(&port->parser);
	port->select_mode = EV3_UART_NO_MODE;
	port->requested_mode = EV3_UART_NO_MODE;
	port->restore_mode = EV3_UART_NO_MODE;
	return 0;
}

/**
 * ev3_uart_port_start() - start listening for a sensor
 * @port: the port, set up by ev3_uart_port_init()
 *
 * The fast sync probe first: a Powered Up device that has just been
 * powered may answer.
 */
void ev3_uart_port_start(struct ev3_uart_port *port)
{
	ev3_uart_kick(port, EV3_UART_DO_PROBE);
}

/**
 * ev3_uart_port_stop() - stop a port for good
 * @port: the port
 *
 * Removes its sensor, if any, and waits for its work items and timers:
 * after it the core neither calls the transport for @port nor touches
 * it, and the transport may free it. Not under the port's receive path.
 */
void ev3_uart_port_stop(struct ev3_uart_port *port)
{
	struct ev3_uart_sensor_dev *sd;

	spin_lock(&port->lock);
	WRITE_ONCE(port->closing, true);
	if (port->sensor)
		WRITE_ONCE(port->sensor->gone, true);
	complete_all(&port->select_done);
	spin_unlock(&port->lock);

	/*
	 * The port's work, if it is registering a sensor, does so whatever
	 * @closing says: take the sensor only once the work cannot run any
	 * more. @closing keeps everything from starting a timer or asking
	 * the work again; a timer that fired has asked it before
	 * hrtimer_cancel() returns, so the timers go first.
	 */
	hrtimer_cancel(&port->ack_timer);
	hrtimer_cancel(&port->probe_timer);
	hrtimer_cancel(&port->fast_timer);
	ev3_uart_keepalive_stop(port);
	cancel_work_sync(&port->work);
	destroy_workqueue(port->wq);

	spin_lock(&port->lock);
	sd = port->sensor;
	port->sensor = NULL;
	if (sd)
		WRITE_ONCE(sd->gone, true);
	/*
	 * A sensor the work published after the first complete_all() may
	 * have a mode change waiting: wake it, or the unregistering below
	 * waits for it (up to 250 ms).
	 */
	complete_all(&port->select_done);
	spin_unlock(&port->lock);
	if (sd) {
		ev3_uart_trace_sensor(port, EV3_UART_TRACE_CLOSED, &sd->desc, sd);
		ev3_uart_sensor_destroy(sd);
	}
}

/**
 * ev3_uart_port_set_label() - set the port's label
 * @port: the port
 * @label: e.g. "in1", checked by the caller; the next sensor's address
 *	has it
 */
void ev3_uart_port_set_label(struct ev3_uart_port *port, const char *label)
{
	spin_lock(&port->lock);
	strscpy(port->label, label, sizeof(port->label));
	spin_unlock(&port->lock);
}

/**
 * ev3_uart_port_get_label() - the port's label
 * @port: the port
 * @label: %EV3_UART_LABEL_LEN bytes for it, NUL-padded
 */
void ev3_uart_port_get_label(struct ev3_uart_port *port, char *label)
{
	spin_lock(&port->lock);
	strscpy_pad(label, port->label, EV3_UART_LABEL_LEN);
	spin_unlock(&port->lock);
}

/**
 * ev3_uart_port_stats() - a port's counters
 * @port: the port
 * @st: they are copied here, with the parser's current counts added
 *
 * Return: the parser's state (enum ev3_uart_state).
 */
u8 ev3_uart_port_stats(struct ev3_uart_port *port, struct ev3_uart_stats *st)
{
	u8 state;

	spin_lock(&port->lock);
	*st = port->stats;
	st->garbage += ev3_uart_parser_garbage(&port->parser);
	st->bad_frames += ev3_uart_parser_bad_frames(&port->parser);
	state = ev3_uart_parser_state(&port->parser);
	spin_unlock(&port->lock);
	return state;
}

/**
 * ev3_uart_view_register() - add a view of every sensor registered from now
 * @view: its operations; it must outlive its registration
 *
 * Only from the module's init, before any port starts.
 *
 * Return: 0, or -%ENOSPC if there are %EV3_UART_MAX_VIEWS already.
 */
int ev3_uart_view_register(const struct ev3_uart_view_ops *view)
{
	int i;

	for (i = 0; i < EV3_UART_MAX_VIEWS; i++) {
		if (!ev3_uart_views[i]) {
			ev3_uart_views[i] = view;
			return 0;
		}
	}
	return -ENOSPC;
}

/**
 * ev3_uart_view_unregister() - remove a view
 * @view: as registered
 *
 * Only from the module's exit (or a failed init), once no port runs.
 */
void ev3_uart_view_unregister(const struct ev3_uart_view_ops *view)
{
	int i;

	for (i = 0; i < EV3_UART_MAX_VIEWS; i++) {
		if (ev3_uart_views[i] != view)
			continue;
		for (; i + 1 < EV3_UART_MAX_VIEWS; i++)
			ev3_uart_views[i] = ev3_uart_views[i + 1];
		ev3_uart_views[i] = NULL;
		return;
	}
}

/**
 * ev3_uart_core_init() - the core's share of the module's init
 *
 * Return: 0 or -%ENOMEM.
 */
int ev3_uart_core_init(void)
{
	ev3_uart_keepalive_wq = alloc_workqueue("lego_ev3_keepalive",
						WQ_UNBOUND | WQ_HIGHPRI, 0);
	return ev3_uart_keepalive_wq ? 0 : -ENOMEM;
}

/**
 * ev3_uart_core_exit() - the core's share of the module's exit
 */
void ev3_uart_core_exit(void)
{
	destroy_workqueue(ev3_uart_keepalive_wq);
}
