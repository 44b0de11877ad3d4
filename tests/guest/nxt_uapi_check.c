// SPDX-License-Identifier: GPL-2.0
/*
 * Prints the size and the offsets of struct nxt_transaction and the ioctl
 * numbers of include/uapi/linux/lego_nxt.h as the C compiler sees them,
 * one "name value" a line, for the guest tests to compare with their own
 * description of the interface (tests/guest/nxtdev.py, uapi_layout()).
 */
#include <stddef.h>
#include <stdio.h>
#include <linux/lego_nxt.h>

#define SIZE(t)		printf("%s %zu\n", #t, sizeof(struct nxt_##t))
#define OFFSET(t, m)	printf("%s.%s %zu\n", #t, #m, offsetof(struct nxt_##t, m))
#define IOCTL(n)	printf("%s %lu\n", #n, (unsigned long)NXT_IOC_##n)

int main(void)
{
	SIZE(transaction);
	OFFSET(transaction, reply);
	OFFSET(transaction, length);
	OFFSET(transaction, reply_length);
	IOCTL(TRANSACT);
	IOCTL(SET_TIMEOUT);
	IOCTL(GET_TIMEOUT);
	IOCTL(TTY_MINOR);
	return 0;
}
