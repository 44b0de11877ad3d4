// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl connect / attach / disconnect: a brick on Bluetooth (or any
 * serial line) as /dev/nxtN, through the lego_nxt_serial line discipline.
 *
 * The discipline lives as long as its tty is open, so attach stays behind
 * as a small daemon holding the tty (as ldattach does): it prints the
 * brick's /dev/nxtN, then waits until it is told to let go (disconnect,
 * SIGTERM) or the tty hangs up (the Bluetooth link is lost; the driver has
 * then removed the node already). connect first opens an RFCOMM channel
 * to the brick and makes a tty of it (/dev/rfcommN), released when the
 * daemon closes it, which ends the link.
 *
 * Each daemon leaves $NXTCTL_RUNDIR/nxtN (default /run/nxtctl) holding its
 * process ID and its tty, for disconnect.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "nxtctl.h"

#define RUNDIR_DEFAULT	"/run/nxtctl"
#define WATCH_MS	500	/* the daemon checks its tty this often */
#define WAIT_MS		5000	/* for a node to appear or go */

/*
 * Bluetooth's socket and RFCOMM tty interface, as <bluetooth/bluetooth.h>
 * and <bluetooth/rfcomm.h> (libbluetooth-dev) give it, and the kernel's
 * net/bluetooth/rfcomm/tty.c reads it.
 */
#ifndef AF_BLUETOOTH
#define AF_BLUETOOTH	31
#endif
#define BTPROTO_RFCOMM	3
#define RFCOMM_REUSE_DLC	0x1	/* the tty takes the socket's link */
#define RFCOMM_RELEASE_ONHUP	0x2	/* gone at the tty's last close */
#define RFCOMMCREATEDEV	_IOW('R', 200, int)
#define NXT_RFCOMM_CHANNEL	1		/* the brick's serial port */

struct bt_addr {
	unsigned char b[6];			/* least significant byte first */
};

struct sockaddr_rc {
	sa_family_t rc_family;
	struct bt_addr rc_bdaddr;
	unsigned char rc_channel;
};

struct rfcomm_dev_req {
	short dev_id;
	unsigned int flags;
	struct bt_addr src;
	struct bt_addr dst;
	unsigned char channel;
};

static const char *rundir(void)
{
	const char *d = getenv("NXTCTL_RUNDIR");

	return d && *d ? d : RUNDIR_DEFAULT;
}

static void sleep_ms(unsigned int ms)
{
	struct timespec ts = { ms / 1000, (ms % 1000) * 1000000L };

	while (nanosleep(&ts, &ts) && errno == EINTR)
		;
}

/* Waits up to WAIT_MS for @path to exist (@want) or not. */
static int wait_path(const char *path, int want)
{
	int waited;

	for (waited = 0; waited < WAIT_MS; waited += 20) {
		if ((access(path, F_OK) == 0) == want)
			return 0;
		sleep_ms(20);
	}
	return -1;
}

/* "AA:BB:CC:DD:EE:FF" into the kernel's byte order (reversed). */
static int parse_bdaddr(const char *s, struct bt_addr *a)
{
	unsigned int v[6];
	char end;
	int i;

	if (sscanf(s, "%2x:%2x:%2x:%2x:%2x:%2x%c", &v[0], &v[1], &v[2], &v[3],
		   &v[4], &v[5], &end) != 6 || strlen(s) != 17)
		return -1;
	for (i = 0; i < 6; i++)
		a->b[5 - i] = v[i];
	return 0;
}

/* The tty raw, so that nothing between the driver and the line changes a byte. */
static int tty_raw(int fd)
{
	struct termios t;

	if (tcgetattr(fd, &t))
		return -1;
	cfmakeraw(&t);
	return tcsetattr(fd, TCSANOW, &t);
}

/* Puts N_LEGONXT on @fd; its node's minor in @minor. */
static int set_ldisc(int fd, const char *tty, unsigned int *minor)
{
	int ld = N_LEGONXT;

	if (tty_raw(fd))
		return sys_error(tty, errno);
	if (ioctl(fd, TIOCSETD, &ld)) {
		int err = errno;

		if (err == EINVAL)
			fprintf(stderr,
				"nxtctl: %s: line discipline %d unknown: is lego_nxt_serial installed (modprobe lego_nxt_serial)?\n",
				tty, N_LEGONXT);
		else if (err == EPERM)
			fprintf(stderr,
				"nxtctl: %s: attaching a brick takes root (CAP_SYS_ADMIN)\n", tty);
		else
			return sys_error(tty, err);
		return EXIT_DEVICE;
	}
	if (ioctl(fd, NXT_IOC_TTY_MINOR, minor))
		return sys_error("NXT_IOC_TTY_MINOR", errno);
	return EXIT_OK;
}

/*
 * The daemon: holds the tty until SIGTERM, SIGINT or SIGHUP (read from a
 * signalfd; the brick is detached by going back to N_TTY) or until the
 * discipline is gone (a hangup, or someone else's TIOCSETD).
 */
static void hold(int fd, const char *pidfile)
{
	struct pollfd p[2] = { { .fd = fd, .events = POLLIN }, { .events = POLLIN } };
	unsigned int minor;
	int stop = 0;
	sigset_t set;

	sigemptyset(&set);
	sigaddset(&set, SIGTERM);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGHUP);
	sigprocmask(SIG_BLOCK, &set, NULL);
	p[1].fd = signalfd(-1, &set, SFD_CLOEXEC);
	for (;;) {
		int n = poll(p, p[1].fd >= 0 ? 2 : 1, WATCH_MS);

		if (n > 0 && p[1].revents) {
			stop = 1;
			break;
		}
		/* The discipline has no poll(): a hung-up tty says POLLHUP. */
		if (n > 0 && (p[0].revents & (POLLHUP | POLLERR | POLLNVAL)))
			break;
		if (ioctl(fd, NXT_IOC_TTY_MINOR, &minor))
			break;
	}
	if (stop) {
		int ld = N_TTY;

		ioctl(fd, TIOCSETD, &ld);
	}
	unlink(pidfile);
	close(fd);
}

/*
 * Attaches the brick on the open tty @fd, prints its node, and holds the
 * tty: in the background, unless @foreground.
 */
static int attach_fd(int fd, const char *tty, int foreground)
{
	char node[32], pidfile[256];
	unsigned int minor;
	pid_t pid;
	FILE *f;
	int ret;

	ret = set_ldisc(fd, tty, &minor);
	if (ret)
		return ret;
	snprintf(node, sizeof(node), "/dev/nxt%u", minor);
	snprintf(pidfile, sizeof(pidfile), "%s/nxt%u", rundir(), minor);
	if (mkdir(rundir(), 0755) && errno != EEXIST)
		fprintf(stderr, "nxtctl: %s: %s (disconnect will not find %s)\n",
			rundir(), strerror(errno), node);
	/* The node comes with the discipline; udev may still be naming it. */
	if (wait_path(node, 1))
		fprintf(stderr, "nxtctl: %s did not appear\n", node);
	printf("%s\n", node);
	fflush(stdout);

	pid = foreground ? getpid() : fork();
	if (pid < 0)
		return sys_error("fork", errno);
	if (pid > 0 || foreground) {
		f = fopen(pidfile, "w");
		if (f) {
			fprintf(f, "%ld %s\n", (long)pid, tty);
			fclose(f);
		}
		if (!foreground)
			return EXIT_OK;	/* the daemon holds the tty */
	} else {
		/* Nothing of the caller's held: its pipes see their end. */
		setsid();
		if (!freopen("/dev/null", "r", stdin) || !freopen("/dev/null", "w", stdout) ||
		    !freopen("/dev/null", "w", stderr))
			_exit(EXIT_DEVICE);
	}
	hold(fd, pidfile);
	if (!foreground)
		_exit(EXIT_OK);
	return EXIT_OK;
}

int cmd_attach(int argc, char **argv)
{
	struct opt opts[] = { { .name = "foreground" }, {} };
	char *pos[1];
	int npos, ret, fd;

	ret = parse_opts("attach", argc, argv, opts, pos, &npos, 1, 1);
	if (ret)
		return ret;
	fd = open(pos[0], O_RDWR | O_NOCTTY | O_CLOEXEC);
	if (fd < 0)
		return sys_error(pos[0], errno);
	ret = attach_fd(fd, pos[0], opts[0].set);
	if (ret || !opts[0].set)
		close(fd);
	return ret;
}

/* An RFCOMM channel to @addr, made a tty: its path in @tty. */
static int rfcomm_tty(const struct bt_addr *addr, unsigned int channel,
		      char *tty, size_t size)
{
	struct sockaddr_rc sa = { .rc_family = AF_BLUETOOTH, .rc_channel = channel };
	struct rfcomm_dev_req req = { .dev_id = -1 };
	int s, id;

	s = socket(AF_BLUETOOTH, SOCK_STREAM | SOCK_CLOEXEC, BTPROTO_RFCOMM);
	if (s < 0) {
		if (errno == EAFNOSUPPORT || errno == EPROTONOSUPPORT)
			fputs("nxtctl: no Bluetooth RFCOMM in this kernel (modprobe rfcomm)\n",
			      stderr);
		else
			sys_error("Bluetooth socket", errno);
		return -1;
	}
	sa.rc_bdaddr = *addr;
	if (connect(s, (struct sockaddr *)&sa, sizeof(sa))) {
		int err = errno;

		fprintf(stderr, "nxtctl: connecting to the brick: %s%s\n", strerror(err),
			err == EHOSTDOWN || err == ETIMEDOUT || err == ECONNREFUSED ?
			" (is it on, in range, and paired?)" : "");
		close(s);
		return -1;
	}
	/* The tty takes the connected link over, and ends it at its last close. */
	req.flags = RFCOMM_REUSE_DLC | RFCOMM_RELEASE_ONHUP;
	req.dst = *addr;
	req.channel = channel;
	id = ioctl(s, RFCOMMCREATEDEV, &req);
	if (id < 0) {
		sys_error("RFCOMMCREATEDEV", errno);
		close(s);
		return -1;
	}
	close(s);
	snprintf(tty, size, "/dev/rfcomm%d", id);
	if (wait_path(tty, 1)) {
		fprintf(stderr, "nxtctl: %s did not appear\n", tty);
		return -1;
	}
	return 0;
}

int cmd_connect(int argc, char **argv)
{
	struct opt opts[] = { { .name = "foreground" }, { .name = "channel", .has_arg = 1 }, {} };
	unsigned int channel = NXT_RFCOMM_CHANNEL;
	struct bt_addr addr;
	char tty[32], *pos[1], *end;
	int npos, ret, fd;

	ret = parse_opts("connect", argc, argv, opts, pos, &npos, 1, 1);
	if (ret)
		return ret;
	if (parse_bdaddr(pos[0], &addr))
		return usage_error("connect",
				   "connect: '%s' is not a Bluetooth address (AA:BB:CC:DD:EE:FF)",
				   pos[0]);
	if (opts[1].set) {
		channel = strtoul(opts[1].arg, &end, 10);
		if (*end || channel < 1 || channel > 30)
			return usage_error("connect", "connect: --channel takes 1 to 30");
	}
	if (rfcomm_tty(&addr, channel, tty, sizeof(tty)))
		return EXIT_DEVICE;
	fd = open(tty, O_RDWR | O_NOCTTY | O_CLOEXEC);
	if (fd < 0)
		return sys_error(tty, errno);
	ret = attach_fd(fd, tty, opts[0].set);
	if (ret || !opts[0].set)
		close(fd);
	return ret;
}

int cmd_disconnect(int argc, char **argv)
{
	char pidfile[256], tty[128], *pos[1];
	const char *node, *name;
	int ret, n, npos;
	long pid;
	FILE *f;

	ret = parse_opts("disconnect", argc, argv, NULL, pos, &npos, 0, 0);
	if (ret)
		return ret;
	node = dev_path ? dev_path : getenv("NXT_DEVICE");
	if (!node)
		return usage_error("disconnect", "disconnect: which brick? -d /dev/nxtN");
	name = strrchr(node, '/') ? strrchr(node, '/') + 1 : node;
	snprintf(pidfile, sizeof(pidfile), "%s/%s", rundir(), name);
	f = fopen(pidfile, "r");
	if (!f) {
		fprintf(stderr,
			"nxtctl: %s was not attached by nxtctl connect or attach (no %s); a USB brick goes with nxtctl release\n",
			node, pidfile);
		return EXIT_DEVICE;
	}
	n = fscanf(f, "%ld %127s", &pid, tty);
	fclose(f);
	if (n != 2 || pid <= 1) {
		fprintf(stderr, "nxtctl: %s: unreadable\n", pidfile);
		return EXIT_DEVICE;
	}
	if (kill(pid, SIGTERM)) {
		if (errno != ESRCH)
			return sys_error("kill", errno);
		unlink(pidfile);	/* a daemon that died: only its file was left */
	}
	if (wait_path(node, 0)) {
		fprintf(stderr, "nxtctl: %s is still there\n", node);
		return EXIT_DEVICE;
	}
	printf("%s\n", tty);
	return EXIT_OK;
}
