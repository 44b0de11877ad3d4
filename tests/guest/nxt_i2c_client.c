// SPDX-License-Identifier: GPL-2.0
/*
 * One I2C transfer, or many, through /dev/i2c-N with I2C_RDWR, as a C
 * program of a user would make them (tests/guest/test_nxt_i2c.py).
 *
 *   nxt_i2c_client [-n COUNT] DEV ADDR MSG...
 *
 * ADDR is the 7-bit address (0x01 for LEGO's ultrasonic sensor); each MSG
 * is "w:HEX" (bytes to write) or "r:N" (N bytes to read). The messages go
 * in one transfer, COUNT times (default 1; 0: until one fails). Each read
 * message of the last transfer is printed as a line of hex; a failure
 * prints "errno NAME" on stdout after "done N" (the transfers that
 * succeeded) and exits with 2.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <linux/i2c.h>
#include <linux/i2c-dev.h>

#define MAX_MSGS	8
#define MAX_LEN		64

static const char *errno_name(int e)
{
	switch (e) {
	case EOPNOTSUPP: return "EOPNOTSUPP";
	case ENXIO: return "ENXIO";
	case ENODEV: return "ENODEV";
	case ETIMEDOUT: return "ETIMEDOUT";
	case EIO: return "EIO";
	case EINVAL: return "EINVAL";
	case EAGAIN: return "EAGAIN";
	case EPROTO: return "EPROTO";
	case EINTR: return "EINTR";
	default: return strerror(e);
	}
}

int main(int argc, char **argv)
{
	static unsigned char bufs[MAX_MSGS][MAX_LEN];
	struct i2c_msg msgs[MAX_MSGS];
	struct i2c_rdwr_ioctl_data rdwr = { .msgs = msgs };
	long count = 1, done = 0;
	unsigned int addr, i, j;
	int fd, arg = 1;

	if (argc > 2 && !strcmp(argv[1], "-n")) {
		count = strtol(argv[2], NULL, 0);
		arg = 3;
	}
	if (argc - arg < 3 || argc - arg - 2 > MAX_MSGS) {
		fprintf(stderr, "usage: %s [-n COUNT] DEV ADDR MSG...\n", argv[0]);
		return 1;
	}
	fd = open(argv[arg], O_RDWR);
	if (fd < 0) {
		perror(argv[arg]);
		return 1;
	}
	addr = strtoul(argv[arg + 1], NULL, 0);
	for (i = 0; arg + 2 + i < (unsigned int)argc; i++) {
		const char *m = argv[arg + 2 + i];

		msgs[i].addr = addr;
		msgs[i].buf = bufs[i];
		if (!strncmp(m, "r:", 2)) {
			msgs[i].flags = I2C_M_RD;
			msgs[i].len = strtoul(m + 2, NULL, 0);
		} else if (!strncmp(m, "w:", 2)) {
			msgs[i].flags = 0;
			msgs[i].len = strlen(m + 2) / 2;
			for (j = 0; j < msgs[i].len && j < MAX_LEN; j++) {
				if (sscanf(m + 2 + 2 * j, "%2hhx", &bufs[i][j]) != 1) {
					fprintf(stderr, "bad hex in %s\n", m);
					return 1;
				}
			}
		} else {
			fprintf(stderr, "bad message %s\n", m);
			return 1;
		}
		if (msgs[i].len > MAX_LEN) {
			fprintf(stderr, "message too long\n");
			return 1;
		}
	}
	rdwr.nmsgs = i;

	while (!count || done < count) {
		if (ioctl(fd, I2C_RDWR, &rdwr) < 0) {
			int e = errno;

			printf("done %ld\nerrno %s\n", done, errno_name(e));
			return 2;
		}
		done++;
	}
	for (i = 0; i < rdwr.nmsgs; i++) {
		if (!(msgs[i].flags & I2C_M_RD))
			continue;
		for (j = 0; j < msgs[i].len; j++)
			printf("%02x", bufs[i][j]);
		printf("\n");
	}
	close(fd);
	return 0;
}
