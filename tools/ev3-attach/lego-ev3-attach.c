// SPDX-License-Identifier: GPL-2.0
/*
 * lego-ev3-attach: attach the lego_ev3_uart line discipline to a tty and
 * keep the tty open until SIGTERM or SIGINT, then put N_TTY back.
 *
 *   lego-ev3-attach [--label=NAME] [--foreground|--daemon [--pidfile=FILE]
 *                   [--wait[=SECONDS]]] TTY
 *   lego-ev3-attach --detach TTY
 *   lego-ev3-attach --help | --version
 *
 * Exit codes are listed in print_help() and in Documentation/lego/ev3-attach.rst.
 */
#define _GNU_SOURCE	/* fopencookie(), mkostemp() */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <syslog.h>
#include <time.h>
#include <termios.h>
#include <unistd.h>

#include <linux/lego_ev3_uart.h>

#ifndef N_TTY
#define N_TTY 0
#endif

/* The package's version, from dkms.conf (see the Makefile). */
#ifndef LEGO_VERSION
#define LEGO_VERSION "unknown"
#endif

/* Exit codes, documented in print_help() and ev3-attach.rst. */
enum {
	EXIT_OK = 0,		/* stopped by a signal, or --detach done */
	EXIT_FAIL = 1,		/* another system error */
	EXIT_USAGE = 2,		/* bad command line or label */
	EXIT_NOTTY = 3,		/* no such file, or not a tty */
	EXIT_NOLDISC = 4,	/* the discipline is not available */
	EXIT_PERM = 5,		/* permission denied */
	EXIT_BUSY = 6,		/* tty busy or already attached */
	EXIT_GONE = 7,		/* the tty was hung up (device unplugged) */
	EXIT_NOSENSOR = 8,	/* --wait: no sensor in time (still attached) */
};

/* --wait without a number: long enough for a sensor's handshake. */
#define WAIT_DEFAULT_S	30
#define SENSOR_CLASS	"/sys/class/lego-sensor"

static const char *prog = "lego-ev3-attach";
static FILE *err_out;

/* Errors go to stderr, or to syslog once daemonised (see to_syslog()). */
#define msg(fmt, ...) \
	fprintf(err_out, "%s: " fmt "\n", prog, ##__VA_ARGS__)

static ssize_t syslog_write(void *cookie, const char *buf, size_t len)
{
	(void)cookie;
	if (len > 1 && buf[len - 1] == '\n')
		syslog(LOG_ERR, "%.*s", (int)(len - 1), buf);
	else if (len > 1)
		syslog(LOG_ERR, "%.*s", (int)len, buf);
	return len;
}

/* A line-buffered stream whose lines go to syslog. */
static void to_syslog(void)
{
	static const cookie_io_functions_t io = { .write = syslog_write };
	FILE *f;

	openlog(prog, LOG_PID, LOG_DAEMON);
	f = fopencookie(NULL, "w", io);
	if (!f)
		return;
	setvbuf(f, NULL, _IOLBF, 0);
	err_out = f;
}

static void print_help(FILE *f)
{
	fprintf(f,
		"Usage: %s [OPTIONS] TTY\n"
		"       %s --detach TTY\n"
		"Attach the LEGO EV3 UART sensor line discipline to TTY (ttyS1 or\n"
		"/dev/ttyS1) and keep it attached until SIGTERM or SIGINT.\n"
		"\n"
		"  -l, --label=NAME    port label: the sensor's address becomes\n"
		"                      TTY:NAME (up to 15 of [A-Za-z0-9_.-]);\n"
		"                      default: the module's port_labels, else none\n"
		"  -f, --foreground    stay in the foreground (default; systemd)\n"
		"  -d, --daemon        run in the background\n"
		"  -p, --pidfile=FILE  with --daemon (default /run/lego-ev3-attach-TTY.pid)\n"
		"  -w, --wait[=SECS]   with --daemon: return once a sensor on TTY is\n"
		"                      there (and udev is done with it), printing its\n"
		"                      sysfs directory; give up after SECS (default %d)\n"
		"  -n, --ldisc=NUM     line discipline number (default %d)\n"
		"  -D, --detach        put N_TTY back on TTY and exit; a lego-ev3-attach\n"
		"                      holding TTY notices it and exits\n"
		"  -h, --help          this help\n"
		"  -V, --version       the version\n"
		"\n"
		"Exit codes: 0 stopped by a signal (or detached), 1 other error,\n"
		"2 usage or bad label, 3 no such tty or not a tty, 4 line discipline\n"
		"not available (module not loaded), 5 permission denied, 6 tty busy\n"
		"or already attached, 7 tty hung up (device unplugged), 8 --wait:\n"
		"no sensor in time (the daemon stays: --detach TTY stops it).\n",
		prog, prog, WAIT_DEFAULT_S, N_LEGOEV3);
}

/* A usage error: what is wrong, then where to look. */
static int usage_error(void)
{
	fprintf(stderr, "Try '%s --help' for more information.\n", prog);
	return EXIT_USAGE;
}

static bool label_ok(const char *label)
{
	const char *p;

	if (strlen(label) >= LEGO_EV3_LABEL_LEN)
		return false;
	for (p = label; *p; p++) {
		if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		      (*p >= '0' && *p <= '9') || strchr("_.-", *p)))
			return false;
	}
	return true;
}

/* An exit code for errno after open() of the tty. */
static int open_error(const char *path, int err)
{
	struct stat st;

	/* A file, a directory, on a read-only file system... */
	if (err != ENOENT && !stat(path, &st) && !S_ISCHR(st.st_mode)) {
		msg("%s: not a tty", path);
		return EXIT_NOTTY;
	}
	switch (err) {
	case ENOENT:
	case ENXIO:
	case ENODEV:
		msg("%s: no such device (%s)", path, strerror(err));
		return EXIT_NOTTY;
	case EACCES:
	case EPERM:
		msg("%s: %s: run as root or in the tty's group", path,
		    strerror(err));
		return EXIT_PERM;
	case EBUSY:
		msg("%s: busy (opened exclusively by another process)", path);
		return EXIT_BUSY;
	default:
		msg("%s: cannot open: %s", path, strerror(err));
		return EXIT_FAIL;
	}
}

static int open_tty(const char *path, int *fd)
{
	*fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
	if (*fd < 0)
		return open_error(path, errno);
	if (!isatty(*fd)) {
		msg("%s: not a tty", path);
		close(*fd);
		return EXIT_NOTTY;
	}
	return EXIT_OK;
}

/* Raw 8N1 at 2400 baud, no flow control: what the discipline sets too. */
static void set_raw(int fd, const char *path)
{
	struct termios t;

	if (tcgetattr(fd, &t))
		goto err;
	cfmakeraw(&t);
	t.c_cflag &= ~(CSIZE | PARENB | CSTOPB | CRTSCTS);
	t.c_cflag |= CS8 | CREAD | CLOCAL;
	t.c_cc[VMIN] = 1;
	t.c_cc[VTIME] = 0;
	cfsetispeed(&t, B2400);
	cfsetospeed(&t, B2400);
	if (tcsetattr(fd, TCSANOW, &t))
		goto err;
	return;
err:
	/* The discipline sets the line up itself: only a warning. */
	msg("%s: warning: cannot set raw 2400 8N1: %s", path, strerror(errno));
}

static int set_ldisc(int fd, const char *path, int num)
{
	if (!ioctl(fd, TIOCSETD, &num))
		return EXIT_OK;
	switch (errno) {
	case EINVAL:
		msg("%s: line discipline %d not available: %s", path, num,
		    "is lego_ev3_uart loaded? (modprobe lego_ev3_uart)");
		return EXIT_NOLDISC;
	case EPERM:
		msg("%s: attaching line discipline %d needs CAP_SYS_ADMIN: run as root",
		    path, num);
		return EXIT_PERM;
	case EBUSY:
		msg("%s: busy: the line discipline cannot be changed now, try again",
		    path);
		return EXIT_BUSY;
	case EIO:
		msg("%s: hung up (device gone?)", path);
		return EXIT_GONE;
	case EOPNOTSUPP:
		msg("%s: this tty cannot write: not usable for a sensor", path);
		return EXIT_NOTTY;
	default:
		msg("%s: cannot set line discipline %d: %s", path, num,
		    strerror(errno));
		return EXIT_FAIL;
	}
}

static int get_ldisc(int fd)
{
	int num;

	if (ioctl(fd, TIOCGETD, &num))
		return -1;
	return num;
}

static int set_label(int fd, const char *path, const char *label)
{
	struct lego_ev3_port_label pl;

	memset(&pl, 0, sizeof(pl));
	snprintf(pl.label, sizeof(pl.label), "%s", label);
	if (ioctl(fd, LEGO_EV3_SET_PORT_LABEL, &pl)) {
		msg("%s: cannot set port label \"%s\": %s", path, label,
		    strerror(errno));
		return errno == EPERM ? EXIT_PERM :
		       errno == EINVAL ? EXIT_USAGE : EXIT_FAIL;
	}
	return EXIT_OK;
}

static int detach(const char *path, int num)
{
	int fd, ret, cur, ntty = N_TTY;

	ret = open_tty(path, &fd);
	if (ret)
		return ret;
	cur = get_ldisc(fd);
	if (cur < 0) {
		msg("%s: cannot read the line discipline: %s", path,
		    strerror(errno));
		close(fd);
		return errno == EIO ? EXIT_GONE : EXIT_FAIL;
	}
	if (cur != num) {
		msg("%s: not attached (line discipline %d)", path, cur);
		close(fd);
		return EXIT_OK;
	}
	if (ioctl(fd, TIOCSETD, &ntty)) {
		msg("%s: cannot put N_TTY back: %s", path, strerror(errno));
		close(fd);
		return errno == EPERM ? EXIT_PERM : EXIT_FAIL;
	}
	close(fd);
	return EXIT_OK;
}

/*
 * Written whole or not at all: a reader that sees the file sees the pid
 * (a temporary file beside it, renamed over it), never an empty file.
 */
static int write_pidfile(const char *pidfile)
{
	char buf[32], tmp[PATH_MAX];
	int fd, n;

	if (snprintf(tmp, sizeof(tmp), "%s.XXXXXX", pidfile) >= (int)sizeof(tmp)) {
		errno = ENAMETOOLONG;
		return -1;
	}
	fd = mkostemp(tmp, O_CLOEXEC);
	if (fd < 0)
		return -1;
	n = snprintf(buf, sizeof(buf), "%ld\n", (long)getpid());
	if (fchmod(fd, 0644) || write(fd, buf, n) != n) {
		int err = errno;

		close(fd);
		unlink(tmp);
		errno = err;
		return -1;
	}
	if (close(fd) || rename(tmp, pidfile)) {
		int err = errno;

		unlink(tmp);
		errno = err;
		return -1;
	}
	return 0;
}

static double now_s(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec / 1e9;
}

/*
 * The sensorN directory whose address is @tty or @tty:LABEL, into @out;
 * false if there is none (yet).
 */
static bool find_sensor(const char *tty, char *out, size_t len)
{
	size_t n = strlen(tty);
	struct dirent *de;
	bool found = false;
	char path[PATH_MAX], addr[64];
	DIR *d;
	FILE *f;

	d = opendir(SENSOR_CLASS);
	if (!d)
		return false;
	while (!found && (de = readdir(d))) {
		if (de->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s/address", SENSOR_CLASS, de->d_name);
		f = fopen(path, "r");
		if (!f)
			continue;
		if (fgets(addr, sizeof(addr), f) && !strncmp(addr, tty, n) &&
		    (addr[n] == '\n' || addr[n] == ':' || !addr[n])) {
			snprintf(out, len, "%s/%s", SENSOR_CLASS, de->d_name);
			found = true;
		}
		fclose(f);
	}
	closedir(d);
	return found;
}

/* Let udevd finish the sensor's events (its rules give the group access). */
static void udev_settle(double secs)
{
	char arg[32];
	pid_t pid;
	int st;

	if (access("/run/udev/control", F_OK) || secs < 1)
		return;
	snprintf(arg, sizeof(arg), "--timeout=%d", (int)secs);
	pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_RDWR);

		if (null >= 0) {
			dup2(null, STDOUT_FILENO);
			dup2(null, STDERR_FILENO);
		}
		execlp("udevadm", "udevadm", "settle", arg, (char *)NULL);
		_exit(127);
	}
	if (pid > 0)
		waitpid(pid, &st, 0);
}

/*
 * --wait: poll for the sensor the daemon's tty brings, print its
 * directory; EXIT_NOSENSOR after @secs.
 */
static int wait_sensor(const char *tty, int secs)
{
	double end = now_s() + secs;
	char dir[PATH_MAX];

	for (;;) {
		if (find_sensor(tty, dir, sizeof(dir))) {
			udev_settle(end - now_s());
			printf("%s\n", dir);
			/* The caller leaves with _exit(), which flushes nothing. */
			fflush(stdout);
			return EXIT_OK;
		}
		if (now_s() >= end)
			break;
		usleep(100 * 1000);
	}
	msg("no sensor on %s after %d s; still attached (lego-ev3-attach --detach %s stops it)",
	    tty, secs, tty);
	return EXIT_NOSENSOR;
}

/*
 * Fork; the parent returns only once the child has written its pidfile, so
 * that the pidfile exists when the command returns; with @wait_s > 0, once
 * a sensor on @tty is there too.
 */
static int daemonize(const char *pidfile, const char *tty, int wait_s)
{
	int pfd[2], null;
	char ok = 0;
	pid_t pid;

	if (pipe(pfd)) {
		msg("pipe: %s", strerror(errno));
		return EXIT_FAIL;
	}
	pid = fork();
	if (pid < 0) {
		msg("fork: %s", strerror(errno));
		return EXIT_FAIL;
	}
	if (pid > 0) {
		close(pfd[1]);
		if (read(pfd[0], &ok, 1) != 1 || !ok)
			_exit(EXIT_FAIL);
		_exit(wait_s > 0 ? wait_sensor(tty, wait_s) : EXIT_OK);
	}
	close(pfd[0]);
	setsid();
	if (chdir("/"))
		_exit(EXIT_FAIL);
	if (pidfile && write_pidfile(pidfile)) {
		msg("%s: %s", pidfile, strerror(errno));
		_exit(EXIT_FAIL);
	}
	null = open("/dev/null", O_RDWR);
	if (null >= 0) {
		dup2(null, STDIN_FILENO);
		dup2(null, STDOUT_FILENO);
		dup2(null, STDERR_FILENO);
		if (null > STDERR_FILENO)
			close(null);
	}
	to_syslog();
	ok = 1;
	if (write(pfd[1], &ok, 1) != 1)
		_exit(EXIT_FAIL);
	close(pfd[1]);
	return EXIT_OK;
}

/*
 * Wait for a signal, a hangup (the device went away) or someone else
 * changing the discipline (lego-ev3-attach --detach, ldattach).
 */
static int hold(int fd, int sfd, const char *path, int num)
{
	struct pollfd pfd[2] = {
		{ .fd = fd, .events = 0 },
		{ .fd = sfd, .events = POLLIN },
	};
	struct signalfd_siginfo si;
	int cur;

	for (;;) {
		pfd[0].revents = 0;
		pfd[1].revents = 0;
		if (poll(pfd, 2, 1000) < 0 && errno != EINTR) {
			msg("poll: %s", strerror(errno));
			return EXIT_FAIL;
		}
		if (pfd[1].revents & POLLIN) {
			if (read(sfd, &si, sizeof(si)) == sizeof(si))
				return EXIT_OK;
		}
		if (pfd[0].revents & (POLLHUP | POLLERR | POLLNVAL)) {
			msg("%s: hung up (device gone?)", path);
			return EXIT_GONE;
		}
		cur = get_ldisc(fd);
		if (cur < 0) {
			msg("%s: hung up (device gone?)", path);
			return EXIT_GONE;
		}
		if (cur != num) {
			msg("%s: line discipline changed to %d: exiting", path,
			    cur);
			return EXIT_OK;
		}
	}
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {
		{ "label", required_argument, NULL, 'l' },
		{ "foreground", no_argument, NULL, 'f' },
		{ "daemon", no_argument, NULL, 'd' },
		{ "pidfile", required_argument, NULL, 'p' },
		{ "wait", optional_argument, NULL, 'w' },
		{ "ldisc", required_argument, NULL, 'n' },
		{ "detach", no_argument, NULL, 'D' },
		{ "help", no_argument, NULL, 'h' },
		{ "version", no_argument, NULL, 'V' },
		{ NULL, 0, NULL, 0 }
	};
	const char *label = NULL, *pidfile = NULL, *name;
	bool daemon_mode = false, do_detach = false;
	char path[PATH_MAX], defpid[PATH_MAX];
	struct termios saved;
	bool have_saved;
	sigset_t block;
	int c, fd, sfd, ret, num = N_LEGOEV3, ntty = N_TTY, wait_s = 0;
	char *end;
	long v;

	err_out = stderr;
	while ((c = getopt_long(argc, argv, "l:fdp:w::n:DhV", opts, NULL)) != -1) {
		switch (c) {
		case 'l':
			label = optarg;
			break;
		case 'f':
			daemon_mode = false;
			break;
		case 'd':
			daemon_mode = true;
			break;
		case 'p':
			pidfile = optarg;
			break;
		case 'w':
			wait_s = WAIT_DEFAULT_S;
			if (!optarg)
				break;
			errno = 0;
			v = strtol(optarg, &end, 10);
			if (errno || *end || end == optarg || v < 1 || v > 3600) {
				msg("bad --wait \"%s\": 1 to 3600 seconds", optarg);
				return EXIT_USAGE;
			}
			wait_s = (int)v;
			break;
		case 'n':
			errno = 0;
			v = strtol(optarg, &end, 0);
			if (errno || *end || end == optarg || v < 0 || v > INT_MAX) {
				msg("bad line discipline number \"%s\"", optarg);
				return EXIT_USAGE;
			}
			num = (int)v;
			break;
		case 'D':
			do_detach = true;
			break;
		case 'h':
			print_help(stdout);
			return EXIT_OK;
		case 'V':
			printf("%s %s\n", prog, LEGO_VERSION);
			return EXIT_OK;
		default:
			/* getopt_long() said what was wrong. */
			return usage_error();
		}
	}
	if (optind >= argc) {
		msg("no TTY given");
		return usage_error();
	}
	if (optind < argc - 1) {
		msg("one TTY only (\"%s\" is extra)", argv[optind + 1]);
		return usage_error();
	}
	if (label && !label_ok(label)) {
		msg("bad label \"%s\": up to %d characters from [A-Za-z0-9_.-]",
		    label, LEGO_EV3_LABEL_LEN - 1);
		return EXIT_USAGE;
	}
	if (do_detach && (label || daemon_mode || pidfile || wait_s)) {
		msg("--detach takes no --label, --daemon, --pidfile or --wait");
		return EXIT_USAGE;
	}
	if (wait_s && !daemon_mode) {
		msg("--wait needs --daemon");
		return EXIT_USAGE;
	}

	name = argv[optind];
	if (!*name) {
		msg("empty TTY name");
		return usage_error();
	}
	if (strchr(name, '/'))
		ret = snprintf(path, sizeof(path), "%s", name);
	else
		ret = snprintf(path, sizeof(path), "/dev/%s", name);
	if (ret < 0 || (size_t)ret >= sizeof(path)) {
		msg("tty name too long");
		return EXIT_USAGE;
	}

	if (do_detach)
		return detach(path, num);

	ret = open_tty(path, &fd);
	if (ret)
		return ret;
	if (get_ldisc(fd) == num) {
		msg("%s: line discipline %d is already attached %s", path, num,
		    "(another lego-ev3-attach or ldattach?)");
		close(fd);
		return EXIT_BUSY;
	}

	/* Signals are read from a signalfd while the tty is held. */
	sigemptyset(&block);
	sigaddset(&block, SIGTERM);
	sigaddset(&block, SIGINT);
	sigaddset(&block, SIGHUP);
	sigprocmask(SIG_BLOCK, &block, NULL);
	sfd = signalfd(-1, &block, SFD_CLOEXEC);
	if (sfd < 0) {
		msg("signalfd: %s", strerror(errno));
		close(fd);
		return EXIT_FAIL;
	}

	have_saved = !tcgetattr(fd, &saved);
	set_raw(fd, path);
	ret = set_ldisc(fd, path, num);
	if (ret)
		goto out_termios;
	if (label) {
		ret = set_label(fd, path, label);
		if (ret)
			goto out_ldisc;
	}

	if (daemon_mode) {
		if (!pidfile) {
			name = strrchr(path, '/') + 1;
			snprintf(defpid, sizeof(defpid),
				 "/run/lego-ev3-attach-%s.pid", name);
			pidfile = defpid;
		}
		ret = daemonize(pidfile, strrchr(path, '/') + 1, wait_s);
		if (ret)
			goto out_ldisc;
	}

	ret = hold(fd, sfd, path, num);
	if (daemon_mode && pidfile)
		unlink(pidfile);

out_ldisc:
	/* Put N_TTY back unless someone else changed the discipline. */
	if (get_ldisc(fd) == num && ioctl(fd, TIOCSETD, &ntty))
		msg("%s: cannot put N_TTY back: %s", path, strerror(errno));
out_termios:
	if (have_saved)
		tcsetattr(fd, TCSANOW, &saved);
	close(fd);
	close(sfd);
	return ret;
}
