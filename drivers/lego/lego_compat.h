/* SPDX-License-Identifier: GPL-2.0 */
/*
 * Differences between the kernels these drivers build against (6.1 LTS up to
 * current mainline), kept in one place. The LEGO_HAVE_* flags are set by the
 * top-level Kbuild, which probes the target kernel's headers.
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

#ifdef LEGO_HAVE_STRING_NS
#define LEGO_IMPORT_KUNIT_NS() MODULE_IMPORT_NS("EXPORTED_FOR_KUNIT_TESTING")
#else
#define LEGO_IMPORT_KUNIT_NS() MODULE_IMPORT_NS(EXPORTED_FOR_KUNIT_TESTING)
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
