// SPDX-License-Identifier: GPL-2.0
/* 6.2: KUnit compares memory (KUNIT_EXPECT_MEMEQ). */
#include <kunit/test.h>

#ifndef KUNIT_EXPECT_MEMEQ
#error no KUNIT_EXPECT_MEMEQ
#endif
