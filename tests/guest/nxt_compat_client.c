// SPDX-License-Identifier: GPL-2.0
/*
 * A 32-bit client of /dev/nxtN: every ioctl of include/uapi/linux/lego_nxt.h
 * through the driver's compat_ioctl (compat_ptr_ioctl), which is right only
 * if every structure has the same layout on i386 as on x86_64.
 * tests/build-modules.sh builds it with gcc -m32 -static;
 * tests/guest/test_nxt_compat.py runs it against the emulated brick.
 *
 *   nxt-compat-client --layout
 *	prints the sizes, the members' offsets and the ioctl numbers as this
 *	(32-bit) compiler sees them, one "name value" a line;
 *   nxt-compat-client NODE BATTERY_MV SLEEP_LIMIT_MS DISTANCE_CM SOUND_RAW
 *	issues every ioctl on NODE and checks each reply against what the
 *	emulated brick answers (tests/emulator/nxt_brick.py), given the
 *	brick's battery voltage, sleep limit, ultrasonic distance and the
 *	raw value of its sound sensor on port 2. The brick must have no
 *	program running and its motors at rest with zero counters.
 *
 * Prints "FAIL IOCTL: why" for every failed check, then "ok IOCTL" for
 * each ioctl that was called and passed all its checks, and "telegrams N",
 * the number of calls that reached the brick; exits 1 if a check failed.
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

enum {
	I_TRANSACT, I_SET_TIMEOUT, I_GET_TIMEOUT, I_START_PROGRAM,
	I_STOP_PROGRAM, I_PLAY_SOUND_FILE, I_PLAY_TONE, I_SET_OUTPUT_STATE,
	I_SET_INPUT_MODE, I_GET_OUTPUT_STATE, I_GET_INPUT_VALUES,
	I_RESET_INPUT_SCALED_VALUE, I_MESSAGE_WRITE, I_RESET_MOTOR_POSITION,
	I_GET_BATTERY_LEVEL, I_STOP_SOUND_PLAYBACK, I_KEEP_ALIVE,
	I_LS_GET_STATUS, I_LS_WRITE, I_LS_READ, I_GET_CURRENT_PROGRAM_NAME,
	I_MESSAGE_READ, I_COUNT
};

/* Every ioctl of the header, in the order of the enum above. */
#define IOC(n)	{ #n, NXT_IOC_##n }

static const struct {
	const char *name;
	unsigned long nr;
} iocs[I_COUNT] = {
	IOC(TRANSACT), IOC(SET_TIMEOUT), IOC(GET_TIMEOUT), IOC(START_PROGRAM),
	IOC(STOP_PROGRAM), IOC(PLAY_SOUND_FILE), IOC(PLAY_TONE),
	IOC(SET_OUTPUT_STATE), IOC(SET_INPUT_MODE), IOC(GET_OUTPUT_STATE),
	IOC(GET_INPUT_VALUES), IOC(RESET_INPUT_SCALED_VALUE),
	IOC(MESSAGE_WRITE), IOC(RESET_MOTOR_POSITION), IOC(GET_BATTERY_LEVEL),
	IOC(STOP_SOUND_PLAYBACK), IOC(KEEP_ALIVE), IOC(LS_GET_STATUS),
	IOC(LS_WRITE), IOC(LS_READ), IOC(GET_CURRENT_PROGRAM_NAME),
	IOC(MESSAGE_READ),
};

/* Calls of each ioctl, and failed checks. */
static unsigned int calls[I_COUNT], failed[I_COUNT];

static unsigned int telegrams;
static unsigned int failures;

/* Errnos that a call refused before anything reached the brick returns. */
static int refused(int err)
{
	return err == EINVAL || err == EMSGSIZE || err == EBADF || err == ENOTTY ||
	       err == EFAULT || err == EAGAIN;
}

/* ioctl(): 0 or the errno. Counts the call, and the telegram it sent. */
static int call(int fd, int which, void *arg)
{
	int err;

	calls[which]++;
	err = ioctl(fd, iocs[which].nr, arg) ? errno : 0;
	if (which != I_SET_TIMEOUT && which != I_GET_TIMEOUT && !refused(err))
		telegrams++;
	return err;
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
	case EIO: return "EIO";
	}
	snprintf(buf, sizeof(bufs[0]), "errno %d", err);
	return buf;
}

/* A call's result @got, which must be @want (0 or an errno). */
static void expect_err(int which, int got, int want, const char *func, int line)
{
	if (got != want)
		fail(which, "%s:%d: %s, expected %s", func, line, err_name(got),
		     err_name(want));
}

#define EXPECT_ERR(which, got, want) \
	expect_err(which, got, want, __func__, __LINE__)

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

static int all_zero(const void *p, size_t n)
{
	const unsigned char *b = p;

	while (n--)
		if (*b++)
			return 0;
	return 1;
}

static void test_timeouts(int fd)
{
	__u32 ms = 0;
	int err;

	err = call(fd, I_GET_TIMEOUT, &ms);
	EXPECT_ERR(I_GET_TIMEOUT, err, 0);
	EXPECT(I_GET_TIMEOUT, ms == 1000, "default timeout %u ms, expected 1000", ms);
	ms = 2500;
	EXPECT_ERR(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), 0);
	ms = 0;
	EXPECT_ERR(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), EINVAL);
	ms = 60001;
	EXPECT_ERR(I_SET_TIMEOUT, call(fd, I_SET_TIMEOUT, &ms), EINVAL);
	ms = 0;
	EXPECT_ERR(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0);
	EXPECT(I_GET_TIMEOUT, ms == 2500, "timeout %u ms after setting 2500", ms);
}

static void test_transact(int fd)
{
	static const __u8 versions[] = { 0x02, 0x88, 0x00, 0x7c, 0x01, 0x1d, 0x01 };
	struct nxt_transaction t;
	int err;

	/* GetVersions: protocol 1.124, firmware 1.29. */
	memset(&t, 0xa5, sizeof(t));
	t.telegram[0] = NXT_SYSTEM_CMD;
	t.telegram[1] = 0x88;
	t.length = 2;
	err = call(fd, I_TRANSACT, &t);
	EXPECT_ERR(I_TRANSACT, err, 0);
	if (!err) {
		EXPECT(I_TRANSACT, t.reply_length == sizeof(versions),
		       "GetVersions: reply_length %u, expected %zu", t.reply_length,
		       sizeof(versions));
		EXPECT(I_TRANSACT, !memcmp(t.reply, versions, sizeof(versions)),
		       "GetVersions: reply %02x %02x %02x %02x %02x %02x %02x",
		       t.reply[0], t.reply[1], t.reply[2], t.reply[3], t.reply[4],
		       t.reply[5], t.reply[6]);
		EXPECT(I_TRANSACT, all_zero(t.reply + sizeof(versions),
					    sizeof(t.reply) - sizeof(versions)),
		       "GetVersions: the reply is not zero past its length");
		EXPECT(I_TRANSACT, t.length == 2, "length changed to %u", t.length);
	}

	/* GetBatteryLevel as a raw direct command. */
	memset(&t, 0, sizeof(t));
	t.telegram[0] = NXT_DIRECT_CMD;
	t.telegram[1] = NXT_GET_BATTERY_LEVEL;
	t.length = 2;
	err = call(fd, I_TRANSACT, &t);
	EXPECT_ERR(I_TRANSACT, err, 0);
	EXPECT(I_TRANSACT, err || (t.reply_length == 5 && t.reply[0] == NXT_REPLY &&
				   t.reply[1] == NXT_GET_BATTERY_LEVEL && !t.reply[2]),
	       "GetBatteryLevel: reply_length %u, reply %02x %02x %02x",
	       t.reply_length, t.reply[0], t.reply[1], t.reply[2]);

	/* A telegram that asks for no reply: KeepAlive. */
	memset(&t, 0xa5, sizeof(t));
	t.telegram[0] = NXT_DIRECT_CMD_NOREPLY;
	t.telegram[1] = NXT_KEEP_ALIVE;
	t.length = 2;
	err = call(fd, I_TRANSACT, &t);
	EXPECT_ERR(I_TRANSACT, err, 0);
	EXPECT(I_TRANSACT, err || t.reply_length == 0,
	       "no-reply telegram: reply_length %u", t.reply_length);

	/* The length member is read where the driver reads it. */
	t.length = NXT_TELEGRAM_MAX + 1;
	EXPECT_ERR(I_TRANSACT, call(fd, I_TRANSACT, &t), EMSGSIZE);
	t.length = 1;
	EXPECT_ERR(I_TRANSACT, call(fd, I_TRANSACT, &t), EINVAL);
}

/* GetCurrentProgramName until a program runs (or none does): the errno. */
static int wait_program(int fd, int running, struct nxt_program *p)
{
	int i, err = 0;

	for (i = 0; i < 100; i++) {
		memset(p, 0, sizeof(*p));
		err = call(fd, I_GET_CURRENT_PROGRAM_NAME, p);
		if (running ? !err : err)
			break;
		sleep_ms(20);
	}
	return err;
}

static void test_program_and_mailboxes(int fd)
{
	static const char msg[] = "from 32 bits";
	struct nxt_status_only so;
	struct nxt_program p;
	struct nxt_message m;
	int err;

	/* No program runs yet. */
	memset(&p, 0x5a, sizeof(p));
	memset(p.reserved, 0, sizeof(p.reserved));
	err = call(fd, I_GET_CURRENT_PROGRAM_NAME, &p);
	EXPECT_ERR(I_GET_CURRENT_PROGRAM_NAME, err, ESRCH);
	EXPECT(I_GET_CURRENT_PROGRAM_NAME, p.status == NXT_STATUS_NO_PROGRAM &&
	       all_zero(p.name, sizeof(p.name)),
	       "no program: status 0x%02x, name \"%.20s\"", p.status, p.name);
	memset(&so, 0, sizeof(so));
	err = call(fd, I_STOP_PROGRAM, &so);
	EXPECT_ERR(I_STOP_PROGRAM, err, ESRCH);
	EXPECT(I_STOP_PROGRAM, so.status == NXT_STATUS_NO_PROGRAM,
	       "no program: status 0x%02x", so.status);
	so.reserved[2] = 1;
	EXPECT_ERR(I_STOP_PROGRAM, call(fd, I_STOP_PROGRAM, &so), EINVAL);

	memset(&p, 0, sizeof(p));
	snprintf(p.name, sizeof(p.name), "%s", "Missing.rxe");
	err = call(fd, I_START_PROGRAM, &p);
	EXPECT_ERR(I_START_PROGRAM, err, ERANGE);
	EXPECT(I_START_PROGRAM, p.status == NXT_STATUS_OUT_OF_RANGE,
	       "missing program: status 0x%02x", p.status);
	p.reserved[0] = 1;
	EXPECT_ERR(I_START_PROGRAM, call(fd, I_START_PROGRAM, &p), EINVAL);

	memset(&p, 0, sizeof(p));
	snprintf(p.name, sizeof(p.name), "%s", "Demo.rxe");
	err = call(fd, I_START_PROGRAM, &p);
	EXPECT_ERR(I_START_PROGRAM, err, 0);
	EXPECT(I_START_PROGRAM, p.status == 0 && !strcmp(p.name, "Demo.rxe"),
	       "status 0x%02x, name \"%.20s\"", p.status, p.name);
	err = wait_program(fd, 1, &p);
	EXPECT_ERR(I_GET_CURRENT_PROGRAM_NAME, err, 0);
	EXPECT(I_GET_CURRENT_PROGRAM_NAME, !strcmp(p.name, "Demo.rxe") && !p.status,
	       "running: name \"%.20s\", status 0x%02x", p.name, p.status);

	/* A message to inbox 3 and back (the emulated program's mailboxes). */
	memset(&m, 0, sizeof(m));
	m.inbox = 3;
	m.size = sizeof(msg);
	memcpy(m.data, msg, sizeof(msg));
	err = call(fd, I_MESSAGE_WRITE, &m);
	EXPECT_ERR(I_MESSAGE_WRITE, err, 0);
	EXPECT(I_MESSAGE_WRITE, m.status == 0, "status 0x%02x", m.status);
	m.inbox = NXT_INBOXES;
	EXPECT_ERR(I_MESSAGE_WRITE, call(fd, I_MESSAGE_WRITE, &m), EINVAL);
	m.inbox = 3;
	m.data[m.size - 1] = 'x';	/* no NUL */
	EXPECT_ERR(I_MESSAGE_WRITE, call(fd, I_MESSAGE_WRITE, &m), EINVAL);

	memset(&m, 0xee, sizeof(m));
	m.inbox = 3;
	m.local_inbox = 7;
	m.remove = 1;
	err = call(fd, I_MESSAGE_READ, &m);
	EXPECT_ERR(I_MESSAGE_READ, err, 0);
	EXPECT(I_MESSAGE_READ, !m.status && m.local_inbox == 7 && m.size == sizeof(msg) &&
	       !memcmp(m.data, msg, sizeof(msg)) &&
	       all_zero(m.data + sizeof(msg), sizeof(m.data) - sizeof(msg)),
	       "status 0x%02x, local_inbox %u, size %u, data \"%.59s\"",
	       m.status, m.local_inbox, m.size, m.data);
	m.inbox = 3;
	m.local_inbox = 7;
	m.remove = 1;
	m.status = 0x55;
	err = call(fd, I_MESSAGE_READ, &m);
	EXPECT_ERR(I_MESSAGE_READ, err, ENOMSG);
	EXPECT(I_MESSAGE_READ, m.status == NXT_STATUS_MAILBOX_EMPTY,
	       "empty mailbox: status 0x%02x", m.status);
	m.inbox = NXT_REMOTE_INBOXES;
	EXPECT_ERR(I_MESSAGE_READ, call(fd, I_MESSAGE_READ, &m), EINVAL);
	m.inbox = 0;
	m.remove = 2;
	EXPECT_ERR(I_MESSAGE_READ, call(fd, I_MESSAGE_READ, &m), EINVAL);

	memset(&so, 0, sizeof(so));
	so.status = 0x55;
	err = call(fd, I_STOP_PROGRAM, &so);
	EXPECT_ERR(I_STOP_PROGRAM, err, 0);
	EXPECT(I_STOP_PROGRAM, so.status == 0, "status 0x%02x", so.status);
	err = wait_program(fd, 0, &p);
	EXPECT_ERR(I_GET_CURRENT_PROGRAM_NAME, err, ESRCH);
}

static void test_sound(int fd)
{
	struct nxt_sound_file sf;
	struct nxt_status_only so;
	struct nxt_tone t;
	int err;

	memset(&sf, 0, sizeof(sf));
	snprintf(sf.name, sizeof(sf.name), "%s", "Woops.rso");
	sf.loop = 1;
	err = call(fd, I_PLAY_SOUND_FILE, &sf);
	EXPECT_ERR(I_PLAY_SOUND_FILE, err, 0);
	EXPECT(I_PLAY_SOUND_FILE, sf.status == 0 && sf.loop == 1,
	       "status 0x%02x, loop %u", sf.status, sf.loop);
	snprintf(sf.name, sizeof(sf.name), "%s", "Missing.rso");
	err = call(fd, I_PLAY_SOUND_FILE, &sf);
	EXPECT_ERR(I_PLAY_SOUND_FILE, err, ERANGE);
	EXPECT(I_PLAY_SOUND_FILE, sf.status == NXT_STATUS_OUT_OF_RANGE,
	       "missing file: status 0x%02x", sf.status);
	sf.loop = 2;
	EXPECT_ERR(I_PLAY_SOUND_FILE, call(fd, I_PLAY_SOUND_FILE, &sf), EINVAL);
	sf.loop = 0;
	sf.reserved[1] = 1;
	EXPECT_ERR(I_PLAY_SOUND_FILE, call(fd, I_PLAY_SOUND_FILE, &sf), EINVAL);

	memset(&so, 0, sizeof(so));
	so.status = 0x55;
	err = call(fd, I_STOP_SOUND_PLAYBACK, &so);
	EXPECT_ERR(I_STOP_SOUND_PLAYBACK, err, 0);
	EXPECT(I_STOP_SOUND_PLAYBACK, so.status == 0, "status 0x%02x", so.status);
	so.reserved[0] = 1;
	EXPECT_ERR(I_STOP_SOUND_PLAYBACK, call(fd, I_STOP_SOUND_PLAYBACK, &so), EINVAL);

	/* Last: the test reads this tone back from the emulated brick. */
	memset(&t, 0, sizeof(t));
	t.frequency = NXT_TONE_MIN_HZ - 1;
	t.duration = 10;
	EXPECT_ERR(I_PLAY_TONE, call(fd, I_PLAY_TONE, &t), EINVAL);
	t.frequency = NXT_TONE_MAX_HZ + 1;
	EXPECT_ERR(I_PLAY_TONE, call(fd, I_PLAY_TONE, &t), EINVAL);
	t.frequency = 1234;
	t.duration = 30000;
	t.status = 0x55;
	err = call(fd, I_PLAY_TONE, &t);
	EXPECT_ERR(I_PLAY_TONE, err, 0);
	EXPECT(I_PLAY_TONE, t.status == 0 && t.frequency == 1234 && t.duration == 30000,
	       "status 0x%02x, frequency %u, duration %u", t.status, t.frequency,
	       t.duration);
}

static int get_output(int fd, __u8 port, struct nxt_output_state *o)
{
	int err;

	memset(o, 0, sizeof(*o));
	o->port = port;
	o->status = 0x55;
	err = call(fd, I_GET_OUTPUT_STATE, o);
	EXPECT_ERR(I_GET_OUTPUT_STATE, err, 0);
	EXPECT(I_GET_OUTPUT_STATE, o->port == port && o->status == 0,
	       "port %u, status 0x%02x", o->port, o->status);
	return err;
}

static void test_motors(int fd)
{
	struct nxt_output_state o, g;
	struct nxt_motor_position mp;
	int err;

	/* Port B backwards, regulated, steering, with a far limit. */
	memset(&o, 0, sizeof(o));
	o.port = 1;
	o.power = -75;
	o.mode = NXT_MODE_MOTORON | NXT_MODE_BRAKE | NXT_MODE_REGULATED;
	o.regulation_mode = NXT_REGULATION_MOTOR_SPEED;
	o.turn_ratio = -20;
	o.run_state = NXT_RUN_STATE_RUNNING;
	o.tacho_limit = 123456;
	o.status = 0x55;
	err = call(fd, I_SET_OUTPUT_STATE, &o);
	EXPECT_ERR(I_SET_OUTPUT_STATE, err, 0);
	EXPECT(I_SET_OUTPUT_STATE, o.status == 0, "status 0x%02x", o.status);
	sleep_ms(100);
	if (!get_output(fd, 1, &g)) {
		EXPECT(I_GET_OUTPUT_STATE, g.power == -75 &&
		       g.mode == (NXT_MODE_MOTORON | NXT_MODE_BRAKE | NXT_MODE_REGULATED) &&
		       g.regulation_mode == NXT_REGULATION_MOTOR_SPEED &&
		       g.turn_ratio == -20 && g.run_state == NXT_RUN_STATE_RUNNING &&
		       g.tacho_limit == 123456,
		       "running: power %d, mode 0x%02x, regulation %u, turn %d, run state 0x%02x, limit %u",
		       g.power, g.mode, g.regulation_mode, g.turn_ratio, g.run_state,
		       g.tacho_limit);
		/* 100 ms backwards at power 75: about -75 degrees. */
		EXPECT(I_GET_OUTPUT_STATE, g.tacho_count < -10 && g.tacho_count > -5000 &&
		       g.block_tacho_count == g.tacho_count &&
		       g.rotation_count == g.tacho_count,
		       "running backwards: tacho %d, block %d, rotation %d",
		       g.tacho_count, g.block_tacho_count, g.rotation_count);
	}
	o.port = NXT_OUTPUT_PORTS;
	EXPECT_ERR(I_SET_OUTPUT_STATE, call(fd, I_SET_OUTPUT_STATE, &o), EINVAL);
	o.port = 1;
	o.power = NXT_POWER_MAX + 1;
	EXPECT_ERR(I_SET_OUTPUT_STATE, call(fd, I_SET_OUTPUT_STATE, &o), EINVAL);
	o.power = 0;
	o.turn_ratio = -NXT_POWER_MAX - 1;
	EXPECT_ERR(I_SET_OUTPUT_STATE, call(fd, I_SET_OUTPUT_STATE, &o), EINVAL);

	/* Stop it: a new goal zeroes the tacho count, not the others. */
	memset(&o, 0, sizeof(o));
	o.port = 1;
	EXPECT_ERR(I_SET_OUTPUT_STATE, call(fd, I_SET_OUTPUT_STATE, &o), 0);
	if (!get_output(fd, 1, &g))
		EXPECT(I_GET_OUTPUT_STATE, g.power == 0 && g.run_state == 0 &&
		       g.tacho_count == 0 && g.block_tacho_count < -10 &&
		       g.rotation_count == g.block_tacho_count,
		       "stopped: power %d, run state 0x%02x, tacho %d, block %d, rotation %d",
		       g.power, g.run_state, g.tacho_count, g.block_tacho_count,
		       g.rotation_count);
	memset(&g, 0, sizeof(g));
	g.port = NXT_OUTPUT_PORTS;
	EXPECT_ERR(I_GET_OUTPUT_STATE, call(fd, I_GET_OUTPUT_STATE, &g), EINVAL);
	g.port = 0;
	g.reserved = 1;
	EXPECT_ERR(I_GET_OUTPUT_STATE, call(fd, I_GET_OUTPUT_STATE, &g), EINVAL);

	/* Relative: the block count only; then absolute: the rotation count. */
	memset(&mp, 0, sizeof(mp));
	mp.port = 1;
	mp.relative = 1;
	mp.status = 0x55;
	err = call(fd, I_RESET_MOTOR_POSITION, &mp);
	EXPECT_ERR(I_RESET_MOTOR_POSITION, err, 0);
	EXPECT(I_RESET_MOTOR_POSITION, mp.status == 0, "status 0x%02x", mp.status);
	if (!get_output(fd, 1, &g))
		EXPECT(I_RESET_MOTOR_POSITION, g.block_tacho_count == 0 &&
		       g.rotation_count < -10,
		       "after a relative reset: block %d, rotation %d",
		       g.block_tacho_count, g.rotation_count);
	mp.relative = 0;
	EXPECT_ERR(I_RESET_MOTOR_POSITION, call(fd, I_RESET_MOTOR_POSITION, &mp), 0);
	if (!get_output(fd, 1, &g))
		EXPECT(I_RESET_MOTOR_POSITION, g.rotation_count == 0,
		       "after an absolute reset: rotation %d", g.rotation_count);
	mp.relative = 2;
	EXPECT_ERR(I_RESET_MOTOR_POSITION, call(fd, I_RESET_MOTOR_POSITION, &mp), EINVAL);
	mp.relative = 0;
	mp.port = NXT_OUTPUT_PORTS;
	EXPECT_ERR(I_RESET_MOTOR_POSITION, call(fd, I_RESET_MOTOR_POSITION, &mp), EINVAL);
}

static int get_input(int fd, __u8 port, struct nxt_input_values *v)
{
	int err;

	memset(v, 0, sizeof(*v));
	v->port = port;
	v->status = 0x55;
	err = call(fd, I_GET_INPUT_VALUES, v);
	EXPECT_ERR(I_GET_INPUT_VALUES, err, 0);
	EXPECT(I_GET_INPUT_VALUES, v->port == port && v->status == 0,
	       "port %u, status 0x%02x", v->port, v->status);
	return err;
}

static void set_input(int fd, __u8 port, __u8 type, __u8 mode)
{
	struct nxt_input_mode im = { .port = port, .type = type, .mode = mode,
				     .status = 0x55 };
	int err;

	err = call(fd, I_SET_INPUT_MODE, &im);
	EXPECT_ERR(I_SET_INPUT_MODE, err, 0);
	EXPECT(I_SET_INPUT_MODE, im.status == 0 && im.port == port && im.type == type &&
	       im.mode == mode, "status 0x%02x", im.status);
}

static void test_sensors(int fd, unsigned int sound_raw)
{
	struct nxt_input_mode im;
	struct nxt_input_values v;
	struct nxt_input_port ip;
	int pct = (1023 - (int)sound_raw) * 100 / 1023;
	int i, err;

	/* The sound sensor on port 2 (1), in percent of full scale. */
	set_input(fd, 1, NXT_SENSOR_SOUND_DB, NXT_SENSOR_MODE_PERCENT);
	for (i = 0; i < 100; i++) {
		if (get_input(fd, 1, &v) || v.valid)
			break;
		sleep_ms(20);
	}
	EXPECT(I_GET_INPUT_VALUES, v.valid == 1 && v.calibrated == 0 &&
	       v.type == NXT_SENSOR_SOUND_DB && v.mode == NXT_SENSOR_MODE_PERCENT &&
	       v.raw == sound_raw && v.normalized == sound_raw && v.scaled == pct &&
	       v.calibrated_value == (__s16)sound_raw && v.reserved == 0,
	       "valid %u, calibrated %u, type 0x%02x, mode 0x%02x, raw %u, normalized %u, scaled %d (expected %d), calibrated value %d",
	       v.valid, v.calibrated, v.type, v.mode, v.raw, v.normalized, v.scaled, pct,
	       v.calibrated_value);
	set_input(fd, 1, NXT_SENSOR_SOUND_DB, NXT_SENSOR_MODE_RAW);
	if (!get_input(fd, 1, &v))
		EXPECT(I_GET_INPUT_VALUES, v.mode == NXT_SENSOR_MODE_RAW &&
		       v.scaled == (__s16)sound_raw,
		       "raw mode: mode 0x%02x, scaled %d", v.mode, v.scaled);
	memset(&v, 0, sizeof(v));
	v.port = NXT_INPUT_PORTS;
	EXPECT_ERR(I_GET_INPUT_VALUES, call(fd, I_GET_INPUT_VALUES, &v), EINVAL);
	v.port = 0;
	v.reserved = 1;
	EXPECT_ERR(I_GET_INPUT_VALUES, call(fd, I_GET_INPUT_VALUES, &v), EINVAL);

	memset(&im, 0, sizeof(im));
	im.port = NXT_INPUT_PORTS;
	EXPECT_ERR(I_SET_INPUT_MODE, call(fd, I_SET_INPUT_MODE, &im), EINVAL);
	im.port = 0;
	im.type = NXT_SENSOR_TYPES;
	EXPECT_ERR(I_SET_INPUT_MODE, call(fd, I_SET_INPUT_MODE, &im), EINVAL);

	memset(&ip, 0, sizeof(ip));
	ip.port = 1;
	ip.status = 0x55;
	err = call(fd, I_RESET_INPUT_SCALED_VALUE, &ip);
	EXPECT_ERR(I_RESET_INPUT_SCALED_VALUE, err, 0);
	EXPECT(I_RESET_INPUT_SCALED_VALUE, ip.status == 0 && ip.port == 1,
	       "status 0x%02x, port %u", ip.status, ip.port);
	ip.port = NXT_INPUT_PORTS;
	EXPECT_ERR(I_RESET_INPUT_SCALED_VALUE, call(fd, I_RESET_INPUT_SCALED_VALUE, &ip),
		   EINVAL);
	ip.port = 0;
	ip.reserved[1] = 1;
	EXPECT_ERR(I_RESET_INPUT_SCALED_VALUE, call(fd, I_RESET_INPUT_SCALED_VALUE, &ip),
		   EINVAL);
}

static void test_battery_and_keep_alive(int fd, unsigned int mv, unsigned int sleep_limit)
{
	struct nxt_keep_alive k;
	struct nxt_battery b;
	int err;

	memset(&b, 0, sizeof(b));
	b.status = 0x55;
	err = call(fd, I_GET_BATTERY_LEVEL, &b);
	EXPECT_ERR(I_GET_BATTERY_LEVEL, err, 0);
	EXPECT(I_GET_BATTERY_LEVEL, b.millivolts == mv && b.status == 0,
	       "%u mV (expected %u), status 0x%02x", b.millivolts, mv, b.status);
	b.reserved = 1;
	EXPECT_ERR(I_GET_BATTERY_LEVEL, call(fd, I_GET_BATTERY_LEVEL, &b), EINVAL);

	memset(&k, 0, sizeof(k));
	k.status = 0x55;
	err = call(fd, I_KEEP_ALIVE, &k);
	EXPECT_ERR(I_KEEP_ALIVE, err, 0);
	EXPECT(I_KEEP_ALIVE, k.sleep_limit == sleep_limit && k.status == 0,
	       "sleep limit %u ms (expected %u), status 0x%02x", k.sleep_limit,
	       sleep_limit, k.status);
	k.reserved[2] = 1;
	EXPECT_ERR(I_KEEP_ALIVE, call(fd, I_KEEP_ALIVE, &k), EINVAL);
}

/* LSGetStatus until the transfer is done: the errno; *ready its bytes. */
static int ls_wait(int fd, __u8 port, unsigned int *ready)
{
	struct nxt_ls_status s;
	int i, err = 0;

	for (i = 0; i < 500; i++) {
		memset(&s, 0, sizeof(s));
		s.port = port;
		s.bytes_ready = 0x55;
		err = call(fd, I_LS_GET_STATUS, &s);
		if (err != EINPROGRESS)
			break;
		EXPECT(I_LS_GET_STATUS, s.status == NXT_STATUS_PENDING,
		       "pending: status 0x%02x", s.status);
		sleep_ms(2);
	}
	EXPECT(I_LS_GET_STATUS, err || (s.status == 0 && s.port == port),
	       "done: status 0x%02x, port %u", s.status, s.port);
	*ready = s.bytes_ready;
	return err;
}

static int ls_write(int fd, __u8 reg, __u8 rx_length)
{
	struct nxt_ls_write w;
	int err;

	memset(&w, 0, sizeof(w));
	w.port = 3;
	w.tx_length = 2;
	w.rx_length = rx_length;
	w.tx_data[0] = 0x02;	/* the ultrasonic sensor's I2C address */
	w.tx_data[1] = reg;
	w.status = 0x55;
	err = call(fd, I_LS_WRITE, &w);
	EXPECT_ERR(I_LS_WRITE, err, 0);
	EXPECT(I_LS_WRITE, err || w.status == 0, "status 0x%02x", w.status);
	return err;
}

static void test_ultrasonic(int fd, unsigned int distance)
{
	struct nxt_ls_status s;
	struct nxt_ls_write w;
	struct nxt_ls_read r;
	unsigned int ready = 0;
	int err, i;

	/* Sensor port 4 (3): the ultrasonic sensor, 9 V low-speed. */
	set_input(fd, 3, NXT_SENSOR_LOWSPEED_9V, NXT_SENSOR_MODE_RAW);
	for (i = 0; i < 100; i++) {
		memset(&s, 0, sizeof(s));
		s.port = 3;
		err = call(fd, I_LS_GET_STATUS, &s);
		if (err != EBUSY)
			break;
		EXPECT(I_LS_GET_STATUS, s.status == NXT_STATUS_CHANNEL_BUSY,
		       "settling: status 0x%02x", s.status);
		sleep_ms(20);
	}
	EXPECT_ERR(I_LS_GET_STATUS, err, 0);

	/* Register 0x42: the distance, one byte. */
	if (!ls_write(fd, 0x42, 1)) {
		err = ls_wait(fd, 3, &ready);
		EXPECT_ERR(I_LS_GET_STATUS, err, 0);
		EXPECT(I_LS_GET_STATUS, ready == 1, "bytes ready %u, expected 1", ready);
	}
	memset(&r, 0xee, sizeof(r));
	r.port = 3;
	r.reserved = 0;
	err = call(fd, I_LS_READ, &r);
	EXPECT_ERR(I_LS_READ, err, 0);
	EXPECT(I_LS_READ, err || (r.status == 0 && r.port == 3 && r.length == 1 &&
				  r.data[0] == distance && all_zero(r.data + 1, 15)),
	       "status 0x%02x, length %u, data[0] %u (expected %u)", r.status, r.length,
	       r.data[0], distance);

	/* Register 0x08: the vendor, eight bytes. */
	if (!ls_write(fd, 0x08, 8)) {
		err = ls_wait(fd, 3, &ready);
		EXPECT_ERR(I_LS_GET_STATUS, err, 0);
		EXPECT(I_LS_GET_STATUS, ready == 8, "bytes ready %u, expected 8", ready);
	}
	memset(&r, 0, sizeof(r));
	r.port = 3;
	err = call(fd, I_LS_READ, &r);
	EXPECT_ERR(I_LS_READ, err, 0);
	EXPECT(I_LS_READ, err || (r.length == 8 && !memcmp(r.data, "LEGO\0\0\0\0", 8) &&
				  all_zero(r.data + 8, 8)),
	       "length %u, data \"%.16s\"", r.length, r.data);

	/* Port 1 (0) is no low-speed port: the firmware's channel busy. */
	memset(&r, 0xee, sizeof(r));
	r.port = 0;
	r.reserved = 0;
	err = call(fd, I_LS_READ, &r);
	EXPECT_ERR(I_LS_READ, err, EBUSY);
	EXPECT(I_LS_READ, r.status == NXT_STATUS_CHANNEL_BUSY && r.length == 0,
	       "not low-speed: status 0x%02x, length %u", r.status, r.length);
	r.port = NXT_INPUT_PORTS;
	EXPECT_ERR(I_LS_READ, call(fd, I_LS_READ, &r), EINVAL);
	memset(&s, 0, sizeof(s));
	s.port = 3;
	s.reserved = 1;
	EXPECT_ERR(I_LS_GET_STATUS, call(fd, I_LS_GET_STATUS, &s), EINVAL);

	memset(&w, 0, sizeof(w));
	w.port = 3;
	w.tx_length = NXT_LS_DATA_MAX + 1;
	EXPECT_ERR(I_LS_WRITE, call(fd, I_LS_WRITE, &w), EINVAL);
	w.tx_length = 1;
	w.rx_length = NXT_LS_DATA_MAX + 1;
	EXPECT_ERR(I_LS_WRITE, call(fd, I_LS_WRITE, &w), EINVAL);
}

/* A file opened read-only: the timeouts work, nothing is sent. */
static void test_read_only(const char *node)
{
	struct nxt_battery b;
	__u32 ms = 0;
	int fd;

	fd = open(node, O_RDONLY);
	if (fd < 0) {
		fail(I_GET_BATTERY_LEVEL, "open %s read-only: %s", node, strerror(errno));
		return;
	}
	EXPECT_ERR(I_GET_TIMEOUT, call(fd, I_GET_TIMEOUT, &ms), 0);
	EXPECT(I_GET_TIMEOUT, ms == 1000, "read-only file: timeout %u ms", ms);
	memset(&b, 0, sizeof(b));
	EXPECT_ERR(I_GET_BATTERY_LEVEL, call(fd, I_GET_BATTERY_LEVEL, &b), EBADF);
	close(fd);
}

#define SIZE(t)		printf("%s %zu\n", #t, sizeof(struct nxt_##t))
#define OFFSET(t, m)	printf("%s.%s %zu\n", #t, #m, offsetof(struct nxt_##t, m))

static void print_layout(void)
{
	int i;

	SIZE(transaction);
	OFFSET(transaction, telegram);
	OFFSET(transaction, reply);
	OFFSET(transaction, length);
	OFFSET(transaction, reply_length);
	SIZE(status_only);
	OFFSET(status_only, status);
	SIZE(program);
	OFFSET(program, name);
	OFFSET(program, status);
	SIZE(sound_file);
	OFFSET(sound_file, name);
	OFFSET(sound_file, loop);
	OFFSET(sound_file, status);
	SIZE(tone);
	OFFSET(tone, frequency);
	OFFSET(tone, duration);
	OFFSET(tone, status);
	SIZE(output_state);
	OFFSET(output_state, port);
	OFFSET(output_state, power);
	OFFSET(output_state, mode);
	OFFSET(output_state, regulation_mode);
	OFFSET(output_state, turn_ratio);
	OFFSET(output_state, run_state);
	OFFSET(output_state, status);
	OFFSET(output_state, tacho_limit);
	OFFSET(output_state, tacho_count);
	OFFSET(output_state, block_tacho_count);
	OFFSET(output_state, rotation_count);
	SIZE(input_mode);
	OFFSET(input_mode, port);
	OFFSET(input_mode, type);
	OFFSET(input_mode, mode);
	OFFSET(input_mode, status);
	SIZE(input_values);
	OFFSET(input_values, port);
	OFFSET(input_values, valid);
	OFFSET(input_values, calibrated);
	OFFSET(input_values, type);
	OFFSET(input_values, mode);
	OFFSET(input_values, status);
	OFFSET(input_values, raw);
	OFFSET(input_values, normalized);
	OFFSET(input_values, scaled);
	OFFSET(input_values, calibrated_value);
	SIZE(input_port);
	OFFSET(input_port, port);
	OFFSET(input_port, status);
	SIZE(motor_position);
	OFFSET(motor_position, port);
	OFFSET(motor_position, relative);
	OFFSET(motor_position, status);
	SIZE(message);
	OFFSET(message, inbox);
	OFFSET(message, local_inbox);
	OFFSET(message, remove);
	OFFSET(message, size);
	OFFSET(message, data);
	OFFSET(message, status);
	SIZE(battery);
	OFFSET(battery, millivolts);
	OFFSET(battery, status);
	SIZE(keep_alive);
	OFFSET(keep_alive, sleep_limit);
	OFFSET(keep_alive, status);
	SIZE(ls_status);
	OFFSET(ls_status, port);
	OFFSET(ls_status, bytes_ready);
	OFFSET(ls_status, status);
	SIZE(ls_write);
	OFFSET(ls_write, port);
	OFFSET(ls_write, tx_length);
	OFFSET(ls_write, rx_length);
	OFFSET(ls_write, status);
	OFFSET(ls_write, tx_data);
	SIZE(ls_read);
	OFFSET(ls_read, port);
	OFFSET(ls_read, length);
	OFFSET(ls_read, status);
	OFFSET(ls_read, data);
	for (i = 0; i < I_COUNT; i++)
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
	test_transact(fd);
	test_program_and_mailboxes(fd);
	test_sound(fd);
	test_motors(fd);
	test_sensors(fd, sound_raw);
	test_battery_and_keep_alive(fd, mv, sleep_limit);
	test_ultrasonic(fd, distance);
	close(fd);
	test_read_only(argv[1]);

	for (i = 0; i < I_COUNT; i++)
		if (calls[i] && !failed[i])
			printf("ok %s\n", iocs[i].name);
	printf("telegrams %u\n", telegrams);
	return failures ? 1 : 0;
}
