// SPDX-License-Identifier: GPL-2.0
/*
 * NXT transaction benchmark client: GetBatteryLevel in a loop from N threads.
 *
 *   nxt_bench_client dev NODE THREADS SECONDS EXPECT_MV
 *   nxt_bench_client libusb VID:PID THREADS SECONDS EXPECT_MV
 *
 * dev:    every thread opens NODE (/dev/nxtN) itself and does what a C
 *         program on the telegram ABI does: liblegonxt builds the telegram
 *         (lnxt_get_battery_level()), NXT_IOC_TRANSACT sends it and returns
 *         the reply, liblegonxt checks that the reply answers it
 *         (lnxt_reply_check()) and reads the millivolts
 *         (lnxt_parse_battery_level()); the driver serialises the brick.
 * libusb: one libusb-1.0 handle with interface 0 claimed (the kernel driver
 *         must be unbound first); the threads share it and take a mutex
 *         around each bulk OUT 0x01 (00 0B) + bulk IN 0x82, since the NXT
 *         protocol has no transaction ids and a reply belongs to whoever
 *         reads next: this is what a libusb program has to do.
 *
 * Every reply is checked (dev: by liblegonxt; libusb: length 5, 02 0B,
 * status 0 by hand; both: the millivolts equal EXPECT_MV); a failed or
 * mismatched transaction counts as an error. Runs for SECONDS, then prints
 * one JSON object on stdout: clients, ok, errors, seconds, tps, p50_us,
 * p99_us, max_us, first_error.
 * Exit status: 0 when it ran (errors are reported, not fatal), 1 on a setup
 * failure, 2 on a usage error.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#include <legonxt.h>
#include <libusb.h>
#include <linux/lego_nxt.h>
#include <linux/types.h>

#define MAX_THREADS	64
#define MAX_SAMPLES	262144
#define EP_OUT		0x01
#define EP_IN		0x82
#define USB_TIMEOUT_MS	2000

struct worker {
	pthread_t tid;
	int index;
	unsigned long ok, errors;
	__u32 *lat_us;	/* latencies of the successful transactions */
	size_t nlat;
	char first_error[128];
};

static int use_libusb;
static const char *node;
static unsigned int expect_mv;
static double stop_at;
static libusb_device_handle *usb;
static pthread_mutex_t usb_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_barrier_t start_barrier;

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec / 1e9;
}

static void fail(struct worker *w, const char *fmt, ...)
{
	va_list ap;

	w->errors++;
	if (w->first_error[0])
		return;
	va_start(ap, fmt);
	vsnprintf(w->first_error, sizeof(w->first_error), fmt, ap);
	va_end(ap);
}

/*
 * One GetBatteryLevel through /dev/nxtN, built, checked and parsed by
 * liblegonxt around NXT_IOC_TRANSACT: 0 when the reply checks out.
 */
static int dev_transaction(struct worker *w, int fd)
{
	struct nxt_transaction t;
	struct lnxt_msg m;
	const char *why;
	uint16_t mv;
	int status;

	lnxt_get_battery_level(&m);
	memset(&t, 0, sizeof(t));
	memcpy(t.telegram, m.buf, m.len);
	t.length = m.len;
	if (ioctl(fd, NXT_IOC_TRANSACT, &t) < 0) {
		fail(w, "NXT_IOC_TRANSACT: %s", strerror(errno));
		return -1;
	}
	status = lnxt_reply_check(&m, t.reply, t.reply_length);
	if (status < 0) {
		fail(w, "reply does not answer GetBatteryLevel: %u bytes %02x %02x", t.reply_length,
		     t.reply[0], t.reply[1]);
		return -1;
	}
	if (status) {
		why = lnxt_status_name(status);
		fail(w, "brick status 0x%02x (%s)", status, why ? why : "unknown");
		return -1;
	}
	if (lnxt_parse_battery_level(t.reply, t.reply_length, &mv)) {
		fail(w, "GetBatteryLevel reply of %u bytes", t.reply_length);
		return -1;
	}
	if (mv != expect_mv) {
		fail(w, "reply status 0, %u mV", mv);
		return -1;
	}
	return 0;
}

/* One GetBatteryLevel over libusb: 0 when the reply checks out. */
static int usb_transaction(struct worker *w)
{
	unsigned char cmd[2] = { 0x00, 0x0b }, reply[64];
	int sent = 0, got = 0, r;

	pthread_mutex_lock(&usb_lock);
	r = libusb_bulk_transfer(usb, EP_OUT, cmd, sizeof(cmd), &sent, USB_TIMEOUT_MS);
	if (r == 0 && sent == sizeof(cmd))
		r = libusb_bulk_transfer(usb, EP_IN, reply, sizeof(reply), &got,
					 USB_TIMEOUT_MS);
	pthread_mutex_unlock(&usb_lock);
	if (r != 0) {
		fail(w, "bulk transfer: %s", libusb_error_name(r));
		return -1;
	}
	if (sent != sizeof(cmd)) {
		fail(w, "short bulk OUT: %d bytes", sent);
		return -1;
	}
	if (got != 5 || reply[0] != 0x02 || reply[1] != 0x0b || reply[2] != 0 ||
	    (unsigned int)(reply[3] | reply[4] << 8) != expect_mv) {
		fail(w, "bad reply: %d bytes %02x %02x %02x", got, reply[0], reply[1],
		     reply[2]);
		return -1;
	}
	return 0;
}

static void *run(void *arg)
{
	struct worker *w = arg;
	int fd = -1;
	double t0, t1;
	int r;

	if (!use_libusb) {
		fd = open(node, O_RDWR | O_CLOEXEC);
		if (fd < 0)
			fail(w, "open %s: %s", node, strerror(errno));
	}
	pthread_barrier_wait(&start_barrier);
	if (!use_libusb && fd < 0)
		return NULL;
	while ((t0 = now()) < stop_at) {
		r = use_libusb ? usb_transaction(w) : dev_transaction(w, fd);
		t1 = now();
		if (r)
			continue;
		w->ok++;
		if (w->nlat < MAX_SAMPLES)
			w->lat_us[w->nlat++] = (__u32)((t1 - t0) * 1e6 + 0.5);
	}
	if (fd >= 0)
		close(fd);
	return NULL;
}

static int cmp_u32(const void *a, const void *b)
{
	__u32 x = *(const __u32 *)a, y = *(const __u32 *)b;

	return x < y ? -1 : x > y;
}

static __u32 percentile(const __u32 *v, size_t n, double p)
{
	size_t i;

	if (!n)
		return 0;
	i = (size_t)(p / 100.0 * (n - 1) + 0.5);
	return v[i < n ? i : n - 1];
}

static int open_libusb(const char *vidpid)
{
	unsigned int vid, pid;
	int r;

	if (sscanf(vidpid, "%x:%x", &vid, &pid) != 2) {
		fprintf(stderr, "nxt_bench_client: VID:PID expected, got %s\n", vidpid);
		return -1;
	}
	r = libusb_init(NULL);
	if (r) {
		fprintf(stderr, "nxt_bench_client: libusb_init: %s\n", libusb_error_name(r));
		return -1;
	}
	usb = libusb_open_device_with_vid_pid(NULL, vid, pid);
	if (!usb) {
		fprintf(stderr, "nxt_bench_client: no USB device %04x:%04x\n", vid, pid);
		return -1;
	}
	r = libusb_claim_interface(usb, 0);
	if (r) {
		fprintf(stderr, "nxt_bench_client: claim interface 0: %s\n",
			libusb_error_name(r));
		return -1;
	}
	return 0;
}

int main(int argc, char **argv)
{
	static struct worker workers[MAX_THREADS];
	unsigned long ok = 0, errors = 0;
	const char *first_error = "";
	double seconds, start, elapsed;
	__u32 *all;
	size_t n = 0;
	int threads, i;

	if (argc != 6 || (strcmp(argv[1], "dev") && strcmp(argv[1], "libusb"))) {
		fprintf(stderr, "usage: %s dev NODE|libusb VID:PID THREADS SECONDS EXPECT_MV\n",
			argv[0]);
		return 2;
	}
	use_libusb = !strcmp(argv[1], "libusb");
	node = argv[2];
	threads = atoi(argv[3]);
	seconds = atof(argv[4]);
	expect_mv = (unsigned int)strtoul(argv[5], NULL, 0);
	if (threads < 1 || threads > MAX_THREADS || seconds <= 0) {
		fprintf(stderr, "nxt_bench_client: 1..%d threads and SECONDS > 0\n", MAX_THREADS);
		return 2;
	}
	if (use_libusb && open_libusb(node))
		return 1;

	pthread_barrier_init(&start_barrier, NULL, threads + 1);
	for (i = 0; i < threads; i++) {
		workers[i].index = i;
		workers[i].lat_us = malloc(MAX_SAMPLES * sizeof(__u32));
		if (!workers[i].lat_us) {
			perror("nxt_bench_client: malloc");
			return 1;
		}
		stop_at = 1e30;
		if (pthread_create(&workers[i].tid, NULL, run, &workers[i])) {
			perror("nxt_bench_client: pthread_create");
			return 1;
		}
	}
	start = now();
	stop_at = start + seconds;
	__atomic_thread_fence(__ATOMIC_SEQ_CST);
	pthread_barrier_wait(&start_barrier);
	for (i = 0; i < threads; i++)
		pthread_join(workers[i].tid, NULL);
	elapsed = now() - start;

	all = malloc((size_t)threads * MAX_SAMPLES * sizeof(__u32));
	if (!all) {
		perror("nxt_bench_client: malloc");
		return 1;
	}
	for (i = 0; i < threads; i++) {
		ok += workers[i].ok;
		errors += workers[i].errors;
		memcpy(all + n, workers[i].lat_us, workers[i].nlat * sizeof(__u32));
		n += workers[i].nlat;
		if (!first_error[0] && workers[i].first_error[0])
			first_error = workers[i].first_error;
	}
	qsort(all, n, sizeof(*all), cmp_u32);
	printf("{\"clients\": %d, \"ok\": %lu, \"errors\": %lu, ", threads, ok, errors);
	printf("\"seconds\": %.3f, \"tps\": %.2f, ", elapsed, ok / elapsed);
	printf("\"p50_us\": %u, \"p99_us\": %u, \"max_us\": %u, ",
	       percentile(all, n, 50), percentile(all, n, 99), n ? all[n - 1] : 0);
	printf("\"first_error\": \"%s\"}\n", first_error);
	if (usb) {
		libusb_release_interface(usb, 0);
		libusb_close(usb);
		libusb_exit(NULL);
	}
	return 0;
}
