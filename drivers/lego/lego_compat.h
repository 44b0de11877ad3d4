/* SPDX-License-Identifier: GPL-2.0 */
/*
 * Differences between the kernels these drivers build against (6.1 LTS up to
 * current mainline), kept in one place. The LEGO_HAVE_* flags are set by the
 * top-level Kbuild, which compiles each of drivers/lego/probes/ against the
 * target kernel's headers. The code uses the newest kernel's interfaces;
 * what older kernels lack is mapped here onto what they have.
 */
#ifndef _LEGO_COMPAT_H
#define _LEGO_COMPAT_H

#include <linux/module.h>
#include <kunit/visibility.h>

/* 6.12: the unaligned access helpers moved to <linux/unaligned.h>. */
#ifdef LEGO_HAVE_LINUX_UNALIGNED
#include <linux/unaligned.h>
#else
#include <asm/unaligned.h>
#endif

/* 6.13: symbol namespaces became string literals. */
#ifdef LEGO_HAVE_IDENT_NS
#define LEGO_IMPORT_KUNIT_NS() MODULE_IMPORT_NS(EXPORTED_FOR_KUNIT_TESTING)
#else
#define LEGO_IMPORT_KUNIT_NS() MODULE_IMPORT_NS("EXPORTED_FOR_KUNIT_TESTING")
#endif

/* Types of the flag buffer and of the count in tty_ldisc_ops::receive_buf. */
#ifdef LEGO_HAVE_TTY_RX_SIZE_T
#define LEGO_TTY_FLAG	u8
#define LEGO_TTY_COUNT	size_t
#else
#define LEGO_TTY_FLAG	char
#define LEGO_TTY_COUNT	int
#endif

/* Return type of tty_operations::write (its count is LEGO_TTY_COUNT). */
#ifdef LEGO_HAVE_TTY_WRITE_SSIZE_T
#define LEGO_TTY_WRITE_RET	ssize_t
#else
#define LEGO_TTY_WRITE_RET	int
#endif

/* The device argument of struct class's dev_uevent. */
#ifdef LEGO_HAVE_CONST_UEVENT
#define LEGO_UEVENT_CONST const
#else
#define LEGO_UEVENT_CONST
#endif

/*
 * 6.16: bin_attribute callbacks take a const struct bin_attribute, and an
 * attribute_group's bin_attrs lists const ones. LEGO_BIN_ATTR is the type
 * the callbacks take ("LEGO_BIN_ATTR *attr"); a group's list is
 * "static LEGO_BIN_ATTR *LEGO_BIN_ATTR_CONST x[]". (checkpatch's
 * CONST_STRUCT is ignored for this file: the older kernels' type is not
 * const.)
 */
#ifdef LEGO_HAVE_CONST_BIN_ATTR
#define LEGO_BIN_ATTR		const struct bin_attribute
#define LEGO_BIN_ATTR_CONST	const
#else
#define LEGO_BIN_ATTR		struct bin_attribute
#define LEGO_BIN_ATTR_CONST
#endif

/*
 * kzalloc_obj(), in the newest kernels: allocate the size of an object's
 * type, typed. The code always passes the GFP flags.
 */
#ifndef LEGO_HAVE_KZALLOC_OBJ
#define kzalloc_obj(obj, gfp)	kzalloc(sizeof(obj), gfp)
#endif

/*
 * An attribute_group's list of const attributes, attrs_const, where the
 * kernel has it (attrs is to go): declare the list
 * "static LEGO_ATTR_CONST struct attribute *LEGO_ATTR_CONST x[]" and set
 * it as ".LEGO_GROUP_ATTRS = x".
 */
#ifdef LEGO_HAVE_ATTRS_CONST
#define LEGO_ATTR_CONST		const
#define LEGO_GROUP_ATTRS	attrs_const
#else
#define LEGO_ATTR_CONST
#define LEGO_GROUP_ATTRS	attrs
#endif

/* 6.4: class_register() takes a const struct class. */
#ifdef LEGO_HAVE_CONST_CLASS
#define LEGO_CLASS_CONST const
#else
#define LEGO_CLASS_CONST
#endif

#ifdef __KERNEL__
/*
 * system_percpu_wq and system_dfl_wq are the new names of system_wq and
 * system_unbound_wq, whose names are to be removed.
 */
#ifndef LEGO_HAVE_SYSTEM_DFL_WQ
#include <linux/workqueue.h>

#define system_percpu_wq	system_wq
#define system_dfl_wq		system_unbound_wq
#endif

/*
 * 6.16: iio_push_to_buffers_with_ts() takes the size of the scan (and
 * checks it); iio_push_to_buffers_with_timestamp() is deprecated.
 */
#ifndef LEGO_HAVE_IIO_PUSH_WITH_TS
#define iio_push_to_buffers_with_ts(indio_dev, data, len, ts)	\
	({ (void)(len); iio_push_to_buffers_with_timestamp(indio_dev, data, ts); })
#endif

/*
 * 6.8: struct i2c_algorithm's master_xfer became xfer; the old name is
 * deprecated. An algorithm names its member LEGO_I2C_XFER.
 */
#ifdef LEGO_HAVE_I2C_ALGO_XFER
#define LEGO_I2C_XFER	xfer
#else
#define LEGO_I2C_XFER	master_xfer
#endif

/*
 * 6.12: iio_for_each_active_channel(); the mask's length became private.
 * As the kernel has it (checkpatch's MACRO_ARG_REUSE is ignored for this
 * file, whose shims keep the shape of the kernel's own macros).
 */
#ifndef LEGO_HAVE_IIO_ACTIVE_CHANNELS
#define iio_for_each_active_channel(indio_dev, chan)			\
	for_each_set_bit((chan), (indio_dev)->active_scan_mask,	\
			 (indio_dev)->masklength)
#endif
#endif /* __KERNEL__ */

/*
 * 6.13: hrtimer_setup() initialises a timer and sets its callback. Kernel
 * builds only: the userspace builds of the protocol cores (fuzzing,
 * benchmarks) include this file too, and have no timers.
 */
#if defined(__KERNEL__) && !defined(LEGO_HAVE_HRTIMER_SETUP)
#include <linux/hrtimer.h>

static inline void
lego_hrtimer_setup(struct hrtimer *timer,
		   enum hrtimer_restart (*function)(struct hrtimer *),
		   clockid_t clock_id, enum hrtimer_mode mode)
{
	hrtimer_init(timer, clock_id, mode);
	timer->function = function;
}

#define hrtimer_setup lego_hrtimer_setup
#endif

/*
 * Timers, in kernel builds only (the userspace builds have none): the code
 * uses the names of current kernels, mapped here onto the older ones.
 * 6.2 (and 6.1.y): del_timer() and del_timer_sync() became timer_delete()
 * and timer_delete_sync(); 6.16: from_timer() became timer_container_of().
 */
#ifdef __KERNEL__
#include <linux/timer.h>

#ifndef LEGO_HAVE_TIMER_DELETE
#define timer_delete(timer)		del_timer(timer)
#define timer_delete_sync(timer)	del_timer_sync(timer)
#endif

#ifndef LEGO_HAVE_TIMER_CONTAINER_OF
#define timer_container_of(var, callback_timer, timer_fieldname)	\
	from_timer(var, callback_timer, timer_fieldname)
#endif
#endif /* __KERNEL__ */

/*
 * KUNIT_EXPECT_MEMEQ() for the KUnit tests, which include <kunit/test.h>:
 * before 6.2, a memcmp() and the names of the two buffers on a failure.
 */
#ifndef LEGO_HAVE_KUNIT_MEMEQ
#define KUNIT_EXPECT_MEMEQ(test, left, right, size)			\
	KUNIT_EXPECT_TRUE_MSG(test, !memcmp(left, right, size),		\
			      "%s and %s differ", #left, #right)
#endif

/*
 * 6.10: __assign_str() in a trace event takes the field's name only (the
 * source is the one __string() named); before, it took the source too.
 * lego_assign_str(field, source) works with both.
 */
#ifdef LEGO_HAVE_ASSIGN_STR_1
#define lego_assign_str(dst, ...)	__assign_str(dst)
#else
#define lego_assign_str(dst, src)	__assign_str(dst, src)
#endif

#endif /* _LEGO_COMPAT_H */
