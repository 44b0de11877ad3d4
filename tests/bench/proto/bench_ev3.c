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
 * Usage: bench_ev3 STREAM UNPLUG [BATCH]
 * Prints: bytes, batches, handshakes, DATA messages, errors, garbage bytes.
 */
#include <stdio.h>
#include <stdlib.h>

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

static void count_event(const struct ev3_uart_event *ev, unsigned long *errors)
{
	if (ev->type == EV3_UART_EV_ERROR)
		++*errors;
}

int main(int argc, char **argv)
{
	unsigned long batches = 0, handshakes = 0, data = 0, errors = 0;
	size_t len, pos = 0, n, used, batch, unplug, since_tick = 0;
	struct ev3_uart_parser p;
	struct ev3_uart_event ev;
	long long sum = 0;
	unsigned int i;
	FILE *uf;
	s32 v;
	u8 *buf;

	if (argc < 3) {
		fprintf(stderr, "usage: %s STREAM UNPLUG [BATCH]\n", argv[0]);
		return 2;
	}
	buf = read_file(argv[1], &len);
	uf = fopen(argv[2], "r");
	if (!uf) {
		perror(argv[2]);
		return 1;
	}
	if (fscanf(uf, "%zu", &unplug) != 1)
		unplug = len;
	batch = argc > 3 ? strtoul(argv[3], NULL, 0) : 16;
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
	printf("bytes %zu batches %lu handshakes %lu data %lu ", len, batches,
	       handshakes, data);
	printf("errors %lu garbage %lu checksum %lld\n", errors, p.garbage, sum);
	fclose(uf);
	free(buf);
	return 0;
}
