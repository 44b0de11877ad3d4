// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS NXT brick: the char device /dev/nxtN.
 *
 * write() sends one telegram; read() returns the reply to that same open
 * file's last telegram, so that two processes never see each other's
 * replies. NXT_IOC_TRANSACT does both in one call. The brick's status byte
 * is part of the reply, for userspace to read: an errno here is always a
 * failure of the telegram or of the transport. The userspace interface is
 * in include/uapi/linux/lego_nxt.h and Documentation/lego/nxt-usb.rst.
 *
 * Each open file has one transaction of its own (struct nxt_file), and
 * @lock makes its operations take turns: a write() waits for the reply to
 * the file's previous telegram to arrive (and drops it if it was not read),
 * so the transaction is never reused while it is in flight.
 *
 * The nodes are the driver's own, whatever the brick's link: a char device
 * region of NXT_MINORS minors and the class "lego-nxt", whose devices carry
 * the sysfs attributes (nxt_sysfs.c). A transport adds a node for each
 * brick (nxt_node_add()) under its own device and removes it first thing
 * when the brick goes (nxt_node_remove()), which waits for an open() in
 * progress: an open() finds its brick in @nxt_nodes under @nxt_nodes_rwsem.
 */
#include <linux/cdev.h>
#include <linux/device.h>
#include <linux/fs.h>
#include <linux/module.h>
#include <linux/poll.h>
#include <linux/rwsem.h>
#include <linux/slab.h>
#include <linux/uaccess.h>
#include <linux/xarray.h>

#include "lego_compat.h"
#include "nxt_core.h"
#include "nxt_proto.h"
#include "nxt_views.h"

/* Bricks at once: /dev/nxt0 to /dev/nxt255. */
#define NXT_MINORS	256

static dev_t nxt_devt;
static struct cdev nxt_cdev;
/* Minor -> brick, for open(); written under @nxt_nodes_rwsem held for writing. */
static DEFINE_XARRAY_ALLOC(nxt_nodes);
static DECLARE_RWSEM(nxt_nodes_rwsem);

static LEGO_CLASS_CONST struct class nxt_class = {
	.name		= "lego-nxt",
	.dev_groups	= nxt_groups,
};

/**
 * struct nxt_file - an open /dev/nxtN
 * @brick: the brick, referenced while the file is open
 * @lock: one operation of this file at a time; protects the members below
 * @timeout_ms: reply timeout of this file's transactions; written with
 *	WRITE_ONCE() under @lock, read under @lock or with READ_ONCE()
 *	(NXT_IOC_GET_TIMEOUT)
 * @pending: @xfer was started and its result has not been read; written
 *	with WRITE_ONCE() under @lock, read under @lock or with READ_ONCE()
 *	(poll())
 * @xfer: this file's transaction
 */
struct nxt_file {
	struct nxt_brick *brick;
	struct mutex lock;	/* see above */
	unsigned int timeout_ms;
	bool pending;
	struct nxt_xfer xfer;
};

static int nxt_open(struct inode *inode, struct file *file)
{
	struct nxt_brick *b;
	struct nxt_file *f;
	int ret;

	f = kzalloc_obj(*f, GFP_KERNEL);
	if (!f)
		return -ENOMEM;
	mutex_init(&f->lock);
	f->timeout_ms = NXT_TIMEOUT_DEFAULT_MS;

	/* nxt_node_remove() waits for this: the transport is still there. */
	if (down_read_killable(&nxt_nodes_rwsem)) {
		kfree(f);
		return -ERESTARTSYS;
	}
	b = xa_load(&nxt_nodes, iminor(inode));
	if (!b) {
		ret = -ENODEV;
		goto out;
	}
	/*
	 * The file holds its transport's module as well as the brick: the
	 * brick's last put, and the close of its link, run the transport's
	 * code, which must not be unloaded before then.
	 */
	if (!try_module_get(b->ops->owner)) {
		ret = -ENODEV;
		goto out;
	}
	/* Start collecting replies; stale ones are drained. */
	ret = nxt_brick_open(b);
	if (ret) {
		module_put(b->ops->owner);
		goto out;
	}
	nxt_brick_get(b);
	f->brick = b;
out:
	up_read(&nxt_nodes_rwsem);
	if (ret) {
		kfree(f);
		return ret;
	}
	file->private_data = f;
	return stream_open(inode, file);
}

static int nxt_release(struct inode *inode, struct file *file)
{
	struct nxt_file *f = file->private_data;
	struct module *owner = f->brick->ops->owner;

	mutex_lock(&f->lock);
	if (f->pending)
		nxt_xfer_cancel(f->brick, &f->xfer);
	mutex_unlock(&f->lock);
	nxt_brick_close(f->brick);
	nxt_brick_put(f->brick);
	kfree(f);
	module_put(owner);
	return 0;
}

static int nxt_file_lock(struct nxt_file *f, bool nonblock)
{
	if (nonblock)
		return mutex_trylock(&f->lock) ? 0 : -EAGAIN;
	return mutex_lock_interruptible(&f->lock) ? -ERESTARTSYS : 0;
}

/* Lets the file's previous transaction finish, and forgets it. @lock held. */
static int nxt_file_settle(struct nxt_file *f, bool nonblock)
{
	int ret;

	if (!f->pending)
		return 0;
	ret = nxt_xfer_wait(f->brick, &f->xfer, nonblock);
	if (ret == -EAGAIN || ret == -ERESTARTSYS)
		return ret;
	WRITE_ONCE(f->pending, false);
	return 0;
}

static ssize_t nxt_write(struct file *file, const char __user *buf,
			 size_t count, loff_t *ppos)
{
	struct nxt_file *f = file->private_data;
	bool nonblock = file->f_flags & O_NONBLOCK;
	u8 tg[NXT_TELEGRAM_MAX];
	int ret;

	/* The firmware takes each packet as one command: never split one. */
	if (count > NXT_TELEGRAM_MAX)
		return -EMSGSIZE;
	if (count < NXT_TELEGRAM_MIN)
		return -EINVAL;
	if (copy_from_user(tg, buf, count))
		return -EFAULT;
	ret = nxt_telegram_check(tg, count);
	if (ret < 0)
		return ret;

	ret = nxt_file_lock(f, nonblock);
	if (ret)
		return ret;
	ret = nxt_file_settle(f, nonblock);
	if (ret)
		goto out;
	ret = nxt_xfer_start(f->brick, &f->xfer, tg, count, f->timeout_ms, nonblock);
	if (ret)
		goto out;
	WRITE_ONCE(f->pending, f->xfer.want_reply);
	ret = count;
out:
	mutex_unlock(&f->lock);
	return ret;
}

static ssize_t nxt_read(struct file *file, char __user *buf, size_t count,
			loff_t *ppos)
{
	struct nxt_file *f = file->private_data;
	bool nonblock = file->f_flags & O_NONBLOCK;
	int ret;

	ret = nxt_file_lock(f, nonblock);
	if (ret)
		return ret;
	if (!f->pending) {
		/* Nothing was asked that has a reply. */
		ret = nxt_gone(f->brick) ? -ENODEV : -ENODATA;
		goto out;
	}
	ret = nxt_xfer_wait(f->brick, &f->xfer, nonblock);
	if (ret == -EAGAIN || ret == -ERESTARTSYS)
		goto out;
	if (ret) {
		WRITE_ONCE(f->pending, false);
		goto out;
	}
	if (count < f->xfer.reply_len) {
		/* Kept for a read with a buffer big enough. */
		ret = -EMSGSIZE;
		goto out;
	}
	WRITE_ONCE(f->pending, false);
	ret = f->xfer.reply_len;
	if (copy_to_user(buf, f->xfer.reply, f->xfer.reply_len))
		ret = -EFAULT;
out:
	mutex_unlock(&f->lock);
	return ret;
}

static __poll_t nxt_poll(struct file *file, poll_table *wait)
{
	struct nxt_file *f = file->private_data;
	struct nxt_brick *b = f->brick;
	__poll_t mask = 0;
	bool pending, done;

	poll_wait(file, &b->wait, wait);
	if (nxt_gone(b))
		return EPOLLERR | EPOLLHUP;

	/*
	 * Without @lock: a transaction in @xfer only moves from pending to
	 * done, and its status is read under the brick's lock, under which
	 * it is always written (even when the transaction is set up).
	 */
	pending = READ_ONCE(f->pending);
	done = nxt_xfer_done(b, &f->xfer);
	if (pending && done)
		mask |= EPOLLIN | EPOLLRDNORM;
	if ((!pending || done) && nxt_slot_free(b))
		mask |= EPOLLOUT | EPOLLWRNORM;
	return mask;
}

/*
 * A telegram and its reply, for the ioctls. @lock held. -ERESTARTSYS only
 * when nothing was sent, so that the call can be restarted; -EINTR once it
 * was.
 */
static int nxt_file_transact(struct nxt_file *f, const u8 *tg, size_t len,
			     bool nonblock)
{
	int ret;

	ret = nxt_file_settle(f, nonblock);
	if (ret)
		return ret;
	return nxt_transact(f->brick, &f->xfer, tg, len, f->timeout_ms, nonblock);
}

static long nxt_ioctl_transact(struct nxt_file *f, void __user *argp,
			       bool nonblock)
{
	struct nxt_transaction t;
	int ret;

	if (copy_from_user(&t, argp, sizeof(t)))
		return -EFAULT;
	if (t.length > NXT_TELEGRAM_MAX)
		return -EMSGSIZE;
	ret = nxt_telegram_check(t.telegram, t.length);
	if (ret < 0)
		return ret;

	ret = nxt_file_lock(f, nonblock);
	if (ret)
		return ret;
	ret = nxt_file_transact(f, t.telegram, t.length, nonblock);
	if (!ret) {
		/* Zero past the reply's length. */
		memcpy(t.reply, f->xfer.reply, sizeof(t.reply));
		t.reply_length = f->xfer.reply_len;
	}
	mutex_unlock(&f->lock);
	if (ret)
		return ret;
	return copy_to_user(argp, &t, sizeof(t)) ? -EFAULT : 0;
}

/*
 * NXT_IOC_TRANSACT needs a file opened for writing, as write() does: a
 * read-only file must not make the brick act (erase its flash, start its
 * firmware update, drive its motors). The timeout ioctls send nothing.
 */
static bool nxt_may_send(struct file *file, unsigned int cmd)
{
	struct nxt_file *f = file->private_data;

	if (file->f_mode & FMODE_WRITE)
		return true;
	dev_dbg_ratelimited(f->brick->dev,
			    "ioctl 0x%08x needs a file opened for writing\n", cmd);
	return false;
}

static long nxt_ioctl(struct file *file, unsigned int cmd, unsigned long arg)
{
	struct nxt_file *f = file->private_data;
	bool nonblock = file->f_flags & O_NONBLOCK;
	void __user *argp = (void __user *)arg;
	u32 ms;

	switch (cmd) {
	case NXT_IOC_TRANSACT:
		if (!nxt_may_send(file, cmd))
			return -EBADF;
		return nxt_ioctl_transact(f, argp, nonblock);
	case NXT_IOC_SET_TIMEOUT:
		if (get_user(ms, (u32 __user *)argp))
			return -EFAULT;
		if (ms < 1 || ms > NXT_TIMEOUT_MAX_MS)
			return -EINVAL;
		if (mutex_lock_interruptible(&f->lock))
			return -ERESTARTSYS;
		WRITE_ONCE(f->timeout_ms, ms);
		mutex_unlock(&f->lock);
		return 0;
	case NXT_IOC_GET_TIMEOUT:
		return put_user(READ_ONCE(f->timeout_ms), (u32 __user *)argp);
	default:
		return -ENOTTY;
	}
}

static const struct file_operations nxt_fops = {
	.owner		= THIS_MODULE,
	.open		= nxt_open,
	.release	= nxt_release,
	.read		= nxt_read,
	.write		= nxt_write,
	.poll		= nxt_poll,
	.unlocked_ioctl	= nxt_ioctl,
	/* Every argument has the same layout on 32 and 64 bits. */
	.compat_ioctl	= compat_ptr_ioctl,
};

/**
 * nxt_node_add() - give a brick its /dev/nxtN
 * @b: the brick
 * @parent: the transport's device, the node's parent in sysfs
 *
 * Return: 0, -%EBUSY when NXT_MINORS bricks have a node, or another
 * negative errno.
 */
int nxt_node_add(struct nxt_brick *b, struct device *parent)
{
	struct device *dev;
	u32 minor;
	int ret;

	down_write(&nxt_nodes_rwsem);
	ret = xa_alloc(&nxt_nodes, &minor, b, XA_LIMIT(0, NXT_MINORS - 1), GFP_KERNEL);
	up_write(&nxt_nodes_rwsem);
	if (ret)
		return ret;

	dev = device_create(&nxt_class, parent, MKDEV(MAJOR(nxt_devt), minor), b,
			    "nxt%d", minor);
	if (IS_ERR(dev)) {
		down_write(&nxt_nodes_rwsem);
		xa_erase(&nxt_nodes, minor);
		up_write(&nxt_nodes_rwsem);
		return PTR_ERR(dev);
	}
	b->minor = minor;
	b->node = dev;
	/* Its sensor ports' I2C adapters, children of the node. */
	nxt_i2c_add(b);
	return 0;
}
EXPORT_SYMBOL_GPL(nxt_node_add);

/**
 * nxt_node_remove() - take a brick's /dev/nxtN away
 * @b: the brick, whose node nxt_node_add() added
 *
 * No open() finds the brick once this returns, and none is running; the
 * files already open keep the brick until they are closed. A sysfs read
 * in progress is waited for, and so are the sensor ports' I2C transfers
 * and, as for any I2C adapter, the files that hold a port's /dev/i2c-N
 * open (nxt_i2c_remove()).
 */
void nxt_node_remove(struct nxt_brick *b)
{
	nxt_i2c_remove(b);
	/*
	 * No open() finds the brick from here on, but its minor stays taken
	 * until its device is gone (NULL stored in an allocating XArray
	 * reserves the entry): a brick plugged meanwhile would else get the
	 * minor while "nxtN" is still in sysfs, and fail to probe.
	 */
	down_write(&nxt_nodes_rwsem);
	xa_store(&nxt_nodes, b->minor, NULL, GFP_KERNEL);
	up_write(&nxt_nodes_rwsem);
	device_destroy(&nxt_class, MKDEV(MAJOR(nxt_devt), b->minor));
	b->node = NULL;
	xa_erase(&nxt_nodes, b->minor);
}
EXPORT_SYMBOL_GPL(nxt_node_remove);

/**
 * nxt_cdev_init() - register the char device region and the class
 *
 * Return: 0 or a negative errno.
 */
int nxt_cdev_init(void)
{
	int ret;

	ret = alloc_chrdev_region(&nxt_devt, 0, NXT_MINORS, "nxt");
	if (ret)
		return ret;
	cdev_init(&nxt_cdev, &nxt_fops);
	nxt_cdev.owner = THIS_MODULE;
	ret = cdev_add(&nxt_cdev, nxt_devt, NXT_MINORS);
	if (ret)
		goto err_region;
	ret = class_register(&nxt_class);
	if (ret)
		goto err_cdev;
	return 0;

err_cdev:
	cdev_del(&nxt_cdev);
err_region:
	unregister_chrdev_region(nxt_devt, NXT_MINORS);
	return ret;
}

/** nxt_cdev_exit() - undo nxt_cdev_init(), once every node is removed */
void nxt_cdev_exit(void)
{
	class_unregister(&nxt_class);
	cdev_del(&nxt_cdev);
	unregister_chrdev_region(nxt_devt, NXT_MINORS);
	xa_destroy(&nxt_nodes);
}
