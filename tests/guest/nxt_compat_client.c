// SPDX-License-Identifier: GPL-2.0
/*
 * A 32-bit client of /dev/nxtN: every ioctl of include/uapi/linux/lego_nxt.h
 * through the driver's compat_ioctl (compat_ptr_ioctl), which is right only
 * if struct nxt_transaction has the same layout on i386 as on x86_64, and
 * the ioctl numbers the header does not have, the retired typed ones
 * included, which must fail with ENOTTY. tests/build-modules.sh builds it
 * with gcc -m32 -static; tests/guest/test_nxt_compat.py runs it against the
 * emulated brick.
 *
 *   nxt-compat-client --layout
 *	prints the size and the members' offsets of struct nxt_transaction,
 *	the header's constants and its ioctl numbers as this (32-bit)
 *	compiler sees them, one "name value" a line;
 *   nxt-compat-client NODE BATTERY_MV SLEEP_LIMIT_MS DISTANCE_CM SOUND_RAW
 *	sends telegrams through NXT_IOC_TRANSACT on NODE and checks each
 *	reply byte for byte against what the emulated brick answers
 *	(tests/emulator/nxt_brick.py), given the brick's battery voltage,
 *	sleep limit, ultrasonic distance and the raw value of its sound
 *	sensor on port 2; checks the telegrams the driver must refuse, the
 *	timeouts, and ENOTTY for the numbers it does not know. The brick must
 *	have no program running, the sensors of its default set (sound on
 *	port 2, ultrasonic on port 4) and its IOMaps as they start.
 *
 * The brick's status byte is data: a reply that says the brick refused a
 * command is a successful NXT_IOC_TRANSACT.
 *
 * Prints "FAIL NAME: why" for every failed check, then "ok NAME" for each
 * of TRANSACT, SET_TIMEOUT, GET_TIMEOUT, RETIRED (the numbers of the typed
 * ioctls of earlier releases) and UNKNOWN (other numbers of the header's
 * magic) that was called and passed all its checks, and "telegrams N", the
 * number of calls that reached the brick; exits 1 if a check failed.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>
#include <linux/lego_nxt.h>

#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))

enum { I_TRANSACT, I_SET_TIMEOUT, I_GET_TIMEOUT, I_RETIRED, I_UNKNOWN, I_COUNT };

static const struct {
	const char *name;
	unsigned long nr;
} iocs[I_COUNT] = {
	{ "TRANSACT", NXT_IOC_TRANSACT },
	{ "SET_TIMEOUT", NXT_IOC_SET_TIMEOUT },
	{ "GET_TIMEOUT", NXT_IOC_GET_TIMEOUT },
	{ "RETIRED", 0 },
	{ "UNKNOWN", 0 },
};

/*
 * The typed ioctls of the releases before the driver went into the kernel:
 * _IOWR(NXT_IOC_MAGIC, 0x10 + opcode, the command's structure), the same
 * on i386 and x86_64. No argument was larger than 64 bytes.
 */
#define RETIRED_ARG_MAX	64

static const struct {
	const char *name;
	unsigned long nr;
} retired[] = {
	{ "START_PROGRAM", 0xc018e410 },
	{ "STOP_PROGRAM", 0xc004e411 },
	{ "PLAY_SOUND_FILE", 0xc018e412 },
	{ "PLAY_TONE", 0xc008e413 },
	{ "SET_OUTPUT_STATE", 0xc018e414 },
	{ "SET_INPUT_MODE", 0xc004e415 },
	{ "GET_OUTPUT_STATE", 0xc018e416 },
	{ "GET_INPUT_VALUES", 0xc010e417 },
	{ "RESET_INPUT_SCALED_VALUE", 0xc004e418 },
	{ "MESSAGE_WRITE", 0xc040e419 },
	{ "RESET_MOTOR_POSITION", 0xc004e41a },
	{ "GET_BATTERY_LEVEL", 0xc004e41b },
	{ "STOP_SOUND_PLAYBACK", 0xc004e41c },
	{ "KEEP_ALIVE", 0xc008e41d },
	{ "LS_GET_STATUS", 0xc004e41e },
	{ "LS_WRITE", 0xc014e41f },
	{ "LS_READ", 0xc014e420 },
	{ "GET_CURRENT_PROGRAM_NAME", 0xc018e421 },
	{ "MESSAGE_READ", 0xc040e423 },
};

/* The firmware's status bytes that the emulated brick answers here. */
#define STATUS_SUCCESS		0x00
#define STATUS_PENDING		0x20
#define STATUS_NO_PROGRAM	0xec
#define STATUS_ILLEGAL_VALUE	0xc0
#define STATUS_NOT_READY	0xe0

/* Calls of each kind, and failed checks. */
static unsigned int calls[I_COUNT], failed[I_COUNT];

static unsigned int telegrams;
static unsigned int failures;

/* Errnos that a call refused before anything reached the brick returns. */
static int refused(int err)
{
	return err == EINVAL || err == EMSGSIZE || err == EBADF || err == ENOTTY ||
	       err == EFAULT || err == EAGAIN;
}

/* ioctl() with number @nr: 0 or the errno. Counts the call, and the telegram it sent. */
static int call_nr(int fd, int which, unsigned long nr, void *arg)
{
	int err;

	calls[which]++;
	err = ioctl(fd, nr, arg) ? errno : 0;
	if (which == I_TRANSACT && !refused(err))
		telegrams++;
	return err;
}

static int call(int fd, int which, void *arg)
{
	return call_nr(fd, which, iocs[which].nr, arg);
}

static void fail(int which, const char *fmt, ...)
{
	va_list ap;

	failed[which]++;
	failures++;
	printf("FAIL %s: ", iocs[which].name);
	va_start(ap, fmt);
	vprintf(fmt, ap);
	va_end(ap);
	putchar('\n');
}

#define EXPECT(which, cond, ...)				\
	do {							\
		if (!(cond))					\
			fail(which, __VA_ARGS__);		\
	} while (0)

/* The errno's name; numbers in a buffer of two, for two in one message. */
static const char *err_name(int err)
{
	static char bufs[2][16];
	static unsigned int n;
	char *buf = bufs[n++ % 2];

	switch (err) {
	case 0: return "0";
	case EINVAL: return "EINVAL";
	case ENOTTY: return "ENOTTY";
	case EFAULT: return "EFAULT";
	case EBADF: return "EBADF";
	case EMSGSIZE: return "EMSGSIZE";
	case ERANGE: return "ERANGE";
	case ESRCH: return "ESRCH";
	case ENOMSG: return "ENOMSG";
	case EBUSY: return "EBUSY";
	case EINPROGRESS: return "EINPROGRESS";
	case ETIMEDOUT: return "ETIMEDOUT";
	case EPROTO: return "EPROTO";
	case EIO: return "EIO";
	}
	snprintf(buf, sizeof(bufs[0]), "errno %d", err);
	return buf;
}

/* A call's result @got, which must be @want (0 or an errno). */
static void expect_err(int which, int got, int want, const char *what)
{
	if (got != want)
		fail(which, "%s: %s, expected %s", what, err_name(got), err_name(want));
}

/* Bytes in hex, for messages; a buffer of two, for two in one message. */
static const char *hex(const void *p, size_t n)
{
	static char bufs[2][3 * NXT_TELEGRAM_MAX + 1];
	static unsigned int k;
	char *buf = bufs[k++ % 2];
	const unsigned char *b = p;
	size_t i;

	buf[0] = 0;
	for (i = 0; i < n && i < NXT_TELEGRAM_MAX; i++)
		sprintf(buf + 3 * i, "%02x%s", b[i], i + 1 < n ? " " : "");
	return buf;
}

/*
 * poll() with no file: its timeout is in milliseconds, so it needs none of
 * the 32-bit time syscalls (glibc's nanosleep() uses clock_nanosleep with a
 * 32-bit time_t when the time fits, which a kernel without
 * CONFIG_COMPAT_32BIT_TIME refuses with ENOSYS).
 */
static void sleep_ms(unsigned int ms)
{
	if (poll(NULL, 0, ms) < 0) {
		printf("FAIL: poll() to sleep %u ms: %s\n", ms, strerror(errno));
		failures++;
	}
}

static int all_bytes(const void *p, int c, size_t n)
{
	const unsigned char *b = p;

	while (n--)
		if (*b++ != c)
			return 0;
	return 1;
}

/* The telegrams' filler: what the driver must neither read nor change. */
#define FILL	0xa5

/*
 * A telegram through NXT_IOC_TRANSACT: the errno. On success, checks what
 * came back besides the reply: the telegram and its length as they were,
 * the filler past the telegram, zeros past the reply.
 */
static int transact(int fd, struct nxt_transaction *t, const void *tg, size_t len,
		    const char *what)
{
	int err;

	memset(t, FILL, sizeof(*t));
	memcpy(t->telegram, tg, len);
	t->length = len;
	err = call(fd, I_TRANSACT, t);
	if (err)
		return err;
	EXPECT(I_TRANSACT, t->length == len && !memcmp(t->telegram, tg, len) &&
	       all_bytes(t->telegram + len, FILL, sizeof(t->telegram) - len),
	       "%s: the telegram came back changed: length %u, %s", what, t->length,
	       hex(t->telegram, t->length <= NXT_TELEGRAM_MAX ? t->length : 0));
	EXPECT(I_TRANSACT, t->reply_length <= NXT_TELEGRAM_MAX &&
	       all_bytes(t->reply + t->reply_length, 0, NXT_TELEGRAM_MAX - t->reply_length),
	       "%s: reply_length %u, reply not zero past it: %s", what, t->reply_length,
	       hex(t->reply, NXT_TELEGRAM_MAX));
	return 0;
}

/* A telegram whose reply must be @want, @want_len bytes, exactly: the errno. */
static int expect_reply(int fd, const void *tg, size_t len, const void *want,
			size_t want_len, const char *what)
{
	struct nxt_transaction t;
	int err;

	err = transact(fd, &t, tg, len, what);
	expect_err(I_TRANSACT, err, 0, what);
	if (err)
		return err;
	EXPECT(I_TRANSACT, t.reply_length == want_len && !memcmp(t.reply, want, want_len),
	       "%s: reply %s, expected %s", what,
	       hex(t.reply, t.reply_length <= NXT_TELEGRAM_MAX ? t.reply_length : 0),
	       hex(want, want_len));
	return 0;
}

static void test_timeouts(int fd)
{
	__u32 ms = 0;
	int err;

	err = call(fd, I_GET_TIMEOUT, &ms);
	expect_err(I_GET_TIMEOUT, err, 0, "default");
	EXPECT(I_GET_TIMEOUT, ms == 1000, "default timeout %u ms, expected 1000", ms);
	ms = 60000;
	expect_err(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), 0, "60000 ms");
	ms = 0;
	expect_err(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0, "after 60000 ms");
	EXPECT(I_GET_TIMEOUT, ms == 60000, "timeout %u ms after setting 60000", ms);
	ms = 2500;
	expect_err(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), 0, "2500 ms");
	ms = 0;
	expect_err(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), EINVAL, "0 ms");
	ms = 60001;
	expect_err(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), EINVAL, "60001 ms");
	ms = 0;
	expect_err(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0, "after 2500 ms");
	EXPECT(I_GET_TIMEOUT, ms == 2500, "timeout %u ms after setting 2500", ms);
}

static void put_le16(unsigned char *p, unsigned int v)
{
	p[0] = v;
	p[1] = v >> 8;
}

static void put_le32(unsigned char *p, unsigned int v)
{
	put_le16(p, v);
	put_le16(p + 2, v >> 16);
}

/* The emulated brick's IOMap of the input module, as it starts. */
#define INPUT_MODULE	0x00030001u
#define IOMAP_OFFSET	17
#define IOMAP_COUNT	55	/* a 64-byte reply */

static unsigned char iomap_pattern(unsigned int module, unsigned int offset)
{
	return offset + 37 * ((module >> 16) & 0xff) + (module & 0xff);
}

/* Replies of every size, from the brick's own values and the client's. */
static void test_replies(int fd, unsigned int mv, unsigned int sleep_limit)
{
	static const unsigned char versions[] = { 0x01, 0x88 };
	static const unsigned char versions_r[] = { 0x02, 0x88, 0x00, 0x7c, 0x01, 0x1d, 0x01 };
	static const unsigned char battery[] = { 0x00, 0x0b };
	static const unsigned char keep_alive[] = { 0x00, 0x0d };
	static const unsigned char missing[] = "\x00\x00Missing.rxe";
	static const unsigned char missing_r[] = { 0x02, 0x00, STATUS_ILLEGAL_VALUE };
	static const unsigned char program[] = { 0x00, 0x11 };
	unsigned char want[NXT_TELEGRAM_MAX], tg[NXT_TELEGRAM_MAX];
	unsigned int i;

	/* GetVersions: protocol 1.124, firmware 1.29. */
	expect_reply(fd, versions, sizeof(versions), versions_r, sizeof(versions_r),
		     "GetVersions");

	memcpy(want, "\x02\x0b\x00", 3);
	put_le16(want + 3, mv);
	expect_reply(fd, battery, sizeof(battery), want, 5, "GetBatteryLevel");

	memcpy(want, "\x02\x0d\x00", 3);
	put_le32(want + 3, sleep_limit);
	expect_reply(fd, keep_alive, sizeof(keep_alive), want, 7, "KeepAlive");

	/* The brick's refusal is data: the call succeeds, the status says it. */
	expect_reply(fd, missing, sizeof(missing), missing_r, sizeof(missing_r),
		     "StartProgram of a missing file");
	memset(want, 0, sizeof(want));
	memcpy(want, "\x02\x11", 2);
	want[2] = STATUS_NO_PROGRAM;
	expect_reply(fd, program, sizeof(program), want, 23,
		     "GetCurrentProgramName with no program");

	/*
	 * ReadIOMap: a telegram of 64 bytes (the command reads 10; the rest
	 * is the brick's to ignore) and a reply of 64.
	 */
	memset(tg, 0x5a, sizeof(tg));
	tg[0] = NXT_SYSTEM_CMD;
	tg[1] = 0x94;
	put_le32(tg + 2, INPUT_MODULE);
	put_le16(tg + 6, IOMAP_OFFSET);
	put_le16(tg + 8, IOMAP_COUNT);
	memcpy(want, "\x02\x94\x00", 3);
	put_le32(want + 3, INPUT_MODULE);
	put_le16(want + 7, IOMAP_COUNT);
	for (i = 0; i < IOMAP_COUNT; i++)
		want[9 + i] = iomap_pattern(INPUT_MODULE, IOMAP_OFFSET + i);
	expect_reply(fd, tg, sizeof(tg), want, 9 + IOMAP_COUNT, "ReadIOMap of 55 bytes");
}

/*
 * GetInputValues of @port: 0, the errno, or -1 for a reply that is not the
 * command's; @reply gets the reply's 16 bytes.
 */
static int input_values(int fd, unsigned char port, unsigned char *reply)
{
	unsigned char tg[] = { 0x00, 0x07, port };
	struct nxt_transaction t;
	int err;

	err = transact(fd, &t, tg, sizeof(tg), "GetInputValues");
	expect_err(I_TRANSACT, err, 0, "GetInputValues");
	if (err)
		return err;
	if (t.reply_length != 16 || memcmp(t.reply, "\x02\x07\x00", 3) || t.reply[3] != port) {
		fail(I_TRANSACT, "GetInputValues of port %u: reply %s", port,
		     hex(t.reply, t.reply_length));
		return -1;
	}
	memcpy(reply, t.reply, 16);
	return 0;
}

/* The sound sensor on port 2 (1): a no-reply telegram, then its values. */
static void test_sound_sensor(int fd, unsigned int raw)
{
	/* SetInputMode: port 1, SOUND_DB, PCTFULLSCALEMODE; no reply. */
	static const unsigned char pct[] = { NXT_DIRECT_CMD_NOREPLY, 0x05, 1, 0x07, 0x80 };
	static const unsigned char raw_mode[] = { 0x00, 0x05, 1, 0x07, 0x00 };
	static const unsigned char ok_r[] = { 0x02, 0x05, STATUS_SUCCESS };
	unsigned int scaled = (1023 - raw) * 100 / 1023;
	unsigned char want[16], got[16] = { 0 };
	struct nxt_transaction t;
	int err, i;

	err = transact(fd, &t, pct, sizeof(pct), "no-reply SetInputMode");
	expect_err(I_TRANSACT, err, 0, "no-reply SetInputMode");
	EXPECT(I_TRANSACT, err || (t.reply_length == 0 && all_bytes(t.reply, 0, sizeof(t.reply))),
	       "no-reply telegram: reply_length %u, reply %s", t.reply_length,
	       hex(t.reply, sizeof(t.reply)));

	/* port, valid, calibrated, type, mode, raw, normalized, scaled, calibrated value */
	memcpy(want, "\x02\x07\x00\x01\x01\x00\x07\x80", 8);
	put_le16(want + 8, raw);
	put_le16(want + 10, raw);
	put_le16(want + 12, scaled);
	put_le16(want + 14, raw);
	for (i = 0; i < 100; i++) {
		if (input_values(fd, 1, got) || got[4])
			break;
		sleep_ms(20);
	}
	EXPECT(I_TRANSACT, !memcmp(got, want, 16), "sound sensor in percent: reply %s, expected %s",
	       hex(got, 16), hex(want, 16));

	expect_reply(fd, raw_mode, sizeof(raw_mode), ok_r, sizeof(ok_r), "SetInputMode");
	want[7] = 0x00;
	put_le16(want + 12, raw);
	if (!input_values(fd, 1, got))
		EXPECT(I_TRANSACT, !memcmp(got, want, 4) && !memcmp(got + 5, want + 5, 11),
		       "sound sensor raw: reply %s, expected %s (valid or not)", hex(got, 16),
		       hex(want, 16));
}

/*
 * LSGetStatus of port 3 until its status is no longer @busy: the last
 * status; *ready the bytes ready. Every reply is 4 bytes, the count 0
 * unless the status is success.
 */
static int ls_status(int fd, unsigned char busy, unsigned int *ready)
{
	static const unsigned char tg[] = { 0x00, 0x0e, 3 };
	struct nxt_transaction t;
	int i, err, status = -1;

	*ready = 0;
	for (i = 0; i < 500; i++) {
		err = transact(fd, &t, tg, sizeof(tg), "LSGetStatus");
		expect_err(I_TRANSACT, err, 0, "LSGetStatus");
		if (err)
			return -1;
		if (t.reply_length != 4 || memcmp(t.reply, "\x02\x0e", 2) ||
		    (t.reply[2] != STATUS_SUCCESS && t.reply[3])) {
			fail(I_TRANSACT, "LSGetStatus: reply %s", hex(t.reply, t.reply_length));
			return -1;
		}
		status = t.reply[2];
		*ready = t.reply[3];
		if (status != busy)
			break;
		sleep_ms(status == STATUS_PENDING ? 2 : 20);
	}
	return status;
}

/* The ultrasonic sensor on port 4 (3): statuses that are not errors. */
static void test_ultrasonic(int fd, unsigned int distance)
{
	static const unsigned char mode[] = { 0x00, 0x05, 3, 0x0b, 0x00 };
	static const unsigned char mode_r[] = { 0x02, 0x05, STATUS_SUCCESS };
	static const unsigned char ls_write[] = { 0x00, 0x0f, 3, 2, 1, 0x02, 0x42 };
	static const unsigned char ls_write_r[] = { 0x02, 0x0f, STATUS_SUCCESS };
	static const unsigned char ls_read[] = { 0x00, 0x10, 3 };
	static const unsigned char ls_read0[] = { 0x00, 0x10, 0 };
	unsigned char want[20];
	unsigned int ready;
	int status;

	/* LOWSPEED_9V: the channel is not ready until the sensor settles. */
	expect_reply(fd, mode, sizeof(mode), mode_r, sizeof(mode_r), "SetInputMode");
	status = ls_status(fd, STATUS_NOT_READY, &ready);
	EXPECT(I_TRANSACT, status == STATUS_SUCCESS && ready == 0,
	       "LSGetStatus after settling: status 0x%02x, %u bytes ready", status, ready);

	/* Register 0x42, the distance: pending, then one byte. */
	if (!expect_reply(fd, ls_write, sizeof(ls_write), ls_write_r, sizeof(ls_write_r),
			  "LSWrite")) {
		status = ls_status(fd, STATUS_PENDING, &ready);
		EXPECT(I_TRANSACT, status == STATUS_SUCCESS && ready == 1,
		       "LSGetStatus after LSWrite: status 0x%02x, %u bytes ready", status,
		       ready);
	}
	memset(want, 0, sizeof(want));
	memcpy(want, "\x02\x10\x00\x01", 4);
	want[4] = distance;
	expect_reply(fd, ls_read, sizeof(ls_read), want, sizeof(want), "LSRead");

	/* Port 1 (0) is no low-speed port: the firmware's channel not ready. */
	memset(want, 0, sizeof(want));
	memcpy(want, "\x02\x10", 2);
	want[2] = STATUS_NOT_READY;
	expect_reply(fd, ls_read0, sizeof(ls_read0), want, sizeof(want), "LSRead of port 1");
}

/* The telegrams the driver refuses: nothing sent, the structure untouched. */
static void test_refused(int fd)
{
	static const struct {
		const char *what;
		unsigned char tg[NXT_TELEGRAM_MAX];
		__u32 length;
		int err;
	} cases[] = {
		{ "65 bytes", { 0x00, 0x0b }, NXT_TELEGRAM_MAX + 1, EMSGSIZE },
		{ "length 0xffffffff", { 0x00, 0x0b }, 0xffffffff, EMSGSIZE },
		{ "1 byte", { 0x00, 0x0b }, 1, EINVAL },
		{ "0 bytes", { 0x00, 0x0b }, 0, EINVAL },
		{ "a reply", { 0x02, 0x0b, 0x00, 0x1c, 0x1d }, 5, EINVAL },
		{ "type 0x7f", { 0x7f, 0x0b }, 2, EINVAL },
		{ "StartProgram, no NUL", { 0x00, 0x00, 'a', 'b', 'c' }, 5, EINVAL },
		{ "SetOutputState, 11 bytes", { 0x00, 0x04, 0x01, 50 }, 11, EINVAL },
		{ "MessageWrite short of its size", { 0x00, 0x09, 0x01, 10, 'h', 'i' }, 6, EINVAL },
		{ "ReadIOMap, 9 bytes", { 0x01, 0x94, 0x01, 0x00, 0x03 }, 9, EINVAL },
	};
	struct nxt_transaction t, saved;
	unsigned int i;
	int err;

	for (i = 0; i < ARRAY_SIZE(cases); i++) {
		memset(&t, FILL, sizeof(t));
		memcpy(t.telegram, cases[i].tg, sizeof(t.telegram));
		t.length = cases[i].length;
		saved = t;
		err = call(fd, I_TRANSACT, &t);
		expect_err(I_TRANSACT, err, cases[i].err, cases[i].what);
		EXPECT(I_TRANSACT, !memcmp(&t, &saved, sizeof(t)),
		       "%s: refused, but the structure changed", cases[i].what);
	}
}

/* An unknown number: ENOTTY, and the buffer (at least its size) untouched. */
static void expect_enotty(int fd, int which, unsigned long nr, const char *what)
{
	unsigned char buf[sizeof(struct nxt_transaction)], saved[sizeof(buf)];
	unsigned int i;
	int err;

	if (_IOC_SIZE(nr) > sizeof(buf)) {
		fail(which, "%s: 0x%08lx needs a larger buffer", what, nr);
		return;
	}
	for (i = 0; i < sizeof(buf); i++)
		buf[i] = i * 7 + 1;
	memcpy(saved, buf, sizeof(buf));
	err = call_nr(fd, which, nr, buf);
	if (err != ENOTTY || memcmp(buf, saved, sizeof(buf)))
		fail(which, "%s (0x%08lx): %s%s, expected ENOTTY", what, nr, err_name(err),
		     memcmp(buf, saved, sizeof(buf)) ? " and the buffer changed" : "");
}

static void test_unknown(int fd)
{
	char what[64];
	unsigned int i;

	for (i = 0; i < ARRAY_SIZE(retired); i++) {
		snprintf(what, sizeof(what), "NXT_IOC_%s", retired[i].name);
		if (_IOC_TYPE(retired[i].nr) != NXT_IOC_MAGIC ||
		    _IOC_SIZE(retired[i].nr) > RETIRED_ARG_MAX)
			fail(I_RETIRED, "%s: 0x%08lx is no typed number", what, retired[i].nr);
		expect_enotty(fd, I_RETIRED, retired[i].nr, what);
	}
	/* Every other number the typed ioctls had room for. */
	for (i = 0x10; i <= 0x33; i++) {
		snprintf(what, sizeof(what), "_IOWR(NXT_IOC_MAGIC, 0x%02x, __u32)", i);
		expect_enotty(fd, I_RETIRED, _IOWR(NXT_IOC_MAGIC, i, __u32), what);
		snprintf(what, sizeof(what), "_IO(NXT_IOC_MAGIC, 0x%02x)", i);
		expect_enotty(fd, I_RETIRED, _IO(NXT_IOC_MAGIC, i), what);
	}

	/* The numbers of the three ioctls with another direction or size. */
	expect_enotty(fd, I_UNKNOWN, _IO(NXT_IOC_MAGIC, 0x00), "_IO(0x00)");
	expect_enotty(fd, I_UNKNOWN, _IOR(NXT_IOC_MAGIC, 0x00, struct nxt_transaction),
		      "_IOR(0x00, struct nxt_transaction)");
	expect_enotty(fd, I_UNKNOWN, _IOW(NXT_IOC_MAGIC, 0x00, struct nxt_transaction),
		      "_IOW(0x00, struct nxt_transaction)");
	expect_enotty(fd, I_UNKNOWN, _IOWR(NXT_IOC_MAGIC, 0x00, __u32), "_IOWR(0x00, __u32)");
	expect_enotty(fd, I_UNKNOWN, _IOR(NXT_IOC_MAGIC, 0x01, __u32), "_IOR(0x01, __u32)");
	expect_enotty(fd, I_UNKNOWN, _IOWR(NXT_IOC_MAGIC, 0x01, __u32), "_IOWR(0x01, __u32)");
	expect_enotty(fd, I_UNKNOWN, _IOW(NXT_IOC_MAGIC, 0x01, __u64), "_IOW(0x01, __u64)");
	expect_enotty(fd, I_UNKNOWN, _IOW(NXT_IOC_MAGIC, 0x02, __u32), "_IOW(0x02, __u32)");
	expect_enotty(fd, I_UNKNOWN, _IOR(NXT_IOC_MAGIC, 0x02, __u64), "_IOR(0x02, __u64)");
	for (i = 0x03; i <= 0xff; i++) {
		if (i >= 0x10 && i <= 0x33)
			continue;
		snprintf(what, sizeof(what), "_IOWR(NXT_IOC_MAGIC, 0x%02x, struct nxt_transaction)",
			 i);
		expect_enotty(fd, I_UNKNOWN, _IOWR(NXT_IOC_MAGIC, i, struct nxt_transaction),
			      what);
	}
}

/* Last: the test reads this tone back from the emulated brick. */
static void test_tone(int fd)
{
	/* PlayTone: 1234 Hz for 30 s. */
	static const unsigned char tone[] = { 0x00, 0x03, 0xd2, 0x04, 0x30, 0x75 };
	static const unsigned char tone_r[] = { 0x02, 0x03, STATUS_SUCCESS };

	expect_reply(fd, tone, sizeof(tone), tone_r, sizeof(tone_r), "PlayTone");
}

/* A file opened read-only: the timeouts work, nothing is sent. */
static void test_read_only(const char *node)
{
	struct nxt_transaction t, saved;
	__u32 ms = 0;
	int fd;

	fd = open(node, O_RDONLY);
	if (fd < 0) {
		fail(I_TRANSACT, "open %s read-only: %s", node, strerror(errno));
		return;
	}
	expect_err(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0, "read-only file");
	EXPECT(I_GET_TIMEOUT, ms == 1000, "read-only file: timeout %u ms", ms);
	ms = 3000;
	expect_err(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), 0, "read-only file");
	ms = 0;
	expect_err(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0, "read-only file");
	EXPECT(I_GET_TIMEOUT, ms == 3000, "read-only file: timeout %u ms after 3000", ms);

	memset(&t, FILL, sizeof(t));
	memcpy(t.telegram, "\x00\x0b", 2);
	t.length = 2;
	saved = t;
	expect_err(I_TRANSACT, call(fd, I_TRANSACT, &t), EBADF, "read-only file");
	EXPECT(I_TRANSACT, !memcmp(&t, &saved, sizeof(t)),
	       "read-only file: EBADF, but the structure changed");
	expect_enotty(fd, I_RETIRED, retired[11].nr, "GET_BATTERY_LEVEL on a read-only file");
	close(fd);
}

#define OFFSET(t, m)	printf("%s.%s %zu\n", #t, #m, offsetof(struct nxt_##t, m))
#define VALUE(n)	printf("%s %lu\n", #n, (unsigned long)(n))

static void print_layout(void)
{
	int i;

	printf("transaction %zu\n", sizeof(struct nxt_transaction));
	OFFSET(transaction, telegram);
	OFFSET(transaction, reply);
	OFFSET(transaction, length);
	OFFSET(transaction, reply_length);
	VALUE(NXT_TELEGRAM_MIN);
	VALUE(NXT_TELEGRAM_MAX);
	VALUE(NXT_IOC_MAGIC);
	for (i = 0; i < I_COUNT; i++)
		if (iocs[i].nr)
			printf("%s %lu\n", iocs[i].name, iocs[i].nr);
	printf("long %zu\n", sizeof(long));
}

static unsigned int arg_uint(const char *s, const char *what)
{
	char *end;
	unsigned long v = strtoul(s, &end, 0);

	if (!*s || *end) {
		fprintf(stderr, "nxt-compat-client: bad %s \"%s\"\n", what, s);
		exit(2);
	}
	return v;
}

int main(int argc, char **argv)
{
	unsigned int mv, sleep_limit, distance, sound_raw;
	int fd, i;

	if (argc == 2 && !strcmp(argv[1], "--layout")) {
		print_layout();
		return 0;
	}
	if (argc != 6) {
		fprintf(stderr,
			"usage: nxt-compat-client --layout\n"
			"       nxt-compat-client NODE BATTERY_MV SLEEP_LIMIT_MS DISTANCE_CM SOUND_RAW\n");
		return 2;
	}
	mv = arg_uint(argv[2], "battery voltage");
	sleep_limit = arg_uint(argv[3], "sleep limit");
	distance = arg_uint(argv[4], "distance");
	sound_raw = arg_uint(argv[5], "sound sensor value");

	setvbuf(stdout, NULL, _IOLBF, 0);
	fd = open(argv[1], O_RDWR);
	if (fd < 0) {
		fprintf(stderr, "nxt-compat-client: open %s: %s\n", argv[1], strerror(errno));
		return 2;
	}
	test_timeouts(fd);
	test_replies(fd, mv, sleep_limit);
	test_sound_sensor(fd, sound_raw);
	test_ultrasonic(fd, distance);
	test_refused(fd);
	test_unknown(fd);
	test_tone(fd);
	close(fd);
	test_read_only(argv[1]);

	for (i = 0; i < I_COUNT; i++)
		if (calls[i] && !failed[i])
			printf("ok %s\n", iocs[i].name);
	printf("telegrams %u\n", telegrams);
	return failures ? 1 : 0;
}
