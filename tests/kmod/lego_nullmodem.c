// SPDX-License-Identifier: GPL-2.0
/*
 * Test-only null-modem cable: pairs of ttys (ttyNM0 <-> ttyNM1, ttyNM2 <->
 * ttyNM3, ...) wired like two UARTs, so that emulated sensors can be tested
 * the way real ones behave on a wire:
 *
 *  - bytes are paced at the writer's baud rate (10 bits per byte, 8N1), so
 *    a handshake at 2400 baud takes as long as on a real sensor and
 *    tty_wait_until_sent() waits until the bytes are "on the wire";
 *  - a byte whose writer and reader run at different speeds arrives as
 *    garbage with TTY_FRAME set, as on a UART (one garbled byte per group of
 *    bytes when the writer is faster, several when it is slower);
 *  - a break (tcsendbreak) arrives as a TTY_BREAK character;
 *  - nothing arrives when the other end is not open.
 *
 * Knobs for tests of the line discipline's own behaviour:
 *  - fifo_room (writable) limits the bytes a port holds before they are on
 *    the wire, so that writes are taken in part, as from a UART whose
 *    buffer is full;
 *  - fail_writes (writable, a bitmask of ports) makes every write to those
 *    ports fail with -EIO, as a broken tty's would;
 *  - tx_stall (writable, a bitmask of ports) holds those ports' transmitters,
 *    as a UART whose FIFO is full and whose CTS the other end deasserts:
 *    write_room() is 0, write() takes nothing, and what the port holds
 *    stays there. Clearing a port's bit lets its bytes go on and wakes its
 *    writer (tty_wakeup()), as the UART's interrupt does once it may send;
 *  - debugfs lego_nullmodem/ttyNM<n>/wire lists what the port took from
 *    its writer ("w") and what it put on the wire ("o"), a byte a line
 *    with ktime_get_ns() and the port's speed at that moment (the last
 *    NM_LOG_SIZE bytes; writing to the file empties it), and .../state
 *    says whether the port is stalled, how many bytes it holds, and the
 *    TTY_DO_WRITE_WAKEUP flag of its tty (-1 when it is not open), which
 *    a line discipline must not leave set for the next one;
 *  - ack_ns records, per port, when its last burst of bytes at 2400 baud
 *    that ended in 0x04 (an EV3 ACK) was on the wire, so that a test can
 *    time the discipline's ACK against the sensor's on the line itself,
 *    whatever the emulator's thread was doing;
 *  - the debugfs file lego_nullmodem/wire logs, with ktime_get_ns() when
 *    it was on the wire, every byte an even port sends (the discipline's
 *    end of each line in the tests: its ACK, keep-alive NACKs, SELECT...)
 *    and the end of every burst of an odd port (the sensor's end) whose
 *    last byte is 0x04 (a sensor's ACK ends its handshake this way), so
 *    that tests can time the discipline's ACK and keep-alive period on
 *    every handshake from kernel time alone (see nm_wire_log()); and,
 *    for the even ports, when each byte was written (before the pacing);
 *  - the same log has a record 's' for each time a CPU of the guest could
 *    not run for NM_STALL_MIN_NS or more: one pinned hard hrtimer a CPU
 *    fires every NM_BEAT_NS, and when one fires that late, the record
 *    (port 255, the CPU in the byte) says when it fired and, in the baud
 *    field, how many microseconds late. Under QEMU's TCG the guest's clock
 *    is the host's: a host that does not run the guest's CPUs makes every
 *    timer of the guest late, the discipline's keep-alive too, and these
 *    records let wire.py tell such a stall from the discipline's own
 *    lateness;
 *  - and a record 'q' (port 255, the CPU it ran on in the byte) each time
 *    a probe work item, queued every NM_BEAT_NS on a workqueue of the
 *    discipline's keep-alive kind (unbound, high priority) from a hard
 *    hrtimer, ran NM_STALL_MIN_NS late or more (the baud field: how many
 *    microseconds): CPUs that run but run other things (a long section
 *    without preemption, an emulated CPU slowed by its host) delay every
 *    such work item, the discipline's keep-alive as much as the probe,
 *    and the heartbeat above does not see it. A delay of the
 *    discipline's own making (its lock held, its work not queued) leaves
 *    the probe on time.
 *
 * And a sensor stream generator for the sample-delivery benchmark
 * (tests/bench/guest/ev3_bench.py), so that the sender's rate is exact and
 * costs one timer rather than a userspace program writing every line:
 *  - gen_lines (a bitmask of pairs) and gen_payload (bytes, a power of two
 *    up to 32) choose the lines and the message; writing gen_hz > 0 starts
 *    the generator (its counters reset), writing 0 stops it;
 *  - while it runs, one hrtimer on an absolute schedule puts one EV3 DATA
 *    message (mode 0, a counting s16 value 0, 1, 2... in its first two
 *    payload bytes, then the checksum) every 1/gen_hz s straight into the
 *    receive buffer of ttyNM(2n) for each pair n in gen_lines, as a sensor
 *    on ttyNM(2n+1) would send it, without the pacing (the message is 4
 *    bytes at 57600 baud: 694 us of a 1000 us period). A late tick sends
 *    the messages that were due since, at most GEN_MAX_BURST at once;
 *  - gen_sent (per pair) counts the messages sent, whether or not the line
 *    is open, gen_dropped those the tty buffer refused (a UART overrun),
 *    gen_span_ns the time from start to stop, gen_late the ticks that sent
 *    more than one message a line, gen_max_burst the most, and gen_cpu_ns
 *    the time spent in the timer function.
 * The line's own writer (ttyNM(2n+1)) must stay quiet meanwhile: its paced
 * bytes would interleave with the generated messages. What the host writes
 * on ttyNM(2n) meanwhile (the line discipline's keep-alives) is taken at
 * once and counted in gen_tx, not paced nor passed on: the sensor's side of
 * the benchmark then costs nothing but the generator's timer.
 *
 * Not meant for anything but tests.
 */
#include <linux/atomic.h>
#include <linux/cpu.h>
#include <linux/debugfs.h>
#include <linux/hrtimer.h>
#include <linux/kfifo.h>
#include <linux/log2.h>
#include <linux/module.h>
#include <linux/percpu.h>
#include <linux/seq_file.h>
#include <linux/slab.h>
#include <linux/smp.h>
#include <linux/spinlock.h>
#include <linux/tty.h>
#include <linux/tty_driver.h>
#include <linux/tty_flip.h>
#include <linux/workqueue.h>

#include "lego_compat.h"

#define NM_FIFO_SIZE	4096
#define NM_TICK_NS	(500 * NSEC_PER_USEC)
#define NM_MAX_PAIRS	16
#define GEN_MAX_BURST	64
#define GEN_MAX_HZ	100000
#define NM_LOG_SIZE	512

static unsigned int pairs = 4;
module_param(pairs, uint, 0444);
MODULE_PARM_DESC(pairs, "number of tty pairs (default 4, at most 16)");

static unsigned int fifo_room;
module_param(fifo_room, uint, 0644);
MODULE_PARM_DESC(fifo_room, "bytes a port holds before they are sent (default 0: 4096)");

static unsigned int fail_writes;
module_param(fail_writes, uint, 0644);
MODULE_PARM_DESC(fail_writes, "bitmask of ports whose writes fail with -EIO (default 0)");

static unsigned long long ack_ns[32];
module_param_array(ack_ns, ullong, NULL, 0444);
MODULE_PARM_DESC(ack_ns,
		 "per port: ktime_get_ns() when its last 2400-baud burst ending in 0x04 was sent");

static unsigned int gen_lines;
module_param(gen_lines, uint, 0644);
MODULE_PARM_DESC(gen_lines, "generator: bitmask of the pairs whose even port receives a stream");

static unsigned int gen_payload = 2;
module_param(gen_payload, uint, 0644);
MODULE_PARM_DESC(gen_payload, "generator: payload bytes of each DATA message (1, 2, 4 ... 32)");

static unsigned long gen_sent[NM_MAX_PAIRS];
module_param_array(gen_sent, ulong, NULL, 0444);
MODULE_PARM_DESC(gen_sent, "generator: messages sent per pair since the last start");

static unsigned long gen_dropped[NM_MAX_PAIRS];
module_param_array(gen_dropped, ulong, NULL, 0444);
MODULE_PARM_DESC(gen_dropped, "generator: messages per pair the tty buffer had no room for");

static unsigned long long gen_span_ns;
module_param(gen_span_ns, ullong, 0444);
MODULE_PARM_DESC(gen_span_ns, "generator: ns from the last start to the last stop");

static unsigned long long gen_cpu_ns;
module_param(gen_cpu_ns, ullong, 0444);
MODULE_PARM_DESC(gen_cpu_ns, "generator: ns spent in its timer function since the last start");

static unsigned long gen_tx[NM_MAX_PAIRS];
module_param_array(gen_tx, ulong, NULL, 0444);
MODULE_PARM_DESC(gen_tx, "generator: bytes per pair the host wrote, taken at once, since the last start");

static unsigned long gen_late;
module_param(gen_late, ulong, 0444);
MODULE_PARM_DESC(gen_late, "generator: ticks that sent more than one message a line");

static unsigned int gen_max_burst;
module_param(gen_max_burst, uint, 0444);
MODULE_PARM_DESC(gen_max_burst, "generator: most messages a line sent in one tick");

/**
 * struct nm_gen - the stream generator (see the top of the file)
 * @timer: its tick, on an absolute schedule
 * @start: when it was started
 * @period_ns: 1/gen_hz
 * @due: messages sent per line so far
 * @lines: gen_lines when it was started
 * @payload: gen_payload when it was started
 * @running: started (read by nm_write())
 * @seq: the next value of each pair
 */
struct nm_gen {
	struct hrtimer timer;
	ktime_t start;
	u64 period_ns;
	u64 due;
	unsigned int lines;
	unsigned int payload;
	bool running;
	u16 seq[NM_MAX_PAIRS];
};

static unsigned int gen_hz;
static struct nm_gen nm_gen;

/**
 * struct nm_byte - a byte a port took from its writer or sent (the wire log)
 * @ns: ktime_get_ns() at that moment
 * @baud: the port's speed then
 * @byte: the byte
 * @kind: 'w' taken by write(), 'o' put on the wire
 */
struct nm_byte {
	u64 ns;
	u32 baud;
	u8 byte;
	char kind;
};

/**
 * struct nm_port - one end of a cable
 * @port: the tty port
 * @peer: the other end
 * @lock: protects @fifo, @credit, @running, @log and @logged
 * @fifo: bytes written and not yet on the wire
 * @timer: paces the bytes out
 * @running: @timer is started and will run again
 * @baud: current speed of this end
 * @credit: bit times available to send, in 1/1e9 bits
 * @last: time of the last tick
 * @garble: state of the garbage generator (timer context only)
 * @log: the last %NM_LOG_SIZE bytes taken and sent
 * @logged: bytes logged since the log was last emptied
 */
struct nm_port {
	struct tty_port port;
	struct nm_port *peer;
	spinlock_t lock;	/* see above */
	DECLARE_KFIFO(fifo, u8, NM_FIFO_SIZE);
	struct hrtimer timer;
	bool running;
	unsigned int baud;
	u64 credit;
	ktime_t last;
	u32 garble;
	struct nm_byte *log;
	unsigned int logged;
};

static struct nm_port *nm_ports;
static struct tty_driver *nm_driver;
static struct dentry *nm_debugfs;
static unsigned int tx_stall;

static bool nm_stalled(const struct nm_port *p)
{
	return READ_ONCE(tx_stall) & BIT(p - nm_ports);
}

/* Log @n bytes the port took ('w') or sent ('o'). @p->lock held. */
static void nm_log(struct nm_port *p, char kind, const u8 *buf, unsigned int n)
{
	u32 baud = READ_ONCE(p->baud);
	u64 ns = ktime_get_ns();
	struct nm_byte *b;
	unsigned int i;

	lockdep_assert_held(&p->lock);
	for (i = 0; i < n; i++) {
		b = &p->log[p->logged++ % NM_LOG_SIZE];
		b->ns = ns;
		b->baud = baud;
		b->byte = buf[i];
		b->kind = kind;
	}
}

/*
 * The wire log (debugfs lego_nullmodem/wire): the last NM_WIRE_LOG records,
 * one a line, oldest first: "seq ns port baud kind byte", kind 'b' for a
 * byte of an even port on the wire, 'w' for one written to it (taken by
 * nm_write()), and 'a' for the end of an odd port's burst that ended in
 * 0x04 (byte is then 04), 's' and 'q' (port 255) for a stalled CPU and a
 * late probe work item (see the top of the file); seq counts every record
 * since the module was loaded (or the log was cleared: write anything to
 * the file), so that a reader can take only what is new and see what was
 * overwritten.
 */
#define NM_WIRE_LOG	16384

struct nm_wire_rec {
	u64 ns;
	u32 baud;
	u8 port;
	u8 byte;
	u8 kind;
};

#define NM_WIRE_STALL	255	/* the port of a stall record */

static struct nm_wire_rec nm_wire[NM_WIRE_LOG];
static u64 nm_wire_head;		/* records logged: the next seq */
/* Protects the two above; raw: the stall heartbeat takes it in hard irq. */
static DEFINE_RAW_SPINLOCK(nm_wire_lock);

/*
 * @n bytes of port @p went on the wire, the last one at @now, @end if its
 * fifo is empty now: each byte's time is when its last bit was sent, at
 * @baud (timer context).
 */
static void nm_wire_log(struct nm_port *p, const u8 *buf, unsigned int n,
			unsigned int baud, u64 now, bool end)
{
	unsigned int port = p - nm_ports, i;
	u64 byte_ns = div_u64(10ULL * NSEC_PER_SEC, baud ?: 9600);
	struct nm_wire_rec *r;
	unsigned long flags;

	if (!(port & 1) || (end && buf[n - 1] == 0x04)) {
		raw_spin_lock_irqsave(&nm_wire_lock, flags);
		for (i = (port & 1) ? n - 1 : 0; i < n; i++) {
			r = &nm_wire[nm_wire_head++ % NM_WIRE_LOG];
			r->ns = now - (n - 1 - i) * byte_ns;
			r->baud = baud;
			r->port = port;
			r->byte = buf[i];
			r->kind = (port & 1) ? 'a' : 'b';
		}
		raw_spin_unlock_irqrestore(&nm_wire_lock, flags);
	}
}

/* @n bytes were written to the even port @port at @baud (any context). */
static void nm_wire_log_write(unsigned int port, const u8 *buf, unsigned int n,
			      unsigned int baud)
{
	u64 now = ktime_get_ns();
	struct nm_wire_rec *r;
	unsigned long flags;
	unsigned int i;

	raw_spin_lock_irqsave(&nm_wire_lock, flags);
	for (i = 0; i < n; i++) {
		r = &nm_wire[nm_wire_head++ % NM_WIRE_LOG];
		r->ns = now;
		r->baud = baud;
		r->port = port;
		r->byte = buf[i];
		r->kind = 'w';
	}
	raw_spin_unlock_irqrestore(&nm_wire_lock, flags);
}

/*
 * The stall heartbeat: a pinned hrtimer on each CPU, in hard interrupt
 * context, so that nothing but the CPU not running (the host not running
 * the guest's vCPU, or interrupts off that long) makes it late.
 */
#define NM_BEAT_NS	(5 * NSEC_PER_MSEC)
#define NM_STALL_MIN_NS	(10 * NSEC_PER_MSEC)

/* A stall record of @kind: @late ns late at @now, on this CPU. */
static void nm_wire_stall(char kind, u64 now, u64 late)
{
	struct nm_wire_rec *r;
	unsigned long flags;

	raw_spin_lock_irqsave(&nm_wire_lock, flags);
	r = &nm_wire[nm_wire_head++ % NM_WIRE_LOG];
	r->ns = now;
	r->baud = min_t(u64, div_u64(late, NSEC_PER_USEC), U32_MAX);
	r->port = NM_WIRE_STALL;
	r->byte = raw_smp_processor_id();
	r->kind = kind;
	raw_spin_unlock_irqrestore(&nm_wire_lock, flags);
}

static DEFINE_PER_CPU(struct hrtimer, nm_beat);

static enum hrtimer_restart nm_beat_fn(struct hrtimer *timer)
{
	u64 now = ktime_get_ns();
	s64 late = now - ktime_to_ns(hrtimer_get_expires(timer));

	if (late >= NM_STALL_MIN_NS)
		nm_wire_stall('s', now, late);
	hrtimer_forward_now(timer, ns_to_ktime(NM_BEAT_NS));
	return HRTIMER_RESTART;
}

static void nm_beat_start(void *unused)
{
	struct hrtimer *t = this_cpu_ptr(&nm_beat);

	hrtimer_setup(t, nm_beat_fn, CLOCK_MONOTONIC, HRTIMER_MODE_REL_PINNED_HARD);
	hrtimer_start(t, ns_to_ktime(NM_BEAT_NS), HRTIMER_MODE_REL_PINNED_HARD);
}

static void nm_beat_stop(void)
{
	unsigned int cpu;

	for_each_online_cpu(cpu)
		hrtimer_cancel(per_cpu_ptr(&nm_beat, cpu));
}

/*
 * The work-queue probe: @timer queues @work every NM_BEAT_NS unless it is
 * still waiting (then its lateness keeps growing from @queued_ns, the time
 * it was queued), and @work logs a 'q' record when it ran late.
 */
static struct {
	struct workqueue_struct *wq;
	struct hrtimer timer;
	struct work_struct work;
	u64 queued_ns;
	atomic_t waiting;
} nm_probe;

static void nm_probe_work(struct work_struct *work)
{
	u64 now = ktime_get_ns();
	u64 late = now - READ_ONCE(nm_probe.queued_ns);

	atomic_set(&nm_probe.waiting, 0);
	if (late >= NM_STALL_MIN_NS)
		nm_wire_stall('q', now, late);
}

static enum hrtimer_restart nm_probe_fn(struct hrtimer *timer)
{
	if (!atomic_xchg(&nm_probe.waiting, 1)) {
		WRITE_ONCE(nm_probe.queued_ns, ktime_get_ns());
		queue_work(nm_probe.wq, &nm_probe.work);
	}
	hrtimer_forward_now(timer, ns_to_ktime(NM_BEAT_NS));
	return HRTIMER_RESTART;
}

static int nm_probe_start(void)
{
	nm_probe.wq = alloc_workqueue("lego_nullmodem_probe", WQ_UNBOUND | WQ_HIGHPRI, 0);
	if (!nm_probe.wq)
		return -ENOMEM;
	INIT_WORK(&nm_probe.work, nm_probe_work);
	hrtimer_setup(&nm_probe.timer, nm_probe_fn, CLOCK_MONOTONIC, HRTIMER_MODE_REL_HARD);
	hrtimer_start(&nm_probe.timer, ns_to_ktime(NM_BEAT_NS), HRTIMER_MODE_REL_HARD);
	return 0;
}

static void nm_probe_stop(void)
{
	hrtimer_cancel(&nm_probe.timer);	/* as nm_beat_stop(): restarts too */
	destroy_workqueue(nm_probe.wq);	/* drains the work */
}

static void *nm_wire_start(struct seq_file *m, loff_t *pos)
	__acquires(&nm_wire_lock)
{
	u64 oldest;

	raw_spin_lock_irq(&nm_wire_lock);
	oldest = nm_wire_head > NM_WIRE_LOG ? nm_wire_head - NM_WIRE_LOG : 0;
	if (*pos < oldest)
		*pos = oldest;
	return *pos < nm_wire_head ? pos : NULL;
}

static void *nm_wire_next(struct seq_file *m, void *v, loff_t *pos)
{
	++*pos;
	return *pos < nm_wire_head ? pos : NULL;
}

static void nm_wire_stop(struct seq_file *m, void *v)
	__releases(&nm_wire_lock)
{
	raw_spin_unlock_irq(&nm_wire_lock);
}

static int nm_wire_show(struct seq_file *m, void *v)
{
	u64 seq = *(loff_t *)v;
	const struct nm_wire_rec *r = &nm_wire[seq % NM_WIRE_LOG];

	seq_printf(m, "%llu %llu %u %u %c %02x\n", seq, r->ns, r->port, r->baud,
		   r->kind, r->byte);
	return 0;
}

static const struct seq_operations nm_wire_seq_ops = {
	.start	= nm_wire_start,
	.next	= nm_wire_next,
	.stop	= nm_wire_stop,
	.show	= nm_wire_show,
};

static int nm_wire_open(struct inode *inode, struct file *file)
{
	return seq_open(file, &nm_wire_seq_ops);
}

/* Any write clears the log. */
static ssize_t nm_wire_write(struct file *file, const char __user *buf,
			     size_t count, loff_t *ppos)
{
	raw_spin_lock_irq(&nm_wire_lock);
	nm_wire_head = 0;
	raw_spin_unlock_irq(&nm_wire_lock);
	return count;
}

static const struct file_operations nm_wire_fops = {
	.owner		= THIS_MODULE,
	.open		= nm_wire_open,
	.read		= seq_read,
	.write		= nm_wire_write,
	.llseek		= seq_lseek,
	.release	= seq_release,
};

static void nm_deliver(struct nm_port *from, const u8 *buf, unsigned int n)
{
	struct nm_port *to = from->peer;
	unsigned int wbaud = READ_ONCE(from->baud), rbaud;
	struct tty_struct *tty = tty_port_tty_get(&to->port);
	unsigned int i, k, ratio;

	if (!tty)
		return;	/* nobody listening: the bytes are lost */
	rbaud = READ_ONCE(to->baud);

	if (wbaud == rbaud) {
		tty_insert_flip_string(&to->port, buf, n);
	} else if (wbaud > rbaud) {
		/* The reader sees one mangled frame per group of bytes. */
		ratio = DIV_ROUND_UP(wbaud, rbaud);
		for (i = 0; i < n; i++) {
			from->garble = from->garble * 1103515245 + 12345;
			if (from->garble % ratio)
				continue;
			tty_insert_flip_char(&to->port, 0xff ^ buf[i] ^ (from->garble >> 16),
					     TTY_FRAME);
		}
	} else {
		/* Each slow byte reads as several short, broken frames. */
		ratio = DIV_ROUND_UP(rbaud, wbaud);
		for (i = 0; i < n; i++)
			for (k = 0; k < ratio && k < 8; k++)
				tty_insert_flip_char(&to->port,
						     (buf[i] & BIT(k)) ? 0xff : 0x00,
						     TTY_FRAME);
	}
	tty_flip_buffer_push(&to->port);
	tty_kref_put(tty);
}

static enum hrtimer_restart nm_tick(struct hrtimer *timer)
{
	struct nm_port *p = container_of(timer, struct nm_port, timer);
	u8 buf[64];
	unsigned int n, bytes;
	ktime_t now = ktime_get();
	bool more;
	struct tty_struct *tty;

	spin_lock(&p->lock);
	if (nm_stalled(p)) {
		/* Held: tx_stall's release starts the timer again. */
		p->credit = 0;
		p->running = false;
		spin_unlock(&p->lock);
		return HRTIMER_NORESTART;
	}
	p->credit += (u64)ktime_to_ns(ktime_sub(now, p->last)) * READ_ONCE(p->baud);
	p->last = now;
	/* 10 bits a byte; credit is in 1e-9 bit units. */
	bytes = min_t(u64, div_u64(p->credit, NSEC_PER_SEC) / 10, sizeof(buf));
	n = kfifo_out(&p->fifo, buf, bytes);
	p->credit -= (u64)n * 10 * NSEC_PER_SEC;
	nm_log(p, 'o', buf, n);
	more = !kfifo_is_empty(&p->fifo);
	if (!more) {
		p->credit = 0;
		p->running = false;
	}
	spin_unlock(&p->lock);

	if (n) {
		nm_wire_log(p, buf, n, READ_ONCE(p->baud), ktime_get_ns(), !more);
		nm_deliver(p, buf, n);
		if (!more && buf[n - 1] == 0x04 && READ_ONCE(p->baud) == 2400)
			WRITE_ONCE(ack_ns[p - nm_ports], ktime_get_ns());
		/* Room in the fifo: let the writer go on. */
		tty = tty_port_tty_get(&p->port);
		if (tty) {
			tty_wakeup(tty);
			tty_kref_put(tty);
		}
	}

	if (!more)
		return HRTIMER_NORESTART;
	hrtimer_forward_now(timer, ns_to_ktime(NM_TICK_NS));
	return HRTIMER_RESTART;
}

/* One DATA message: header, @payload bytes (@v in the first two), checksum. */
static unsigned int nm_gen_msg(u8 *msg, unsigned int payload, u16 v)
{
	unsigned int i;
	u8 sum = 0xff;

	memset(msg, 0, payload + 2);
	msg[0] = 0xc0 | ilog2(payload) << 3;	/* DATA, mode 0 */
	msg[1] = v & 0xff;
	if (payload > 1)
		msg[2] = v >> 8;
	for (i = 0; i <= payload; i++)
		sum ^= msg[i];
	msg[payload + 1] = sum;
	return payload + 2;
}

static enum hrtimer_restart nm_gen_tick(struct hrtimer *timer)
{
	struct nm_gen *g = container_of(timer, struct nm_gen, timer);
	u64 t0 = ktime_get_ns();
	u64 due = div64_u64(t0 - ktime_to_ns(g->start), g->period_ns);
	unsigned int burst, pair, k, len, room;
	u8 msg[2 + 32];

	burst = min_t(u64, due - g->due, GEN_MAX_BURST);
	g->due += burst;
	if (burst > 1)
		gen_late++;
	gen_max_burst = max(gen_max_burst, burst);
	for (pair = 0; burst && pair < pairs; pair++) {
		struct tty_port *port = &nm_ports[2 * pair].port;
		struct tty_struct *tty;

		if (!(g->lines & BIT(pair)))
			continue;
		tty = tty_port_tty_get(port);
		for (k = 0; k < burst; k++) {
			len = nm_gen_msg(msg, g->payload, g->seq[pair]++);
			gen_sent[pair]++;
			/* Nobody listening: the message is lost on the wire. */
			if (!tty)
				continue;
			room = tty_insert_flip_string(port, msg, len);
			if (room < len)
				gen_dropped[pair]++;
		}
		if (tty) {
			tty_flip_buffer_push(port);
			tty_kref_put(tty);
		}
	}
	gen_cpu_ns += ktime_get_ns() - t0;
	/* Due one period after the last one sent (at once when behind). */
	hrtimer_set_expires(timer, ktime_add_ns(g->start, (g->due + 1) * g->period_ns));
	return HRTIMER_RESTART;
}

static int nm_gen_set(const char *val, const struct kernel_param *kp)
{
	struct nm_gen *g = &nm_gen;
	unsigned int hz;
	int ret;

	ret = kstrtouint(val, 0, &hz);
	if (ret)
		return ret;
	if (hz > GEN_MAX_HZ)
		return -EINVAL;
	if (!nm_ports)		/* at load time: only "off" */
		return hz ? -EINVAL : 0;
	if (hz && (!gen_payload || gen_payload > 32 || !is_power_of_2(gen_payload)))
		return -EINVAL;
	/* Writes to a parameter are serialised (kernel_param_lock). */
	if (gen_hz) {
		WRITE_ONCE(g->running, false);
		hrtimer_cancel(&g->timer);
		gen_span_ns = ktime_get_ns() - ktime_to_ns(g->start);
	}
	gen_hz = hz;
	if (!hz)
		return 0;
	memset(gen_sent, 0, sizeof(gen_sent));
	memset(gen_dropped, 0, sizeof(gen_dropped));
	memset(gen_tx, 0, sizeof(gen_tx));
	memset(g->seq, 0, sizeof(g->seq));
	gen_span_ns = 0;
	gen_cpu_ns = 0;
	gen_late = 0;
	gen_max_burst = 0;
	g->lines = READ_ONCE(gen_lines) & (BIT(pairs) - 1);
	g->payload = READ_ONCE(gen_payload);
	g->period_ns = div_u64(NSEC_PER_SEC, hz);
	g->due = 0;
	g->start = ktime_get();
	hrtimer_start(&g->timer, ktime_add_ns(g->start, g->period_ns), HRTIMER_MODE_ABS_SOFT);
	/* nm_write() takes the host's bytes from now on. */
	smp_store_release(&g->running, true);
	return 0;
}

static const struct kernel_param_ops nm_gen_ops = {
	.set = nm_gen_set,
	.get = param_get_uint,
};
module_param_cb(gen_hz, &nm_gen_ops, &gen_hz, 0644);
MODULE_PARM_DESC(gen_hz, "generator: DATA messages a second per line, 0: stopped (default)");

/* Release the ports whose bits are cleared: their bytes go on, their writers wake. */
static int nm_stall_set(const char *val, const struct kernel_param *kp)
{
	unsigned int stall, released, i;
	struct tty_struct *tty;
	unsigned long flags;
	struct nm_port *p;
	int ret;

	ret = kstrtouint(val, 0, &stall);
	if (ret)
		return ret;
	/* Writes to a parameter are serialised (kernel_param_lock). */
	released = tx_stall & ~stall;
	WRITE_ONCE(tx_stall, stall);
	if (!nm_ports)		/* at load time */
		return 0;
	for (i = 0; i < 2 * pairs; i++) {
		if (!(released & BIT(i)))
			continue;
		p = &nm_ports[i];
		spin_lock_irqsave(&p->lock, flags);
		if (!kfifo_is_empty(&p->fifo) && !p->running) {
			p->running = true;
			p->last = ktime_get();
			p->credit = 0;
			hrtimer_start(&p->timer, ns_to_ktime(NM_TICK_NS), HRTIMER_MODE_REL_SOFT);
		}
		spin_unlock_irqrestore(&p->lock, flags);
		tty = tty_port_tty_get(&p->port);
		if (tty) {
			tty_wakeup(tty);
			tty_kref_put(tty);
		}
	}
	return 0;
}

static const struct kernel_param_ops nm_stall_ops = {
	.set = nm_stall_set,
	.get = param_get_uint,
};
module_param_cb(tx_stall, &nm_stall_ops, &tx_stall, 0644);
MODULE_PARM_DESC(tx_stall,
		 "bitmask of ports whose transmitters are held (write() takes nothing); clearing a bit releases");

static int nm_port_wire_show(struct seq_file *m, void *unused)
{
	struct nm_port *p = m->private;
	unsigned int i, n, first;
	struct nm_byte *copy;
	unsigned long flags;

	copy = kmalloc_array(NM_LOG_SIZE, sizeof(*copy), GFP_KERNEL);
	if (!copy)
		return -ENOMEM;
	spin_lock_irqsave(&p->lock, flags);
	n = min_t(unsigned int, p->logged, NM_LOG_SIZE);
	first = p->logged - n;
	for (i = 0; i < n; i++)
		copy[i] = p->log[(first + i) % NM_LOG_SIZE];
	spin_unlock_irqrestore(&p->lock, flags);
	for (i = 0; i < n; i++)
		seq_printf(m, "%llu %c %u %02x\n", copy[i].ns, copy[i].kind,
			   copy[i].baud, copy[i].byte);
	kfree(copy);
	return 0;
}

static int nm_port_wire_open(struct inode *inode, struct file *file)
{
	return single_open(file, nm_port_wire_show, inode->i_private);
}

/* Any write empties the log. */
static ssize_t nm_port_wire_write(struct file *file, const char __user *buf,
				  size_t count, loff_t *ppos)
{
	struct nm_port *p = file_inode(file)->i_private;
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->logged = 0;
	spin_unlock_irqrestore(&p->lock, flags);
	return count;
}

static const struct file_operations nm_port_wire_fops = {
	.owner		= THIS_MODULE,
	.open		= nm_port_wire_open,
	.read		= seq_read,
	.llseek		= seq_lseek,
	.write		= nm_port_wire_write,
	.release	= single_release,
};

static int nm_state_show(struct seq_file *m, void *unused)
{
	struct nm_port *p = m->private;
	struct tty_struct *tty = tty_port_tty_get(&p->port);
	int wakeup = -1;

	if (tty) {
		wakeup = test_bit(TTY_DO_WRITE_WAKEUP, &tty->flags);
		tty_kref_put(tty);
	}
	seq_printf(m, "stall %d\n", nm_stalled(p));
	seq_printf(m, "held %u\n", kfifo_len(&p->fifo));
	seq_printf(m, "write_wakeup %d\n", wakeup);
	return 0;
}
DEFINE_SHOW_ATTRIBUTE(nm_state);

static int nm_install(struct tty_driver *driver, struct tty_struct *tty)
{
	return tty_port_install(&nm_ports[tty->index].port, driver, tty);
}

static int nm_open(struct tty_struct *tty, struct file *filp)
{
	return tty_port_open(tty->port, tty, filp);
}

static void nm_close(struct tty_struct *tty, struct file *filp)
{
	tty_port_close(tty->port, tty, filp);
}

static LEGO_TTY_WRITE_RET nm_write(struct tty_struct *tty, const u8 *buf,
				   LEGO_TTY_COUNT count)
{
	struct nm_port *p = &nm_ports[tty->index];
	unsigned int pair = tty->index / 2;
	unsigned long flags;
	unsigned int n;

	if (READ_ONCE(fail_writes) & BIT(tty->index))
		return -EIO;
	if (nm_stalled(p))
		return 0;
	/* The host's side of a generated line: taken at once (see the top). */
	if (!(tty->index & 1) && smp_load_acquire(&nm_gen.running) &&
	    (READ_ONCE(nm_gen.lines) & BIT(pair))) {
		spin_lock_irqsave(&p->lock, flags);
		gen_tx[pair] += count;
		spin_unlock_irqrestore(&p->lock, flags);
		return count;
	}

	spin_lock_irqsave(&p->lock, flags);
	if (READ_ONCE(fifo_room))
		count = min_t(unsigned int, count,
			      READ_ONCE(fifo_room) - min(kfifo_len(&p->fifo),
							 READ_ONCE(fifo_room)));
	n = kfifo_in(&p->fifo, buf, count);
	if (n && !(tty->index & 1))
		nm_wire_log_write(tty->index, buf, n, READ_ONCE(p->baud));
	nm_log(p, 'w', buf, n);
	if (n && !p->running) {
		p->running = true;
		p->last = ktime_get();
		p->credit = 0;
		hrtimer_start(&p->timer, ns_to_ktime(NM_TICK_NS), HRTIMER_MODE_REL_SOFT);
	}
	spin_unlock_irqrestore(&p->lock, flags);
	return n;
}

static unsigned int nm_write_room(struct tty_struct *tty)
{
	struct nm_port *p = &nm_ports[tty->index];
	unsigned int room = READ_ONCE(fifo_room);

	if (nm_stalled(p))
		return 0;
	if (room)
		return room - min(kfifo_len(&p->fifo), room);
	return kfifo_avail(&p->fifo);
}

static unsigned int nm_chars_in_buffer(struct tty_struct *tty)
{
	return kfifo_len(&nm_ports[tty->index].fifo);
}

static void nm_set_termios(struct tty_struct *tty, const struct ktermios *old)
{
	WRITE_ONCE(nm_ports[tty->index].baud, tty_get_baud_rate(tty) ?: 9600);
}

static int nm_break_ctl(struct tty_struct *tty, int state)
{
	struct nm_port *peer = nm_ports[tty->index].peer;
	struct tty_struct *ptty;

	if (state == 0)
		return 0;
	ptty = tty_port_tty_get(&peer->port);
	if (ptty) {
		tty_insert_flip_char(&peer->port, 0, TTY_BREAK);
		tty_flip_buffer_push(&peer->port);
		tty_kref_put(ptty);
	}
	return 0;
}

static void nm_flush_buffer(struct tty_struct *tty)
{
	struct nm_port *p = &nm_ports[tty->index];
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	kfifo_reset(&p->fifo);
	spin_unlock_irqrestore(&p->lock, flags);
	tty_wakeup(tty);
}

static const struct tty_operations nm_ops = {
	.install	= nm_install,
	.open		= nm_open,
	.close		= nm_close,
	.write		= nm_write,
	.write_room	= nm_write_room,
	.chars_in_buffer = nm_chars_in_buffer,
	.set_termios	= nm_set_termios,
	.break_ctl	= nm_break_ctl,
	.flush_buffer	= nm_flush_buffer,
};

static const struct tty_port_operations nm_port_ops = { };

static int __init nm_init(void)
{
	struct nm_port *p;
	struct dentry *dir;
	unsigned int i, n;
	char name[16];
	int ret;

	if (!pairs || pairs > NM_MAX_PAIRS)
		return -EINVAL;
	n = 2 * pairs;
	nm_ports = kcalloc(n, sizeof(*nm_ports), GFP_KERNEL);
	if (!nm_ports)
		return -ENOMEM;
	for (i = 0; i < n; i++) {
		nm_ports[i].log = kcalloc(NM_LOG_SIZE, sizeof(*nm_ports[i].log), GFP_KERNEL);
		if (!nm_ports[i].log) {
			ret = -ENOMEM;
			goto free_ports;
		}
	}

	nm_driver = tty_alloc_driver(n, TTY_DRIVER_REAL_RAW | TTY_DRIVER_RESET_TERMIOS);
	if (IS_ERR(nm_driver)) {
		ret = PTR_ERR(nm_driver);
		goto free_ports;
	}
	nm_driver->driver_name = "lego_nullmodem";
	nm_driver->name = "ttyNM";
	nm_driver->type = TTY_DRIVER_TYPE_SERIAL;
	nm_driver->subtype = SERIAL_TYPE_NORMAL;
	nm_driver->init_termios = tty_std_termios;
	nm_driver->init_termios.c_cflag = B9600 | CS8 | CREAD | HUPCL | CLOCAL;
	nm_driver->init_termios.c_ispeed = 9600;
	nm_driver->init_termios.c_ospeed = 9600;
	tty_set_operations(nm_driver, &nm_ops);

	nm_debugfs = debugfs_create_dir("lego_nullmodem", NULL);
	for (i = 0; i < n; i++) {
		p = &nm_ports[i];
		tty_port_init(&p->port);
		p->port.ops = &nm_port_ops;
		p->peer = &nm_ports[i ^ 1];
		p->baud = 9600;
		spin_lock_init(&p->lock);
		INIT_KFIFO(p->fifo);
		hrtimer_setup(&p->timer, nm_tick, CLOCK_MONOTONIC, HRTIMER_MODE_REL_SOFT);
		p->garble = i + 1;
		tty_port_link_device(&p->port, nm_driver, i);
		snprintf(name, sizeof(name), "ttyNM%u", i);
		dir = debugfs_create_dir(name, nm_debugfs);
		debugfs_create_file("wire", 0600, dir, p, &nm_port_wire_fops);
		debugfs_create_file("state", 0400, dir, p, &nm_state_fops);
	}

	hrtimer_setup(&nm_gen.timer, nm_gen_tick, CLOCK_MONOTONIC, HRTIMER_MODE_ABS_SOFT);
	ret = tty_register_driver(nm_driver);
	if (ret)
		goto put_driver;
	ret = nm_probe_start();
	if (ret)
		goto unregister;
	/* Tests without debugfs only lose the wire logs. */
	debugfs_create_file("wire", 0600, nm_debugfs, NULL, &nm_wire_fops);
	/* The test VM has no CPU hotplug: the CPUs online now are all. */
	cpus_read_lock();
	on_each_cpu(nm_beat_start, NULL, 1);
	cpus_read_unlock();
	return 0;

unregister:
	tty_unregister_driver(nm_driver);
put_driver:
	debugfs_remove_recursive(nm_debugfs);
	for (i = 0; i < n; i++)
		tty_port_destroy(&nm_ports[i].port);
	tty_driver_kref_put(nm_driver);
free_ports:
	for (i = 0; i < n; i++)
		kfree(nm_ports[i].log);
	kfree(nm_ports);
	nm_ports = NULL;
	return ret;
}
module_init(nm_init);

static void __exit nm_exit(void)
{
	unsigned int i;

	debugfs_remove_recursive(nm_debugfs);
	nm_beat_stop();
	nm_probe_stop();
	hrtimer_cancel(&nm_gen.timer);
	tty_unregister_driver(nm_driver);
	for (i = 0; i < 2 * pairs; i++) {
		hrtimer_cancel(&nm_ports[i].timer);
		tty_port_destroy(&nm_ports[i].port);
		kfree(nm_ports[i].log);
	}
	tty_driver_kref_put(nm_driver);
	kfree(nm_ports);
}
module_exit(nm_exit);

MODULE_DESCRIPTION("Test-only null-modem tty pairs with baud-rate pacing");
MODULE_LICENSE("GPL");
