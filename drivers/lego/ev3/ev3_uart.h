/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensors: what the line discipline and the
 * device front ends (lego-sensor class, IIO) share.
 *
 * Locking
 * -------
 * ev3_uart_port.lock (spinlock) protects the parser, ev3_uart_port.sensor,
 * every ev3_uart_sensor's values (mode, data) and the IIO buffer state (the
 * mode pushed, the last timestamp). It is taken by the receive path (tty
 * flip-buffer work, which also pushes to the IIO buffer under it), the work
 * items and the sysfs/IIO readers, never for longer than a copy or a push;
 * nothing sleeps under it.
 *
 * ev3_uart_port.select_mutex serialises mode changes (one SELECT in flight):
 * a user's (sysfs, IIO buffer) and the restore of the user's mode after a
 * reconnect (ack_work, keepalive_work), which only try it and give way. An
 * IIO buffer's mode (ev3_uart_iio.buffer_mode) is set under it too, with
 * the port lock, so that no mode change slips in between.
 * ev3_uart_port.tx_mutex serialises writes to the tty (ACK, NACK, SELECT,
 * WRITE, SPEED), which all happen in process context, and protects the
 * transmit queue (see ev3_uart_tx()).
 *
 * ev3_uart_port.closing and ev3_uart_sensor_dev.gone are written under the
 * port lock; the few readers outside it use READ_ONCE().
 *
 * The work items that register and unregister sensors (ack_work,
 * reset_work) run on the port's ordered workqueue, so a sensor is never
 * registered and unregistered at the same time. So do the ones that set
 * the tty's speed: those two, probe_work and fast_work (the fast sync
 * probe, see ev3_uart_hunt()); ev3_uart_port.speed and .no_probe are
 * theirs (the receive path only reads no_probe, with READ_ONCE()). The
 * receive path completes ev3_uart_port.probe_done, under the port lock,
 * when the probe is answered. keepalive_work runs on an unbound
 * high-priority workqueue of the module's, so that NACKs go out (from
 * another CPU if need be) while a sensor registers (the sensor resets
 * after a second without one); it only ticks the parser, sends, queues
 * reset_work and starts keepalive_timer for its next run. tx_work runs on
 * system_dfl_wq. The two timers, ev3_uart_port.ack_timer and
 * .keepalive_timer, run in hard interrupt context and take no lock: each
 * only queues its work.
 *
 * Lifetime
 * --------
 * A struct ev3_uart_sensor_dev lives from the end of a handshake until the
 * sensor is lost or the discipline is closed; its description (modes,
 * ranges) never changes during that time, so readers can never see it
 * half reset. Its memory is freed by the release of its class device, which
 * runs once the last reference (an open sysfs file) is gone.
 * The IIO device is unregistered first (ev3_uart_sensor_destroy()): from
 * then on the IIO core calls none of its callbacks, even for a
 * /dev/iio:deviceN still held open, and what it may still read of its own
 * (name, label) are copies in the IIO device's private data, which lives
 * as long as the IIO device.
 * The port outlives every sensor on it: close() unregisters the sensor,
 * which waits for sysfs callbacks in flight, before freeing the port.
 */
#ifndef _EV3_UART_H
#define _EV3_UART_H

#include <linux/completion.h>
#include <linux/device.h>
#include <linux/hrtimer.h>
#include <linux/mutex.h>
#include <linux/ratelimit.h>
#include <linux/spinlock.h>
#include <linux/tty.h>
#include <linux/workqueue.h>
#include <linux/lego_ev3_uart.h>

#include "ev3_uart_proto.h"

#define EV3_UART_LABEL_LEN	LEGO_EV3_LABEL_LEN
/* "tty name:label" */
#define EV3_UART_ADDRESS_LEN	(sizeof_field(struct tty_struct, name) + EV3_UART_LABEL_LEN)

struct dentry;
struct ev3_uart_port;
struct ev3_uart_iio;

/**
 * struct ev3_uart_stats - a port's counters, in debugfs (since it was
 *	attached; the parser's own counts are added when it restarts)
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
 * @speed_changes: speed switches of the tty
 * @fast_syncs: fast sync probes a device answered (its ACK)
 * @registered: sensors registered
 * @lost: sensors lost (not counting a close)
 * @tx_ack: ACKs sent (under &ev3_uart_port.tx_mutex, like the rest)
 * @tx_nack: NACKs sent
 * @tx_select: SELECTs sent
 * @tx_write: WRITEs sent
 * @tx_speed: SPEEDs sent (the fast sync probes)
 * @tx_errors: messages the tty did not take
 *
 * All but the tx_ ones are under &ev3_uart_port.lock.
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
	u64 tx_ack;
	u64 tx_nack;
	u64 tx_select;
	u64 tx_write;
	u64 tx_speed;
	u64 tx_errors;
};

/**
 * struct ev3_uart_sensor_dev - one connected sensor
 * @port: the line it is on
 * @desc: what the sensor said about itself; never changes
 * @driver_name: e.g. "lego-ev3-color", or "ev3-uart-<type>"
 * @address: e.g. "ttyUSB0:in1" (tty name, then the port label if set)
 * @dev: the lego-sensor class device (sensorN)
 * @id: N of sensorN
 * @gone: the sensor was lost or the line closed (written under
 *	@port->lock)
 * @mode: current mode (under @port->lock)
 * @data: last DATA payload of @mode (under @port->lock)
 * @data_len: its length (under @port->lock)
 * @settle_until: jiffies before which values of a new mode may be stale
 * @mode_work: sends the uevent for a mode change (uevents may sleep)
 * @iio: the IIO front end, or NULL (set under @port->lock)
 */
struct ev3_uart_sensor_dev {
	struct ev3_uart_port *port;
	struct ev3_uart_sensor desc;
	char driver_name[EV3_UART_DRIVER_NAME_LEN];
	char address[EV3_UART_ADDRESS_LEN];
	struct device dev;
	int id;
	bool gone;
	u8 mode;
	u8 data[EV3_UART_MAX_PAYLOAD];
	u8 data_len;
	unsigned long settle_until;
	struct work_struct mode_work;
	struct ev3_uart_iio *iio;
};

/**
 * struct ev3_uart_port - one tty with the discipline attached
 * @tty: the tty
 * @lock: see "Locking" above
 * @parser: protocol state
 * @ack_desc: ev3_uart_ack_work()'s copy of the sensor description (only
 *	that work uses it)
 * @sensor: the registered sensor, or NULL
 * @closing: close() has started; no work may be queued any more (written
 *	under @lock)
 * @wq: ordered workqueue for all work of this port
 * @ack_timer: queues @ack_work 10 ms after the sensor's ACK (an hrtimer:
 *	exact at any HZ; it only queues the work, so it takes no lock)
 * @ack_work: answers the sensor's ACK, switches speed and registers the
 *	sensor
 * @keepalive_timer: queues @keepalive_work 100 ms after its last run (an
 *	hrtimer, as @ack_timer: a timer of the timer wheel, run in a softirq,
 *	was seen over 100 ms late in the test VM while its CPUs ran)
 * @keepalive_work: sends NACK every 100 ms and detects a lost sensor
 * @reset_work: drops a lost sensor and goes back to 2400 baud (after the
 *	fast sync probe)
 * @probe_work: the fast sync probe, when the discipline is attached and
 *	when a device resets (a break in the SYNC or PROBE state), 100 ms
 *	after the last at the earliest
 * @fast_work: gives up a fast sync whose handshake did not come in time
 * @probe_done: completed by the receive path when the probe is answered
 * @probed_at: jiffies of the last probe (under @lock)
 * @break_probe: @probe_work was queued for a break (under @lock)
 * @probe_missed: the last probe for a break went unanswered, and no
 *	handshake started since: the next break gets none (under @lock)
 * @speed: the speed the tty was last set to, 0 if unknown
 * @no_probe: the tty cannot run at 115200 baud: no fast sync probe
 * @select_mutex: see "Locking"
 * @select_mode: the mode a SELECT is waiting for, or %EV3_UART_NO_MODE
 * @select_done: completed by the first DATA of @select_mode, or on loss
 * @tx_mutex: see "Locking"
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
 * @bad_speed: a speed this tty could not be set to: handshakes asking for it
 *	are not answered (only ack_work uses it)
 * @backoff: how the sensors on this line have been failing (only ack_work
 *	and reset_work, on the ordered workqueue, use it and the next two)
 * @registered_at: jiffies when the sensor was registered
 * @backoff_until: jiffies until which handshakes are left unanswered (a
 *	device that keeps failing, see ev3_uart_backoff_lost()), 0 for none
 * @log_rs: rate limit of the port's connect, loss and error lines
 * @tx_buf: bytes queued for the tty (under @tx_mutex)
 * @tx_pos: the first byte of @tx_buf not yet sent
 * @tx_len: bytes queued from @tx_pos on
 * @tx_work: sends what is queued once the tty has room again
 * @tx_failed: the last write to the tty failed (under @tx_mutex): further
 *	errors are not logged until one succeeds
 * @stats: counters, for debugfs
 * @debugfs: the port's directory in debugfs (lego_ev3_uart/TTY)
 */
struct ev3_uart_port {
	struct tty_struct *tty;
	spinlock_t lock;	/* see "Locking" */
	struct ev3_uart_parser parser;
	struct ev3_uart_sensor ack_desc;
	struct ev3_uart_sensor_dev *sensor;
	bool closing;
	struct workqueue_struct *wq;
	struct hrtimer ack_timer;
	struct work_struct ack_work;
	struct hrtimer keepalive_timer;
	struct work_struct keepalive_work;
	struct work_struct reset_work;
	struct delayed_work probe_work;
	struct delayed_work fast_work;
	struct completion probe_done;
	unsigned long probed_at;
	bool break_probe;
	bool probe_missed;
	u32 speed;
	bool no_probe;
	struct mutex select_mutex;	/* one mode change at a time */
	u8 select_mode;
	struct completion select_done;
	struct mutex tx_mutex;		/* one writer to the tty at a time */
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
	u8 tx_buf[4 * EV3_UART_MAX_MSG_LEN];
	unsigned int tx_pos;
	unsigned int tx_len;
	struct work_struct tx_work;
	bool tx_failed;
	struct ev3_uart_stats stats;
	struct dentry *debugfs;
};

/* ev3_uart_ldisc.c */
int ev3_uart_set_mode(struct ev3_uart_sensor_dev *sd, u8 mode);
int ev3_uart_set_buffer_mode(struct ev3_uart_sensor_dev *sd,
			     struct ev3_uart_iio *iio, u8 mode);
int ev3_uart_set_mode_by_name(struct ev3_uart_sensor_dev *sd, const char *name);
int ev3_uart_show_modes(struct ev3_uart_sensor_dev *sd, char *buf);
int ev3_uart_show_mode(struct ev3_uart_sensor_dev *sd, char *buf);
int ev3_uart_write(struct ev3_uart_sensor_dev *sd, const u8 *data, size_t len);
int ev3_uart_get_data(struct ev3_uart_sensor_dev *sd, u8 *mode, u8 *data);

/* ev3_uart_class.c */
int ev3_uart_class_init(void);
void ev3_uart_class_exit(void);
struct ev3_uart_sensor_dev *ev3_uart_sensor_create(struct ev3_uart_port *port,
						   const struct ev3_uart_sensor *desc);
void ev3_uart_sensor_destroy(struct ev3_uart_sensor_dev *sd);

/* ev3_uart_iio.c */
int ev3_uart_iio_register(struct ev3_uart_sensor_dev *sd);
void ev3_uart_iio_unregister(struct ev3_uart_sensor_dev *sd);
bool ev3_uart_iio_mode_busy(struct ev3_uart_sensor_dev *sd, u8 mode);
void ev3_uart_iio_buffer_on(struct ev3_uart_iio *iio, u8 mode);
void ev3_uart_iio_push(struct ev3_uart_sensor_dev *sd, u8 mode,
		       const u8 *data, unsigned int len, size_t rest);

#endif /* _EV3_UART_H */
