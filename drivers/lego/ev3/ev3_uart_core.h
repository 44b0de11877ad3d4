/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensors: the sensor core, between a transport
 * (the tty line discipline, ev3_uart_ldisc.c) and the views of a sensor
 * (the lego-sensor class, ev3_uart_class.c, IIO, ev3_uart_iio.c, and a
 * Powered Up device's lights, ev3_uart_leds.c).
 *
 * Layering is one way. The transport feeds the core what it receives
 * (ev3_uart_port_receive()) and does what the core asks through the
 * &struct ev3_uart_transport_ops it filled in: send bytes, change speed.
 * The core runs the protocol (handshake, ACK, speed switch, keep-alive,
 * loss, fast sync probe, SELECT and its confirmation, the restore of the
 * user's mode after a reconnect) and calls the views through the
 * &struct ev3_uart_view_ops they registered. The views call the core's
 * sensor functions (ev3_uart_get_data(), ev3_uart_set_mode()...) and
 * never the transport, nor take its locks.
 *
 * Locking
 * -------
 * ev3_uart_port.lock (spinlock) protects the parser, ev3_uart_port.sensor,
 * every sensor's values (mode, data, held mode) and what the views keep
 * for the receive path (the IIO buffer's last timestamp). It is taken by
 * the receive path (the transport's receive callback, which also pushes
 * to the views under it: &ev3_uart_view_ops.data), the work items and the
 * views' readers (through the core's functions), never for longer than a
 * copy or a push; nothing sleeps under it, and the transport's operations
 * are never called with it held.
 *
 * ev3_uart_port.select_mutex serialises mode changes (one SELECT in
 * flight): a user's (sysfs, IIO buffer, and the SELECTs around values sent
 * to a Powered Up mode or a combined mode set up, ev3_uart_set_mode_data()
 * and ev3_uart_hold_combo()) and the restore of the user's mode
 * after a reconnect (the port's work, keepalive_work), which only try it and give
 * way. A mode held by an IIO buffer (ev3_uart_sensor_dev.held_mode) is set
 * under it too, with the port lock, so that no mode change slips in
 * between.
 *
 * ev3_uart_port.closing and ev3_uart_sensor_dev.gone are written under the
 * port lock; the few readers outside it use READ_ONCE().
 *
 * One work item, ev3_uart_port.work, makes every change of the line's
 * state: it answers a handshake and registers the sensor, removes a lost
 * one, probes for a fast sync and gives one up, in the order of its
 * ev3_uart_port.todo bits (ev3_uart_work()), one at a time, so a sensor is
 * never registered and unregistered at the same time, and only it sets
 * the line's speed: ev3_uart_port.speed and .no_probe are its (the receive
 * path only reads no_probe, with READ_ONCE()). The receive path, the
 * keep-alive and the timers only set a bit of @todo and queue it. The
 * receive path completes ev3_uart_port.probe_done, under the port lock,
 * when the probe is answered. keepalive_work runs on an unbound
 * high-priority workqueue of the module's, so that NACKs go out (from
 * another CPU if need be) while the port's work registers a sensor (the
 * sensor resets after a second without one); it only ticks the parser,
 * sends, asks for a reset and starts keepalive_timer for its next run.
 * The timers (ev3_uart_port.ack_timer, .probe_timer, .fast_timer and
 * .keepalive_timer) run in hard interrupt context and take no lock: each
 * only queues its work.
 *
 * Lifetime
 * --------
 * A struct ev3_uart_sensor_dev lives from the end of a handshake until
 * its last reference is put (ev3_uart_sensor_put()): the core's, dropped
 * when the sensor is lost or the port stops, and the views' (a class
 * device still held by an open sysfs file). Its description (modes,
 * ranges) never changes, so readers can never see it half reset. The
 * views are removed (&ev3_uart_view_ops.remove, in the reverse order of
 * their registration) once the sensor is marked gone and out of the
 * receive path's reach; a view's remove waits for its callbacks in flight
 * and the core calls none of its operations for the sensor after it.
 * The port outlives every sensor on it: ev3_uart_port_stop() removes the
 * sensor before the transport frees the port.
 */
#ifndef _EV3_UART_CORE_H
#define _EV3_UART_CORE_H

#include <linux/completion.h>
#include <linux/hrtimer.h>
#include <linux/kref.h>
#include <linux/mutex.h>
#include <linux/ratelimit.h>
#include <linux/spinlock.h>
#include <linux/wait.h>
#include <linux/workqueue.h>
#include <linux/lego_ev3_uart.h>

#include "ev3_uart_proto.h"

#define EV3_UART_LABEL_LEN	LEGO_EV3_LABEL_LEN
/* A transport's name for its line, e.g. a tty's ("ttyUSB0"). */
#define EV3_UART_PORT_NAME_LEN	64
/* "line name:label" */
#define EV3_UART_ADDRESS_LEN	(EV3_UART_PORT_NAME_LEN + EV3_UART_LABEL_LEN)
/* What a view calls the sensor in the log, e.g. "sensor3". */
#define EV3_UART_DEV_NAME_LEN	32
/* The views a sensor can have: the lego-sensor class, IIO and its lights. */
#define EV3_UART_MAX_VIEWS	3

/* ev3_uart_port_receive()'s flags: a byte received without error is 0. */
#define EV3_UART_RX_OK		0
#define EV3_UART_RX_BREAK	1	/* the line held low: a device resets */

struct device;
struct ev3_uart_port;
struct ev3_uart_iio;
struct ev3_uart_class_dev;
struct ev3_uart_leds;

/**
 * struct ev3_uart_stats - a port's protocol counters (since the port was
 *	started; the parser's own counts are added when it restarts)
 * @syncs: TYPE messages that started a handshake
 * @handshakes: handshakes completed (the sensor's ACK)
 * @info_msgs: handshake messages (CMD, INFO) received while ev3_uart_rx
 *	was traced (the parser reports them only then)
 * @data_msgs: good DATA messages
 * @resyncs: protocol errors, each a return to 2400 baud (resync)
 * @line_errors: bytes received with a framing, parity or overrun error
 * @garbage: bytes dropped while hunting for a message (parser restarts)
 * @bad_frames: DATA messages dropped: bad checksum, size or mode (parser
 *	restarts)
 * @speed_changes: speed switches asked of the transport
 * @fast_syncs: fast sync probes a device answered (its ACK)
 * @registered: sensors registered
 * @lost: sensors lost (not counting a stop)
 *
 * All under &ev3_uart_port.lock.
 */
struct ev3_uart_stats {
	u64 syncs;
	u64 handshakes;
	u64 info_msgs;
	u64 data_msgs;
	u64 resyncs;
	u64 line_errors;
	u64 garbage;
	u64 bad_frames;
	u64 speed_changes;
	u64 fast_syncs;
	u64 registered;
	u64 lost;
};

/**
 * struct ev3_uart_transport_ops - what the core asks of its transport
 * @send: queue a whole message behind what is queued and send what the
 *	line takes; the rest goes out when it has room. Return: 0, or a
 *	negative errno if the line cannot take it (the message is dropped).
 * @discard: drop what is queued and not yet on the wire (a speed change,
 *	a lost sensor: it was meant for the old speed or sensor)
 * @set_speed: drop what is queued, then run the line at @baud. Return: 0,
 *	or -%EINVAL if the line runs at another speed than @baud now.
 * @drain: wait until what is queued is on the wire, @ms at most
 *
 * All are called in process context, from the port's work items and the
 * views' writes, never under &ev3_uart_port.lock; @send may be called
 * from several at once.
 */
struct ev3_uart_transport_ops {
	int (*send)(struct ev3_uart_port *port, const u8 *buf, size_t len);
	void (*discard)(struct ev3_uart_port *port);
	int (*set_speed)(struct ev3_uart_port *port, u32 baud);
	void (*drain)(struct ev3_uart_port *port, unsigned int ms);
};

/**
 * struct ev3_uart_sensor_dev - one connected sensor
 * @port: the line it is on
 * @desc: what the sensor said about itself; never changes
 * @driver_name: e.g. "lego-ev3-color", or "ev3-uart-<type>"
 * @address: e.g. "ttyUSB0:in1" (the line's name, then the port label if
 *	set)
 * @name: the first view's device name ("sensor3"), empty if none gave
 *	one (see ev3_uart_sensor_name()); set before the sensor is published
 * @ref: the core's reference and the views'
 * @gone: the sensor was lost or the port stopped (written under
 *	@port->lock)
 * @mode: current mode (under @port->lock)
 * @data: last DATA payload of @mode (under @port->lock)
 * @data_len: its length (under @port->lock)
 * @settle_until: jiffies before which values of a new mode may be stale
 *	(under @port->lock)
 * @fresh: @data can be trusted: false from a switch to a mode that may
 *	send stale values first (ev3_uart_settle_ms()) until its first DATA
 *	message after @settle_until (under @port->lock)
 * @fresh_wait: readers of the values waiting for @fresh (or @gone)
 * @held_mode: the mode an IIO buffer holds the sensor to, or
 *	%EV3_UART_NO_MODE (under @port->lock and &ev3_uart_port.select_mutex)
 * @lent_mode: the mode ev3_uart_set_mode_data() switched the sensor to for
 *	a moment, or %EV3_UART_NO_MODE: its DATA change neither @mode nor
 *	@data (under @port->lock and &ev3_uart_port.select_mutex)
 * @combo_len: while ev3_uart_hold_combo() holds a combined mode, the size
 *	of its values in a DATA message of mode 0, else 0 (as @held_mode)
 * @iio: the IIO view's, or NULL: the core never looks at it
 * @cls: the class view's, or NULL: the core never looks at it
 * @leds: the LED view's, or NULL: the core never looks at it
 */
struct ev3_uart_sensor_dev {
	struct ev3_uart_port *port;
	struct ev3_uart_sensor desc;
	char driver_name[EV3_UART_DRIVER_NAME_LEN];
	char address[EV3_UART_ADDRESS_LEN];
	char name[EV3_UART_DEV_NAME_LEN];
	struct kref ref;
	bool gone;
	u8 mode;
	u8 data[EV3_UART_MAX_PAYLOAD];
	u8 data_len;
	unsigned long settle_until;
	bool fresh;
	wait_queue_head_t fresh_wait;
	u8 held_mode;
	u8 lent_mode;
	u8 combo_len;
	struct ev3_uart_iio *iio;
	struct ev3_uart_class_dev *cls;
	struct ev3_uart_leds *leds;
};

/**
 * struct ev3_uart_view_ops - a view of the sensors (the class, IIO)
 * @add: a sensor completed its handshake: make its devices, before the
 *	sensor is published to the receive path (may sleep). A view that
 *	cannot do without (the class) returns an error, and the sensor is
 *	not registered; one that can (IIO) says so in the log and returns 0.
 * @remove: the sensor is gone and out of the receive path's reach:
 *	remove its devices and wait for their callbacks (may sleep)
 * @data: a DATA message of @mode, @len bytes, @rest bytes before the end
 *	of the batch received (for its timestamp), its values fresh (see
 *	&ev3_uart_sensor_dev.fresh); under the port lock, never sleeps
 * @mode_changed: the sensor switched to another mode; under the port
 *	lock, never sleeps
 *
 * Any of them may be NULL.
 */
struct ev3_uart_view_ops {
	int (*add)(struct ev3_uart_sensor_dev *sd);
	void (*remove)(struct ev3_uart_sensor_dev *sd);
	void (*data)(struct ev3_uart_sensor_dev *sd, u8 mode, const u8 *data,
		     unsigned int len, size_t rest);
	void (*mode_changed)(struct ev3_uart_sensor_dev *sd);
};

/**
 * struct ev3_uart_port - one line with a sensor on it, as the core sees it
 * @ops: the transport's operations
 * @name: the line's name, for the log and the sensor's address
 * @parent: the device of the line, parent of the sensor's devices
 * @lock: see "Locking" above
 * @parser: protocol state
 * @ack_desc: ev3_uart_ack()'s copy of the sensor description (only the
 *	port's work uses it)
 * @sensor: the registered sensor, or NULL
 * @closing: ev3_uart_port_stop() has started; no work may be queued any
 *	more (written under @lock)
 * @wq: ordered workqueue of @work
 * @todo: what @work is asked to do (bits of enum ev3_uart_todo, set and
 *	cleared atomically, without @lock)
 * @work: the port's state changes but the keep-alive's (ev3_uart_work()):
 *	answers the sensor's ACK, switches speed and registers the sensor;
 *	drops a lost sensor and goes back to 2400 baud (after the fast sync
 *	probe); probes when the port starts and when a device resets (a
 *	break in the SYNC or PROBE state), 100 ms after the last probe at the
 *	earliest; gives up a fast sync whose handshake did not come in time
 * @ack_timer: asks @work to answer 10 ms after the sensor's ACK (an
 *	hrtimer: exact at any HZ; it takes no lock)
 * @probe_timer: asks @work for a probe a break put off
 * @fast_timer: asks @work to give up a fast sync, 500 ms after the answer
 * @keepalive_timer: queues @keepalive_work 100 ms after its last run (an
 *	hrtimer, as @ack_timer: a timer of the timer wheel, run in a softirq,
 *	was seen over 100 ms late in the test VM while its CPUs ran)
 * @keepalive_work: sends NACK every 100 ms and detects a lost sensor
 * @probe_done: completed by the receive path when the probe is answered
 * @probed_at: jiffies of the last probe (under @lock)
 * @break_probe: the probe asked for is for a break (under @lock)
 * @probe_missed: the last probe for a break went unanswered, and no
 *	handshake started since: the next break gets none (under @lock)
 * @speed: the speed the line was last set to, 0 if unknown
 * @no_probe: the line cannot run at 115200 baud: no fast sync probe
 * @select_mutex: see "Locking"
 * @select_mode: the mode a SELECT is waiting for, or %EV3_UART_NO_MODE
 * @select_done: completed by the first DATA of @select_mode, or on loss
 * @requested_type: sensor type the user chose @requested_mode for
 * @requested_lump: that sensor was a Powered Up device (whose type ids
 *	overlap third-party EV3 ones)
 * @requested_mode: mode restored after a reconnect, or %EV3_UART_NO_MODE
 * @restored_at: jiffies of the last restore (a sensor lost right after
 *	one, as calibration modes do, does not get it again)
 * @restore_mode: mode being restored and not yet confirmed, or
 *	%EV3_UART_NO_MODE
 * @restore_ticks: keep-alive periods since the restore began
 * @label: port label set by the user (module parameter or
 *	%LEGO_EV3_SET_PORT_LABEL), e.g. "in1"; under @lock
 * @last_error: reason of the last protocol error, for the log (under @lock)
 * @bad_speed: a speed this line could not be set to: handshakes asking for
 *	it are not answered (only @work uses it)
 * @backoff: how the sensors on this line have been failing (only @work
 *	uses it and the next two)
 * @registered_at: jiffies when the sensor was registered
 * @backoff_until: jiffies until which handshakes are left unanswered (a
 *	device that keeps failing, see ev3_uart_backoff_lost()), 0 for none
 * @log_rs: rate limit of the port's connect, loss and error lines
 * @stats: counters, for debugfs
 */
struct ev3_uart_port {
	const struct ev3_uart_transport_ops *ops;
	char name[EV3_UART_PORT_NAME_LEN];
	struct device *parent;
	spinlock_t lock;	/* see "Locking" */
	struct ev3_uart_parser parser;
	struct ev3_uart_sensor ack_desc;
	struct ev3_uart_sensor_dev *sensor;
	bool closing;
	struct workqueue_struct *wq;
	unsigned long todo;
	struct work_struct work;
	struct hrtimer ack_timer;
	struct hrtimer probe_timer;
	struct hrtimer fast_timer;
	struct hrtimer keepalive_timer;
	struct work_struct keepalive_work;
	struct completion probe_done;
	unsigned long probed_at;
	bool break_probe;
	bool probe_missed;
	u32 speed;
	bool no_probe;
	struct mutex select_mutex;	/* one mode change at a time */
	u8 select_mode;
	struct completion select_done;
	u8 requested_type;
	bool requested_lump;
	u8 requested_mode;
	unsigned long restored_at;
	u8 restore_mode;
	unsigned int restore_ticks;
	char label[EV3_UART_LABEL_LEN];
	const char *last_error;
	u32 bad_speed;
	struct ev3_uart_backoff backoff;
	unsigned long registered_at;
	unsigned long backoff_until;
	struct ratelimit_state log_rs;
	struct ev3_uart_stats stats;
};

/* ev3_uart_core.c: for the module's init and the transport */
int ev3_uart_core_init(void);
void ev3_uart_core_exit(void);
int ev3_uart_view_register(const struct ev3_uart_view_ops *view);
void ev3_uart_view_unregister(const struct ev3_uart_view_ops *view);
int ev3_uart_port_init(struct ev3_uart_port *port,
		       const struct ev3_uart_transport_ops *ops,
		       const char *name, struct device *parent, u32 speed);
void ev3_uart_port_start(struct ev3_uart_port *port);
void ev3_uart_port_stop(struct ev3_uart_port *port);
void ev3_uart_port_receive(struct ev3_uart_port *port, const u8 *cp,
			   const u8 *flags, size_t count);
void ev3_uart_port_set_label(struct ev3_uart_port *port, const char *label);
void ev3_uart_port_get_label(struct ev3_uart_port *port, char *label);
u8 ev3_uart_port_stats(struct ev3_uart_port *port, struct ev3_uart_stats *st);

/* ev3_uart_core.c: for the views */
void ev3_uart_sensor_get(struct ev3_uart_sensor_dev *sd);
void ev3_uart_sensor_put(struct ev3_uart_sensor_dev *sd);
const char *ev3_uart_sensor_name(const struct ev3_uart_sensor_dev *sd);
bool ev3_uart_sensor_log_ok(struct ev3_uart_sensor_dev *sd);
int ev3_uart_get_data(struct ev3_uart_sensor_dev *sd, u8 *mode, u8 *data);
int ev3_uart_get_values(struct ev3_uart_sensor_dev *sd, u8 *mode, u8 *data);
int ev3_uart_set_mode(struct ev3_uart_sensor_dev *sd, u8 mode);
int ev3_uart_set_mode_by_name(struct ev3_uart_sensor_dev *sd, const char *name);
int ev3_uart_hold_mode(struct ev3_uart_sensor_dev *sd, u8 mode);
void ev3_uart_release_mode(struct ev3_uart_sensor_dev *sd);
int ev3_uart_show_modes(struct ev3_uart_sensor_dev *sd, char *buf);
int ev3_uart_show_mode(struct ev3_uart_sensor_dev *sd, char *buf);
int ev3_uart_write(struct ev3_uart_sensor_dev *sd, const u8 *data, size_t len);
int ev3_uart_set_mode_data(struct ev3_uart_sensor_dev *sd, u8 mode,
			   const u8 *data, size_t len);
int ev3_uart_hold_combo(struct ev3_uart_sensor_dev *sd,
			const struct ev3_uart_combo_entry *e, unsigned int n);
void ev3_uart_release_combo(struct ev3_uart_sensor_dev *sd);

#endif /* _EV3_UART_CORE_H */
