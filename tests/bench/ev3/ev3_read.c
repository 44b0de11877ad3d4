// SPDX-License-Identifier: GPL-2.0
/*
 * ev3_read - read EV3 sensor samples the two ways the sample-delivery
 * benchmark compares (tests/bench/guest/ev3_bench.py), and count them.
 *
 *   ev3_read -m iio [-P MS] [-i US] /dev/iio:deviceN...
 *   ev3_read -m tty [-P MS] /dev/ttyNM0...
 *
 * -m iio: the lego_ev3_uart line discipline's path. Each file is the IIO
 * buffer of a sensor in GYRO-ANG with in_angl0 and the timestamp enabled:
 * 16-byte scans, the value's 32-bit storage (s16 in it) at offset 0 and the
 * s64 timestamp at offset 8.
 *
 * -m tty: the userspace reference. Each file is a tty on N_TTY (raw mode is
 * set here) carrying the same bytes the discipline would get, and this
 * program decodes the EV3 DATA messages itself: header (0xc0 | size << 3 |
 * mode), payload, checksum (0xff ^ every byte before it); a byte that does
 * not start a valid message is counted as bad and skipped.
 *
 * Either way it wakes every -P MS (default 10, as a 100 Hz control loop
 * would) and reads everything that is there on every line, so that both
 * paths are read alike. The value is the first s16 of the payload; 0xffff
 * (the emulator's keep-alive answers) is not counted. It prints "ready" once
 * its files are open, then reads until SIGUSR1 (the sender has stopped)
 * and, after that, until two periods in a row bring no sample (but
 * markers) on any line; then:
 *
 *   line I READ DISTINCT DUPLICATED OUT_OF_ORDER BAD
 *   jitter P50_NS P99_NS MAX_NS INTERVALS   (-m iio: |interval between
 *                           consecutive timestamps of a line - -i US|,
 *                           default 1000 us)
 *   cpu USER_US SYSTEM_US WALL_NS           (this process, from "ready")
 *
 * Exit status: 0, 1 on an error, 2 on bad usage.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#define MAX_LINES	16
#define SCAN		16
#define MARKER		0xffff
#define BUF		65536

struct line {
	int fd;
	unsigned char bitmap[65536 / 8];
	unsigned long read, distinct, dup, reordered, bad;
	int have_prev;
	unsigned int prev;
	int64_t last_ts;
	unsigned char pend[BUF + 64];
	size_t pend_len;
};

static struct line lines[MAX_LINES];
static unsigned int nlines;
static int tty_mode;
static int64_t *intervals;
static size_t nintervals, cap;
static volatile sig_atomic_t stopping;

static void on_signal(int sig)
{
	(void)sig;
	stopping = 1;
}

static int64_t now_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static unsigned long samples;

static void sample(struct line *l, unsigned int v, int64_t ts)
{
	if (v == MARKER)
		return;
	samples++;
	l->read++;
	if (l->bitmap[v / 8] & (1U << (v % 8))) {
		l->dup++;
	} else {
		l->bitmap[v / 8] |= 1U << (v % 8);
		l->distinct++;
	}
	if (l->have_prev && v < l->prev)
		l->reordered++;
	l->have_prev = 1;
	l->prev = v;
	if (ts) {
		if (l->last_ts) {
			if (nintervals == cap) {
				cap = cap ? 2 * cap : 1 << 16;
				intervals = realloc(intervals, cap * sizeof(*intervals));
				if (!intervals) {
					perror("ev3_read");
					exit(1);
				}
			}
			intervals[nintervals++] = ts - l->last_ts;
		}
		l->last_ts = ts;
	}
}

/* Decode what is pending on a line; keep an incomplete message. */
static void decode(struct line *l)
{
	unsigned char *p = l->pend;
	size_t n = l->pend_len;

	if (!tty_mode) {
		while (n >= SCAN) {
			int32_t v;
			int64_t ts;

			memcpy(&v, p, sizeof(v));
			memcpy(&ts, p + 8, sizeof(ts));
			sample(l, v & 0xffff, ts);
			p += SCAN;
			n -= SCAN;
		}
	} else {
		while (n) {
			unsigned int len, i, v;
			unsigned char sum = 0xff;

			if ((p[0] & 0xc0) != 0xc0) {
				l->bad++;
				p++;
				n--;
				continue;
			}
			len = (1U << ((p[0] >> 3) & 7)) + 2;
			if (len > 34) {
				l->bad++;
				p++;
				n--;
				continue;
			}
			if (n < len)
				break;
			for (i = 0; i < len - 1; i++)
				sum ^= p[i];
			if (sum != p[len - 1]) {
				l->bad++;
				p++;
				n--;
				continue;
			}
			v = p[1] | (len > 3 ? p[2] << 8 : 0);
			sample(l, v, 0);
			p += len;
			n -= len;
		}
	}
	memmove(l->pend, p, n);
	l->pend_len = n;
}

/* Read all there is on every line; the samples read. */
static unsigned long read_all(void)
{
	unsigned long before = samples;
	unsigned int i;

	for (i = 0; i < nlines; i++) {
		struct line *l = &lines[i];

		for (;;) {
			ssize_t n = read(l->fd, l->pend + l->pend_len, BUF - l->pend_len);

			if (n < 0 && errno == EINTR)
				continue;
			if (n < 0 && errno == EAGAIN)
				break;
			if (n < 0) {
				perror("ev3_read: read");
				exit(1);
			}
			if (!n)
				break;
			l->pend_len += n;
			decode(l);
		}
	}
	return samples - before;
}

static int cmp64(const void *a, const void *b)
{
	int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;

	return (x > y) - (x < y);
}

static void usage(void)
{
	fprintf(stderr, "Usage: ev3_read -m iio|tty [-P MS] [-i US] FILE...\n");
	exit(2);
}

int main(int argc, char **argv)
{
	double period_ms = 10, interval_us = 1000;
	struct rusage ru0, ru1;
	struct timespec next;
	int64_t t0, period;
	const char *mode = NULL;
	unsigned int i;
	int opt, quiet_rounds = 0;

	while ((opt = getopt(argc, argv, "m:P:i:")) != -1) {
		switch (opt) {
		case 'm':
			mode = optarg;
			break;
		case 'P':
			period_ms = atof(optarg);
			break;
		case 'i':
			interval_us = atof(optarg);
			break;
		default:
			usage();
		}
	}
	if (!mode || (strcmp(mode, "iio") && strcmp(mode, "tty")) || optind >= argc ||
	    argc - optind > MAX_LINES || period_ms <= 0)
		usage();
	tty_mode = !strcmp(mode, "tty");
	for (i = 0; optind < argc; i++, optind++) {
		lines[i].fd = open(argv[optind], O_RDONLY | O_NOCTTY | O_NONBLOCK);
		if (lines[i].fd < 0) {
			perror(argv[optind]);
			return 1;
		}
		if (tty_mode) {
			struct termios t;

			if (tcgetattr(lines[i].fd, &t)) {
				perror(argv[optind]);
				return 1;
			}
			cfmakeraw(&t);
			t.c_cflag |= CLOCAL | CREAD;
			cfsetispeed(&t, B57600);
			cfsetospeed(&t, B57600);
			if (tcsetattr(lines[i].fd, TCSANOW, &t)) {
				perror(argv[optind]);
				return 1;
			}
		}
	}
	nlines = i;
	signal(SIGUSR1, on_signal);
	setvbuf(stdout, NULL, _IOLBF, 0);
	printf("ready\n");
	getrusage(RUSAGE_SELF, &ru0);
	t0 = now_ns();
	period = (int64_t)(period_ms * 1e6);
	clock_gettime(CLOCK_MONOTONIC, &next);
	for (;;) {
		int stop = stopping;	/* before the read: nothing is left behind */
		unsigned long got = read_all();

		if (stop) {
			/* Two periods in a row without a sample: all are in. */
			quiet_rounds = got ? 0 : quiet_rounds + 1;
			if (quiet_rounds >= 2)
				break;
		}
		next.tv_nsec += period % 1000000000LL;
		next.tv_sec += period / 1000000000LL + next.tv_nsec / 1000000000L;
		next.tv_nsec %= 1000000000L;
		while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR)
			;
	}
	getrusage(RUSAGE_SELF, &ru1);
	for (i = 0; i < nlines; i++) {
		struct line *l = &lines[i];

		printf("line %u %lu %lu %lu %lu %lu\n", i, l->read, l->distinct, l->dup,
		       l->reordered, l->bad + l->pend_len);
		close(l->fd);
	}
	if (nintervals) {
		int64_t med = (int64_t)(interval_us * 1000);
		size_t k;

		for (k = 0; k < nintervals; k++)
			intervals[k] = llabs(intervals[k] - med);
		qsort(intervals, nintervals, sizeof(*intervals), cmp64);
		printf("jitter %lld %lld %lld %zu\n", (long long)intervals[nintervals / 2],
		       (long long)intervals[(size_t)(nintervals * 0.99)],
		       (long long)intervals[nintervals - 1], nintervals);
	}
	printf("cpu %lld %lld %lld\n",
	       (ru1.ru_utime.tv_sec - ru0.ru_utime.tv_sec) * 1000000LL +
	       ru1.ru_utime.tv_usec - ru0.ru_utime.tv_usec,
	       (ru1.ru_stime.tv_sec - ru0.ru_stime.tv_sec) * 1000000LL +
	       ru1.ru_stime.tv_usec - ru0.ru_stime.tv_usec,
	       (long long)(now_ns() - t0));
	return 0;
}
