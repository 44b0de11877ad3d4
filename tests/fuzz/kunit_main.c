// SPDX-License-Identifier: GPL-2.0
/*
 * Runs the KUnit suite linked with it (ev3_uart_proto_test.c or
 * nxt_proto_test.c, built unchanged against tests/fuzz/shim/kunit/test.h)
 * in userspace, under ASan and UBSan, and prints KTAP-like lines; exits 1
 * if a case failed.
 */
#include <kunit/test.h>

int main(void)
{
	struct kunit_suite *s = lego_kunit_suite;
	struct kunit_case *c;
	int n = 0, failed = 0;

	for (c = s->test_cases; c->run_case; c++)
		n++;
	printf("# %s\n1..%d\n", s->name, n);
	n = 0;
	for (c = s->test_cases; c->run_case; c++) {
		struct kunit test = { .name = c->name };

		unsigned int i;

		if (!setjmp(test.abort))
			c->run_case(&test);
		for (i = 0; i < test.n_allocs; i++)
			free(test.allocs[i]);
		printf("%s %d %s\n", test.failed ? "not ok" : "ok", ++n, c->name);
		failed += test.failed;
	}
	printf("# %s: %d of %d failed\n", s->name, failed, n);
	return failed ? 1 : 0;
}
