// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: its four sensor ports as I2C adapters.
 *
 * The brick's firmware runs the I2C ("low-speed") bus of a sensor port
 * itself; a host asks it for one transaction at a time with three direct
 * commands: LSWrite (the address, up to 15 bytes to write and how many to
 * read back), LSGetStatus (still running, failed, or done with so many
 * bytes read) and LSRead (those bytes). Each adapter here runs that
 * sequence for an i2c_transfer(), in the kernel, so that /dev/i2c-N,
 * i2c-tools and in-kernel I2C drivers work on the brick's ports.
 *
 * What a transfer may be is what one LSWrite can do: a write of up to 15
 * bytes, a read of up to 16, or a write then a read of the same device
 * (the brick makes the repeated start); the I2C core refuses the rest with
 * -EOPNOTSUPP (nxt_i2c_quirks). A read alone is sent as the brick runs
 * every read: the address written, then a repeated start and the read.
 *
 * The adapters are a view of the brick, like /dev/nxtN: they run their
 * telegrams through the transaction engine (nxt_transact()), whose first
 * come first served slot keeps the ports, and the brick's other users,
 * taking turns one telegram at a time. The I2C core holds an adapter's bus
 * lock across a transfer, so a port runs one transfer at a time. The
 * telegrams go out only when a transfer is asked for: the adapters send
 * nothing when they are added.
 *
 * Locking: each port's state (&nxt_i2c_port.mode_set and its transaction)
 * belongs to the transfer that holds the adapter's bus lock. @nxt_i2c.lock
 * (a mutex, taken inside a bus lock, before the brick's @open_lock) guards
 * the brick's open count that the adapters share (@busy, @open), so that a
 * brick read through its ports stays open between transfers and closes
 * NXT_I2C_IDLE_MS after the last.
 */
#include <linux/delay.h>
#include <linux/device.h>
#include <linux/i2c.h>
#include <linux/jiffies.h>
#include <linux/mutex.h>
#include <linux/slab.h>
#include <linux/workqueue.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_views.h"

/* The brick stays open this long after the ports' last transfer. */
#define NXT_I2C_IDLE_MS		1000
/* Reply timeout of each telegram of a transfer. */
#define NXT_I2C_REPLY_MS	1000
/* Between two tries of a port that is not ready (nxt-python waits 10 ms). */
#define NXT_I2C_RETRY_US	10000
/* Between two LSGetStatus of a transaction that runs. */
#define NXT_I2C_POLL_US		2000
/*
 * One byte on the port's bus, which the firmware clocks at about 9600 Hz:
 * the first LSGetStatus waits for the bytes of the transaction.
 */
#define NXT_I2C_BYTE_US		1000

struct nxt_i2c;

/**
 * struct nxt_i2c_port - one sensor port's adapter
 * @adap: the adapter
 * @i2c: the brick's adapters
 * @port: the port, 0 to 3 (the brick's label is one more)
 * @added: @adap was added
 * @mode_set: this adapter set the port to low-speed mode
 * @xfer: the transaction of the telegram being run
 */
struct nxt_i2c_port {
	struct i2c_adapter adap;
	struct nxt_i2c *i2c;
	u8 port;
	bool added;
	bool mode_set;
	struct nxt_xfer xfer;
};

/**
 * struct nxt_i2c - a brick's adapters
 * @brick: the brick
 * @lock: see the comment at the top of this file
 * @busy: transfers running on the ports (@lock)
 * @open: the adapters hold the brick open (@lock)
 * @close_work: closes the brick once the ports are idle
 * @ports: the adapters, one per input port
 */
struct nxt_i2c {
	struct nxt_brick *brick;
	struct mutex lock;	/* see the comment at the top */
	unsigned int busy;
	bool open;
	struct delayed_work close_work;
	struct nxt_i2c_port ports[NXT_INPUT_PORTS];
};

static int nxt_i2c_get(struct nxt_i2c *i2c)
{
	int ret = 0;

	mutex_lock(&i2c->lock);
	if (!i2c->open) {
		ret = nxt_brick_open(i2c->brick);
		i2c->open = !ret;
	}
	if (!ret)
		i2c->busy++;
	mutex_unlock(&i2c->lock);
	return ret == -ERESTARTSYS ? -EINTR : ret;
}

static void nxt_i2c_put(struct nxt_i2c *i2c)
{
	mutex_lock(&i2c->lock);
	if (!--i2c->busy)
		mod_delayed_work(system_dfl_wq, &i2c->close_work,
				 msecs_to_jiffies(NXT_I2C_IDLE_MS));
	mutex_unlock(&i2c->lock);
}

static void nxt_i2c_close_work(struct work_struct *work)
{
	struct nxt_i2c *i2c = container_of(to_delayed_work(work), struct nxt_i2c,
					   close_work);

	mutex_lock(&i2c->lock);
	if (i2c->open && !i2c->busy) {
		nxt_brick_close(i2c->brick);
		i2c->open = false;
	}
	mutex_unlock(&i2c->lock);
}

/*
 * Runs one telegram of a port. Return: the reply's status byte, or a
 * negative errno of the engine or for a reply that does not answer it.
 */
static int nxt_i2c_cmd(struct nxt_i2c_port *p, const u8 *tg, unsigned int len)
{
	struct nxt_xfer *x = &p->xfer;
	int ret;

	ret = nxt_transact(p->i2c->brick, x, tg, len, NXT_I2C_REPLY_MS, false);
	if (ret)
		return ret == -ERESTARTSYS ? -EINTR : ret;
	return nxt_ls_status(x->reply, x->reply_len, tg[1]);
}

/* Waits @us before the port's next telegram; -ETIMEDOUT past @deadline. */
static int nxt_i2c_wait(unsigned long deadline, unsigned int us)
{
	if (time_after(jiffies + usecs_to_jiffies(us), deadline))
		return -ETIMEDOUT;
	usleep_range(us, us + us / 4);
	return 0;
}

/*
 * Starts the port's I2C transaction: sets the port to low-speed mode if
 * this adapter has not, then LSWrite until the port takes it. A port that
 * is not ready may be settling after SetInputMode, or set to another mode
 * by another user of the brick: the mode is set again once per transfer.
 */
static int nxt_i2c_start(struct nxt_i2c_port *p, const u8 *tg, unsigned int len,
			 unsigned long deadline)
{
	bool mode_sent = false;
	u8 mode_tg[5];
	int ret;

	for (;;) {
		if (!p->mode_set) {
			ret = nxt_i2c_cmd(p, mode_tg, nxt_ls_mode_tg(mode_tg, p->port));
			if (ret > 0)
				ret = nxt_ls_errno(ret);
			if (ret)
				return ret;
			p->mode_set = true;
			mode_sent = true;
		}
		ret = nxt_i2c_cmd(p, tg, len);
		if (ret > 0)
			ret = nxt_ls_errno(ret);
		if (ret != -EAGAIN && ret != -EINPROGRESS)
			return ret;
		if (!mode_sent)
			p->mode_set = false;
		ret = nxt_i2c_wait(deadline, NXT_I2C_RETRY_US);
		if (ret)
			return ret;
	}
}

/*
 * Runs one LSWrite on @p and reads what it read into @rbuf. Return: 0 or
 * a negative errno.
 */
static int nxt_i2c_run(struct nxt_i2c_port *p, u16 addr, const u8 *wbuf,
		       u16 wlen, u8 *rbuf, u16 rlen)
{
	unsigned long deadline = jiffies + p->adap.timeout;
	struct nxt_xfer *x = &p->xfer;
	unsigned int us;
	u8 tg[NXT_LS_TG_MAX];
	int len, ret;

	len = nxt_ls_write_tg(tg, p->port, addr, wbuf, wlen, rlen);
	if (len < 0)
		return len;
	ret = nxt_i2c_start(p, tg, len, deadline);
	if (ret)
		return ret;

	/* The address, the bytes written, and the read's address and bytes. */
	us = NXT_I2C_BYTE_US * (1 + wlen + (rlen ? 1 + rlen : 0));
	for (;;) {
		ret = nxt_i2c_wait(deadline, us);
		if (ret)
			return ret;
		ret = nxt_i2c_cmd(p, tg, nxt_ls_port_tg(tg, NXT_LS_GET_STATUS, p->port));
		if (ret < 0)
			return ret;
		ret = nxt_ls_ready(x->reply, x->reply_len);
		if (ret != -EINPROGRESS)
			break;
		us = NXT_I2C_POLL_US;
	}
	if (ret == -EAGAIN)
		p->mode_set = false;	/* the port is no longer low-speed */
	if (ret < 0)
		return ret;
	if (!rlen)
		return 0;

	ret = nxt_i2c_cmd(p, tg, nxt_ls_port_tg(tg, NXT_LS_READ, p->port));
	if (ret < 0)
		return ret;
	return nxt_ls_read_data(x->reply, x->reply_len, rbuf, rlen);
}

static int nxt_i2c_xfer(struct i2c_adapter *adap, struct i2c_msg *msgs, int num)
{
	struct nxt_i2c_port *p = i2c_get_adapdata(adap);
	struct i2c_msg *w = NULL, *r = NULL;
	int i, ret;

	/* The I2C core has checked the shapes (nxt_i2c_quirks); not the flags. */
	for (i = 0; i < num; i++) {
		if (msgs[i].flags & ~(I2C_M_RD | I2C_M_DMA_SAFE)) {
			dev_err_ratelimited(&adap->dev, "cannot send I2C flags 0x%x\n",
					    msgs[i].flags);
			return -EOPNOTSUPP;
		}
		if (msgs[i].flags & I2C_M_RD)
			r = &msgs[i];
		else
			w = &msgs[i];
	}
	if (num < 1 || num > 2 || (num == 2 && (!w || !r || w->addr != r->addr)))
		return -EOPNOTSUPP;

	ret = nxt_i2c_get(p->i2c);
	if (ret)
		return ret;
	ret = nxt_i2c_run(p, (w ?: r)->addr, w ? w->buf : NULL, w ? w->len : 0,
			  r ? r->buf : NULL, r ? r->len : 0);
	nxt_i2c_put(p->i2c);
	if (ret && ret != -ENXIO)
		dev_dbg(&adap->dev, "transfer to 0x%02x: %d\n", (w ?: r)->addr, ret);
	return ret ?: num;
}

static u32 nxt_i2c_functionality(struct i2c_adapter *adap)
{
	/*
	 * Plain I2C within nxt_i2c_quirks, and the SMBus transactions that
	 * fit in one LSWrite. Not block reads (their length comes from the
	 * device), not block writes longer than the brick takes, no PEC and
	 * no 10-bit addresses.
	 */
	return I2C_FUNC_I2C | I2C_FUNC_SMBUS_QUICK | I2C_FUNC_SMBUS_BYTE |
	       I2C_FUNC_SMBUS_BYTE_DATA | I2C_FUNC_SMBUS_WORD_DATA |
	       I2C_FUNC_SMBUS_PROC_CALL;
}

static const struct i2c_algorithm nxt_i2c_algo = {
	.LEGO_I2C_XFER = nxt_i2c_xfer,
	.functionality = nxt_i2c_functionality,
};

static const struct i2c_adapter_quirks nxt_i2c_quirks = {
	.flags			= I2C_AQ_COMB_WRITE_THEN_READ | I2C_AQ_NO_ZERO_LEN_READ,
	.max_write_len		= NXT_LS_WRITE_MAX,
	.max_read_len		= NXT_LS_MAX,
	.max_comb_1st_msg_len	= NXT_LS_WRITE_MAX,
	.max_comb_2nd_msg_len	= NXT_LS_MAX,
};

/**
 * nxt_i2c_add() - give a brick an I2C adapter per sensor port
 * @b: the brick, with its node (nxt_node_add())
 *
 * The adapters are children of the brick's node, named "NXT <serial> port
 * <1..4>" (the brick's serial number, or the transport's name of the brick
 * when it has none). A brick whose adapters cannot be added works without
 * them: this logs why.
 */
void nxt_i2c_add(struct nxt_brick *b)
{
	struct nxt_i2c *i2c;
	unsigned int i;
	int ret;

	i2c = kzalloc_obj(*i2c, GFP_KERNEL);
	if (!i2c)
		return;
	i2c->brick = b;
	mutex_init(&i2c->lock);
	INIT_DELAYED_WORK(&i2c->close_work, nxt_i2c_close_work);
	b->i2c = i2c;

	for (i = 0; i < NXT_INPUT_PORTS; i++) {
		struct nxt_i2c_port *p = &i2c->ports[i];

		p->i2c = i2c;
		p->port = i;
		p->adap.owner = THIS_MODULE;
		p->adap.algo = &nxt_i2c_algo;
		p->adap.quirks = &nxt_i2c_quirks;
		p->adap.dev.parent = b->node;
		snprintf(p->adap.name, sizeof(p->adap.name), "NXT %s port %u",
			 b->serial[0] ? b->serial : b->name, i + 1);
		i2c_set_adapdata(&p->adap, p);
		ret = i2c_add_adapter(&p->adap);
		if (ret) {
			dev_warn(b->node, "no I2C adapter for port %u: %d\n", i + 1, ret);
			continue;
		}
		p->added = true;
	}
}

/**
 * nxt_i2c_remove() - take a brick's adapters away
 * @b: the brick
 *
 * Waits for the transfers in progress (which fail once the brick is gone)
 * and, as for every I2C adapter, for the files that have its /dev/i2c-N
 * open to be closed.
 */
void nxt_i2c_remove(struct nxt_brick *b)
{
	struct nxt_i2c *i2c = b->i2c;
	unsigned int i;

	if (!i2c)
		return;
	for (i = 0; i < NXT_INPUT_PORTS; i++)
		if (i2c->ports[i].added)
			i2c_del_adapter(&i2c->ports[i].adap);
	cancel_delayed_work_sync(&i2c->close_work);
	if (i2c->open)
		nxt_brick_close(b);
	mutex_destroy(&i2c->lock);
	b->i2c = NULL;
	kfree(i2c);
}
