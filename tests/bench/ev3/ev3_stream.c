// SPDX-License-Identifier: GPL-2.0
/*
 * ev3_stream - play EV3 UART sensors on the far ends of tty lines, fast.
 *
 *   ev3_stream -H HANDSHAKE [-s BAUD] [-p BYTES] [-r HZ] [-d SECONDS]
 *              [-D MS] [-c] [-g] [-k] [-q] [-t MS] [-n TRIES] TTY...
 *
 * A benchmark aid for tests/bench/guest/ev3_bench.py (the Python emulator
 * cannot send thousands of messages a second inside the TCG test VM). Per
 * line, like a real sensor on the wire:
 *
 *  - at 2400 baud, writes the recorded handshake (the bytes of HANDSHAKE,
 *    TYPE to the sensor's ACK, back to back) and waits -t MS (80, as the
 *    sensors do) after its last byte left for the host's ACK, else sends it
 *    again (at most -n TRIES times);
 *  - then switches to -s BAUD and sends DATA messages of the current mode
 *    with a -p BYTES payload (a power of two) every 1/-r HZ seconds on an
 *    absolute schedule (a tick that is already late is skipped, not made
 *    up), the first value counting 0, 1, 2... (s16, wrapping), or with -c a
 *    constant 1000 * (mode + 1); with -r 0 it only answers each NACK with a
 *    DATA message (as sensors in their "on NACK" modes do); with -r > 0 the
 *    next scheduled message is the answer;
 *  - answers SELECT after -D MS (the sensor's own reply delay) with the
 *    first DATA message of the new mode;
 *  - with -g, only answers NACKs (value 0xffff, not counted) until it gets
 *    SIGUSR1, then starts the -d SECONDS of its schedule;
 *  - with -q, sends nothing during its schedule: the DATA messages come
 *    from elsewhere, the null modem's generator (gen_hz), and must not be
 *    interleaved with its own; nor does it expect NACKs then (the generator
 *    takes the host's bytes), its one-second watchdog starting again when
 *    the schedule ends;
 *  - ends its schedule early on SIGUSR2;
 *  - with -k, answers NACKs only again (value 0xffff, not counted) once
 *    its schedule is over, so that the host can stop reading while the
 *    sensors are still there, until SIGTERM;
 *  - ends at once, with its report, on SIGTERM;
 *  - stops, as a sensor resets, when no NACK came for a second, and stops
 *    after -d SECONDS of data phase (all lines).
 *
 * It prints one line per event, times in CLOCK_MONOTONIC nanoseconds:
 *   hs LINE T_WRITE T_DRAINED T_ACK BYTES TRIES   (T_ACK 0: never acked)
 *   select LINE T_RECEIVED T_REPLIED MODE
 *   line LINE SENT NACKS LATE_TICKS FIRST_NS LAST_NS STOPPED_BY
 *   total SENT SECONDS RATE_PER_LINE SYSTEM_US
 * (SYSTEM_US: its own system time, mostly its write() calls, over the -d
 * SECONDS of its schedule.)
 * Exit status: 0, 1 on an error, 2 on bad usage.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/resource.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#define MAX_LINES	16
#define MAX_HANDSHAKE	4096
#define NACK		0x02
#define ACK		0x04
#define SELECT		0x43
#define WATCHDOG_NS	1000000000LL

struct line {
	const char *path;
	int fd;
	int live;
	int acked;
	unsigned int mode;
	uint16_t seq;
	unsigned long sent, nacks, late;
	int64_t first, last, last_nack;
	int64_t reply_at;	/* a SELECT to answer at this time, 0: none */
	int64_t select_rx;	/* when that SELECT was read */
	unsigned int reply_mode;
	unsigned char in[8];
	size_t in_len;
	const char *stopped;
};

static struct line lines[MAX_LINES];
static unsigned int nlines;
static unsigned int payload = 2;
static int constant;
static int quiet;
static volatile sig_atomic_t go = 1;

static volatile sig_atomic_t stop;
static volatile sig_atomic_t quit;

static void on_signal(int sig)
{
	if (sig == SIGUSR1)
		go = 1;
	else if (sig == SIGUSR2)
		stop = 1;
	else
		quit = 1;
}

static int64_t now_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static speed_t speed_code(long baud)
{
	switch (baud) {
	case 2400: return B2400;
	case 9600: return B9600;
	case 19200: return B19200;
	case 38400: return B38400;
	case 57600: return B57600;
	case 115200: return B115200;
	case 230400: return B230400;
	case 460800: return B460800;
	}
	return 0;
}

static int set_speed(int fd, speed_t code)
{
	struct termios t;

	if (tcgetattr(fd, &t))
		return -1;
	cfmakeraw(&t);
	t.c_cflag |= CLOCAL | CREAD;
	t.c_cc[VMIN] = 0;
	t.c_cc[VTIME] = 0;
	cfsetispeed(&t, code);
	cfsetospeed(&t, code);
	return tcsetattr(fd, TCSANOW, &t);
}

static int write_all(int fd, const unsigned char *buf, size_t len)
{
	while (len) {
		ssize_t n = write(fd, buf, len);

		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0 && errno == EAGAIN) {
			struct pollfd p = { .fd = fd, .events = POLLOUT };

			poll(&p, 1, 100);
			continue;
		}
		if (n <= 0)
			return -1;
		buf += n;
		len -= n;
	}
	return 0;
}

static unsigned int size_code(unsigned int n)
{
	unsigned int c = 0;

	while ((1U << c) < n)
		c++;
	return c;
}

static void send_data(struct line *l, int64_t t)
{
	unsigned char msg[2 + 32];
	unsigned int v = constant ? 1000 * (l->mode + 1) : go ? l->seq : 0xffff;
	unsigned int i;
	unsigned char sum = 0xff;

	if (quiet && go)
		return;		/* -q: the generator sends */
	memset(msg, 0, sizeof(msg));
	msg[0] = 0xc0 | size_code(payload) << 3 | (l->mode & 7);
	msg[1] = v & 0xff;
	if (payload > 1)
		msg[2] = v >> 8;
	for (i = 0; i <= payload; i++)
		sum ^= msg[i];
	msg[payload + 1] = sum;
	if (write_all(l->fd, msg, payload + 2)) {
		l->live = 0;
		l->stopped = "write-error";
		return;
	}
	if (!go)
		return;		/* a keep-alive reply before the stream: not counted */
	if (!l->sent)
		l->first = t;
	l->last = t;
	l->sent++;
	l->seq++;
}

/* Consume what the host sent; @t is the time it was read. */
static void host_input(struct line *l, int64_t t, int answer_nack, int64_t delay)
{
	unsigned char buf[256];
	ssize_t n, i;

	n = read(l->fd, buf, sizeof(buf));
	for (i = 0; i < n; i++) {
		unsigned char b = buf[i];

		if (l->in_len) {		/* inside a SELECT or WRITE */
			if (l->in_len < sizeof(l->in))
				l->in[l->in_len] = b;
			l->in_len++;
			if (l->in[0] == SELECT && l->in_len == 3) {
				if ((0xff ^ l->in[0] ^ l->in[1]) == l->in[2]) {
					l->reply_at = t + delay;
					l->reply_mode = l->in[1] & 7;
					l->select_rx = t;
				}
				l->in_len = 0;
			} else if (l->in[0] != SELECT &&
				   l->in_len == (1U << ((l->in[0] >> 3) & 7)) + 2) {
				l->in_len = 0;		/* WRITE: ignored */
			}
			continue;
		}
		if (b == NACK) {
			l->nacks++;
			l->last_nack = t;
			if ((answer_nack || !go) && !l->reply_at)
				send_data(l, t);
		} else if (b == SELECT || (b & 0xc7) == 0x44) {
			l->in[0] = b;
			l->in_len = 1;
		}
	}
}

/*
 * Every line on its own, as separate sensors: (re)send the handshake, wait
 * for it to leave (TIOCOUTQ empty), then at most @ack_wait for the host's
 * ACK, else send it again. Lines already connected keep answering NACKs
 * meanwhile.
 */
static int handshake(const unsigned char *hs, size_t hs_len, int64_t ack_wait,
		     unsigned int tries, speed_t data_speed, int64_t delay)
{
	int64_t t_write[MAX_LINES] = { 0 }, t_drained[MAX_LINES] = { 0 };
	int64_t t_ack[MAX_LINES] = { 0 };
	unsigned int try[MAX_LINES] = { 0 }, i;
	int failed[MAX_LINES] = { 0 };

	for (;;) {
		struct pollfd p[MAX_LINES];
		struct timespec ts = { 0, 2000000 };	/* 2 ms: TIOCOUTQ polls */
		int64_t t = now_ns();
		unsigned int waiting = 0;

		for (i = 0; i < nlines; i++) {
			struct line *l = &lines[i];
			int queued;

			p[i].fd = l->fd;
			p[i].events = POLLIN;
			if (l->acked || failed[i])
				continue;
			if (!t_write[i] || (t_drained[i] && t > t_drained[i] + ack_wait)) {
				if (try[i] >= tries) {
					failed[i] = 1;
					continue;
				}
				if (set_speed(l->fd, B2400))
					return -1;
				tcflush(l->fd, TCIFLUSH);
				t_write[i] = now_ns();
				t_drained[i] = 0;
				if (write_all(l->fd, hs, hs_len))
					return -1;
				try[i]++;
			}
			if (!t_drained[i] && !ioctl(l->fd, TIOCOUTQ, &queued) && !queued)
				t_drained[i] = now_ns();
			waiting++;
		}
		if (!waiting)
			break;
		if (ppoll(p, nlines, &ts, NULL) < 0 && errno != EINTR)
			return -1;
		t = now_ns();
		for (i = 0; i < nlines; i++) {
			unsigned char buf[64];
			struct line *l = &lines[i];
			ssize_t got;

			if (!(p[i].revents & POLLIN))
				continue;
			if (l->acked) {
				host_input(l, t, 1, delay);
				continue;
			}
			got = read(l->fd, buf, sizeof(buf));
			if (got > 0 && !failed[i] && memchr(buf, ACK, got)) {
				l->acked = 1;
				t_ack[i] = t;
				/* The sensor switches as soon as it has the ACK. */
				if (set_speed(l->fd, data_speed))
					return -1;
				l->live = 1;
				l->last_nack = t;
			}
		}
	}
	for (i = 0; i < nlines; i++) {
		printf("hs %u %lld %lld %lld %zu %u\n", i, (long long)t_write[i],
		       (long long)t_drained[i], (long long)t_ack[i], hs_len, try[i]);
		if (!lines[i].acked)
			lines[i].stopped = "no-ack";
	}
	return 0;
}

static void usage(void)
{
	fprintf(stderr, "Usage: ev3_stream -H HANDSHAKE [-s BAUD] [-p BYTES] [-r HZ] [-d SECONDS]\n"
		"                  [-D MS] [-c] [-g] [-k] [-q] [-t MS] [-n TRIES] TTY...\n");
	exit(2);
}

int main(int argc, char **argv)
{
	unsigned char hs[MAX_HANDSHAKE];
	const char *hs_path = NULL;
	long baud = 57600;
	double rate = 0, seconds = 5, delay_ms = 15, ack_ms = 80;
	unsigned int tries = 3, i;
	int64_t period = 0, next, end, start, delay, done = 0;
	unsigned long total = 0;
	int started, linger = 0, lingering = 0;
	struct rusage ru0, ru1;
	size_t hs_len;
	speed_t code;
	FILE *f;
	int opt;

	while ((opt = getopt(argc, argv, "H:s:p:r:d:D:cgkqt:n:")) != -1) {
		switch (opt) {
		case 'H':
			hs_path = optarg;
			break;
		case 's':
			baud = atol(optarg);
			break;
		case 'p':
			payload = atoi(optarg);
			break;
		case 'r':
			rate = atof(optarg);
			break;
		case 'd':
			seconds = atof(optarg);
			break;
		case 'D':
			delay_ms = atof(optarg);
			break;
		case 'c':
			constant = 1;
			break;
		case 'g':
			go = 0;
			break;
		case 'k':
			linger = 1;
			break;
		case 'q':
			quiet = 1;
			break;
		case 't':
			ack_ms = atof(optarg);
			break;
		case 'n':
			tries = atoi(optarg);
			break;
		default:
			usage();
		}
	}
	code = speed_code(baud);
	if (!hs_path || optind >= argc || argc - optind > MAX_LINES || !code ||
	    payload < 1 || payload > 32 || (payload & (payload - 1)) ||
	    rate < 0 || rate > 100000 || seconds <= 0 || !tries)
		usage();
	f = fopen(hs_path, "rb");
	if (!f) {
		perror(hs_path);
		return 1;
	}
	hs_len = fread(hs, 1, sizeof(hs), f);
	fclose(f);
	if (!hs_len) {
		fprintf(stderr, "ev3_stream: %s: empty handshake\n", hs_path);
		return 1;
	}
	setvbuf(stdout, NULL, _IOLBF, 0);
	started = go;
	signal(SIGUSR1, on_signal);
	signal(SIGUSR2, on_signal);
	signal(SIGTERM, on_signal);
	for (i = 0; optind < argc; i++, optind++) {
		lines[i].path = argv[optind];
		lines[i].fd = open(argv[optind], O_RDWR | O_NOCTTY | O_NONBLOCK);
		if (lines[i].fd < 0) {
			perror(argv[optind]);
			return 1;
		}
		lines[i].stopped = "time";
	}
	nlines = i;

	delay = (int64_t)(delay_ms * 1e6);
	if (handshake(hs, hs_len, (int64_t)(ack_ms * 1e6), tries, code, delay)) {
		perror("ev3_stream: handshake");
		return 1;
	}

	if (rate > 0)
		period = (int64_t)(1e9 / rate);
	getrusage(RUSAGE_SELF, &ru0);
	start = now_ns();
	end = start + (go ? (int64_t)(seconds * 1e9) : 600000000000LL);
	next = start + period;
	for (;;) {
		if (go && !started) {
			started = 1;
			getrusage(RUSAGE_SELF, &ru0);
			start = now_ns();
			end = start + (int64_t)(seconds * 1e9);
			next = start + period;
		}
		struct pollfd p[MAX_LINES];
		unsigned int n = 0, map[MAX_LINES];
		int64_t t = now_ns(), wake = end;

		for (i = 0; i < nlines; i++) {
			struct line *l = &lines[i];

			if (!l->live)
				continue;
			if (quiet && go)
				l->last_nack = t;	/* -q: no NACKs now */
			if (t - l->last_nack > WATCHDOG_NS) {
				l->live = 0;
				l->stopped = "watchdog";
				continue;
			}
			if (l->reply_at && t >= l->reply_at) {
				l->reply_at = 0;
				l->mode = l->reply_mode;
				send_data(l, t);
				printf("select %u %lld %lld %u\n", i,
				       (long long)l->select_rx,
				       (long long)now_ns(), l->mode);
			}
			if (l->reply_at && l->reply_at < wake)
				wake = l->reply_at;
			p[n].fd = l->fd;
			p[n].events = POLLIN;
			map[n++] = i;
		}
		if (!n || quit)
			break;
		if ((t >= end || stop) && !lingering) {
			getrusage(RUSAGE_SELF, &ru1);
			done = t;
			if (!linger || !started)
				break;
			/* -k: the schedule is over; keep the sensors alive. */
			lingering = 1;
			go = 0;
			end = t + 600000000000LL;
			continue;
		}
		if (period && go && t >= next) {
			for (i = 0; i < nlines; i++)
				if (lines[i].live && !lines[i].reply_at)
					send_data(&lines[i], t);
			next += period;
			/* Late by whole periods: those ticks are lost, as counted. */
			while (next <= now_ns()) {
				next += period;
				for (i = 0; i < nlines; i++)
					lines[i].late++;
			}
			continue;
		}
		if (period && go && next < wake)
			wake = next;
		struct timespec ts = { (wake - t) / 1000000000LL, (wake - t) % 1000000000LL };

		if (ppoll(p, n, &ts, NULL) < 0 && errno != EINTR) {
			perror("ev3_stream: ppoll");
			return 1;
		}
		t = now_ns();
		for (unsigned int k = 0; k < n; k++)
			if (p[k].revents & POLLIN)
				host_input(&lines[map[k]], t, !period, delay);
	}
	if (!done) {
		getrusage(RUSAGE_SELF, &ru1);
		done = now_ns();
	}
	/* Let the last messages leave before the lines close. */
	for (i = 0; i < nlines; i++) {
		struct line *l = &lines[i];

		tcdrain(l->fd);
		printf("line %u %lu %lu %lu %lld %lld %s\n", i, l->sent, l->nacks,
		       l->late, (long long)l->first, (long long)l->last, l->stopped);
		total += l->sent;
	}
	printf("total %lu %.3f %.1f %lld\n", total, (now_ns() - start) / 1e9,
	       nlines ? total / (double)nlines / ((done - start) / 1e9) : 0.0,
	       (ru1.ru_stime.tv_sec - ru0.ru_stime.tv_sec) * 1000000LL +
	       ru1.ru_stime.tv_usec - ru0.ru_stime.tv_usec);
	return 0;
}
