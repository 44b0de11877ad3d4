/* SPDX-License-Identifier: GPL-2.0 */
/*
 * A userspace KUnit for the protocol cores' suites: the same macros, run by
 * kunit_main.c, with ASan and UBSan around them.
 */
#ifndef _LEGO_SHIM_KUNIT_TEST_H
#define _LEGO_SHIM_KUNIT_TEST_H

#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../kshim.h"

#define KUNIT_ALLOC_MAX	256

struct kunit {
	const char *name;
	int failed;
	jmp_buf abort;
	void *allocs[KUNIT_ALLOC_MAX];	/* freed after the case, as in KUnit */
	unsigned int n_allocs;
};

struct kunit_case {
	void (*run_case)(struct kunit *test);
	const char *name;
};

struct kunit_suite {
	const char *name;
	struct kunit_case *test_cases;
};

#define GFP_KERNEL	0
#define KUNIT_CASE(f)	{ .run_case = f, .name = #f }

extern struct kunit_suite *lego_kunit_suite;
#define kunit_test_suite(s)	struct kunit_suite *lego_kunit_suite = &(s)

static inline void *kunit_kzalloc(struct kunit *test, size_t size, int gfp)
{
	void *p;

	if (test->n_allocs == KUNIT_ALLOC_MAX)
		return NULL;
	p = calloc(1, size);
	test->allocs[test->n_allocs++] = p;
	return p;
}

#define KUNIT_FAIL_AT(test, fmt, ...) do {				\
	fprintf(stderr, "    %s:%d: %s: " fmt "\n", __FILE__, __LINE__,	\
		(test)->name, ##__VA_ARGS__);				\
	(test)->failed = 1;						\
} while (0)

#define KUNIT_BINARY(test, a, op, b, assert) do {			\
	long long __a = (long long)(a), __b = (long long)(b);		\
	if (!(__a op __b)) {						\
		KUNIT_FAIL_AT(test, "expected %s %s %s (%lld vs %lld)",	\
			      #a, #op, #b, __a, __b);			\
		if (assert)						\
			longjmp((test)->abort, 1);			\
	}								\
} while (0)

#define KUNIT_EXPECT_EQ(t, a, b)	KUNIT_BINARY(t, a, ==, b, 0)
#define KUNIT_EXPECT_EQ_MSG(t, a, b, ...)	KUNIT_BINARY(t, a, ==, b, 0)
#define KUNIT_EXPECT_NE(t, a, b)	KUNIT_BINARY(t, a, !=, b, 0)
#define KUNIT_EXPECT_GT(t, a, b)	KUNIT_BINARY(t, a, >, b, 0)
#define KUNIT_EXPECT_GE(t, a, b)	KUNIT_BINARY(t, a, >=, b, 0)
#define KUNIT_EXPECT_GE_MSG(t, a, b, ...)	KUNIT_BINARY(t, a, >=, b, 0)
#define KUNIT_EXPECT_LT(t, a, b)	KUNIT_BINARY(t, a, <, b, 0)
#define KUNIT_EXPECT_LT_MSG(t, a, b, ...)	KUNIT_BINARY(t, a, <, b, 0)
#define KUNIT_EXPECT_LE(t, a, b)	KUNIT_BINARY(t, a, <=, b, 0)
#define KUNIT_EXPECT_TRUE(t, c)		KUNIT_BINARY(t, !!(c), ==, 1, 0)
#define KUNIT_EXPECT_FALSE(t, c)	KUNIT_BINARY(t, !!(c), ==, 0, 0)
#define KUNIT_EXPECT_TRUE_MSG(t, c, ...)	KUNIT_BINARY(t, !!(c), ==, 1, 0)
#define KUNIT_EXPECT_FALSE_MSG(t, c, ...)	KUNIT_BINARY(t, !!(c), ==, 0, 0)
#define KUNIT_ASSERT_EQ(t, a, b)	KUNIT_BINARY(t, a, ==, b, 1)
#define KUNIT_ASSERT_NE(t, a, b)	KUNIT_BINARY(t, a, !=, b, 1)
#define KUNIT_ASSERT_GT(t, a, b)	KUNIT_BINARY(t, a, >, b, 1)
#define KUNIT_ASSERT_GE(t, a, b)	KUNIT_BINARY(t, a, >=, b, 1)
#define KUNIT_ASSERT_LT(t, a, b)	KUNIT_BINARY(t, a, <, b, 1)
#define KUNIT_ASSERT_LE(t, a, b)	KUNIT_BINARY(t, a, <=, b, 1)
#define KUNIT_ASSERT_TRUE(t, c)		KUNIT_BINARY(t, !!(c), ==, 1, 1)
#define KUNIT_EXPECT_NULL(t, p)		KUNIT_BINARY(t, (p) == NULL, ==, 1, 0)
#define KUNIT_EXPECT_NOT_NULL(t, p)	KUNIT_BINARY(t, (p) != NULL, ==, 1, 0)
#define KUNIT_ASSERT_NOT_NULL(t, p)	KUNIT_BINARY(t, (p) != NULL, ==, 1, 1)
#define KUNIT_EXPECT_STREQ(t, a, b) do {				\
	if (strcmp((a), (b)))						\
		KUNIT_FAIL_AT(t, "expected %s == %s (\"%s\" vs \"%s\")",	\
			      #a, #b, (a), (b));			\
} while (0)
#define KUNIT_EXPECT_MEMEQ(t, a, b, n) do {				\
	if (memcmp((a), (b), (n)))					\
		KUNIT_FAIL_AT(t, "expected %s == %s (%zu bytes)",	\
			      #a, #b, (size_t)(n));			\
} while (0)

#endif /* _LEGO_SHIM_KUNIT_TEST_H */
