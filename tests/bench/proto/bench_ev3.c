// SPDX-License-Identifier: GPL-2.0
/*
 * The EV3 protocol core over a recorded stream, for callgrind: the stream
 * is received in batches as a UART delivers it, and the parser is driven
 * as the line discipline drives it (ACK and speed change at once after a
 * handshake; each DATA message decoded as the IIO buffer code does; a
 * keep-alive tick per 100 ms of bytes at the line speed). UNPLUG lists
 * the offsets where the line then goes silent: the ticks give the sensor
 * up, and the next handshake is found.
 *
 * Usage: bench_ev3 [-b N | -r MAX] [-m MODE] [-z] STREAM UNPLUG
 *   -b N     batches of N bytes (default 16)
 *   -r MAX   batches of 1 to MAX bytes, drawn from a fixed seed (xorshift32),
 *            so that every run gets the same batches
 *   -m MODE  the host SELECTs MODE right after each handshake (the stream
 *            then carries that mode's DATA messages)
 *   -z       count the data phase only: bench_data_phase() is called as the
 *            first data phase starts (callgrind --zero-before=bench_data_phase
 *            drops what was counted before it)
 * Prints: bytes, bytes counted, batches, handshakes, DATA messages, errors,
 * garbage bytes, bad frames, a checksum of the values.
 */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include <linux/kernel.h>	/* tests/fuzz/shim: noinline */

#include "ev3_uart_proto.h"

static u8 *read_file(const char *path, size_t *len)
{
	FILE *f = fopen(path, "rb");
	u8 *buf;
	long n;

	if (!f || fseek(f, 0, SEEK_END)) {
		perror(path);
		exit(1);
	}
	n = ftell(f);
	if (n < 0 || fseek(f, 0, SEEK_SET)) {
		perror(path);
		exit(1);
	}
	buf = malloc(n ? n : 1);
	if (!buf || fread(buf, 1, n, f) != (size_t)n) {
		perror(path);
		exit(1);
	}
	fclose(f);
	*len = n;
	return buf;
}

/* A mark for callgrind (--zero-before): not inlined, not optimised away. */
noinline void bench_data_phase(void);
noinline void bench_data_phase(void)
{
	__asm__ __volatile__("" ::: "memory");
}

static u32 rnd(u32 *x)
{
	*x ^= *x << 13;
	*x ^= *x >> 17;
	*x ^= *x << 5;
	return *x;
}

static void count_event(const struct ev3_uart_event *ev, unsigned long *errors)
{
	if (ev->type == EV3_UART_EV_ERROR)
		++*errors;
}

int main(int argc, char **argv)
{
	unsigned long batches = 0, handshakes = 0, data = 0, errors = 0;
	size_t len, pos = 0, n, used, batch = 16, rmax = 0, unplug, since_tick = 0;
	size_t counted_from = 0;
	int select = -1, zero = 0, opt;
	u32 seed = 0x2545f491;
	struct ev3_uart_parser p;
	struct ev3_uart_event ev;
	long long sum = 0;
	unsigned int i;
	FILE *uf;
	s32 v;
	u8 *buf;

	while ((opt = getopt(argc, argv, "b:r:m:z")) != -1) {
		switch (opt) {
		case 'b':
			batch = strtoul(optarg, NULL, 0);
			break;
		case 'r':
			rmax = strtoul(optarg, NULL, 0);
			break;
		case 'm':
			select = atoi(optarg);
			break;
		case 'z':
			zero = 1;
			break;
		default:
			goto usage;
		}
	}
	if (argc - optind != 2)
		goto usage;
	buf = read_file(argv[optind], &len);
	uf = fopen(argv[optind + 1], "r");
	if (!uf) {
		perror(argv[optind + 1]);
		return 1;
	}
	if (fscanf(uf, "%zu", &unplug) != 1)
		unplug = len;
	if (!batch)
		batch = 1;

	ev3_uart_parser_init(&p);
	while (pos < len) {
		if (pos == unplug) {
			/* Silence: the keep-alive gives the sensor up. */
			while (!ev3_uart_parser_tick(&p, &ev))
				if (p.state != EV3_UART_STATE_DATA)
					break;
			count_event(&ev, &errors);
			if (fscanf(uf, "%zu", &unplug) != 1)
				unplug = len;
		}
		if (rmax)
			batch = 1 + rnd(&seed) % rmax;
		n = len - pos < batch ? len - pos : batch;
		if (unplug > pos && n > unplug - pos)
			n = unplug - pos;
		batches++;
		since_tick += n;
		if (p.state == EV3_UART_STATE_DATA &&
		    since_tick >= p.sensor.speed / 100) {
			since_tick = 0;
			ev3_uart_parser_tick(&p, &ev);
			count_event(&ev, &errors);
		}
		while (n > 0) {
			used = ev3_uart_parser_feed(&p, buf + pos, n, &ev);
			pos += used;
			n -= used;
			switch (ev.type) {
			case EV3_UART_EV_HANDSHAKE:
				handshakes++;
				ev3_uart_parser_start_data(&p);
				if (select >= 0 && ev3_uart_parser_select(&p, select)) {
					fprintf(stderr, "SELECT %d refused\n", select);
					return 1;
				}
				if (zero == 1) {
					bench_data_phase();
					counted_from = pos;
					zero = 2;
				}
				break;
			case EV3_UART_EV_DATA:
				data++;
				for (i = 0; i < p.sensor.modes[ev.mode].num_values; i++)
					if (!ev3_uart_read_value(&p.sensor.modes[ev.mode],
								 p.data, ev.len, i, &v))
						sum += v;
				break;
			case EV3_UART_EV_ERROR:
				errors++;
				break;
			default:
				break;
			}
		}
	}
	printf("bytes %zu counted %zu batches %lu handshakes %lu data %lu ", len,
	       len - counted_from, batches, handshakes, data);
	printf("errors %lu garbage %lu bad %lu checksum %lld\n", errors, p.garbage,
	       p.bad_frames, sum);
	fclose(uf);
	free(buf);
	return 0;
usage:
	fprintf(stderr, "usage: %s [-b N | -r MAX] [-m MODE] [-z] STREAM UNPLUG\n",
		argv[0]);
	return 2;
}
