// SPDX-License-Identifier: GPL-2.0
/*
 * nxtctl release / claim: hand a brick to libusb programs (nxt-python's
 * usb backend, NBC/NXC, NeXTTool, leJOS) and take it back, through the
 * raw USB device node /dev/bus/usb/BBB/DDD with the usbfs ioctls
 * USBDEVFS_DISCONNECT and USBDEVFS_CONNECT on interface 0, as
 * libusb_detach_kernel_driver() and libusb_attach_kernel_driver() do.
 * Write access to that node is all it takes: no root.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <glob.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <time.h>
#include <unistd.h>
#include <linux/usbdevice_fs.h>

#include "nxtctl.h"

#define SYS_USB		"/sys/bus/usb/devices"
#define NXT_DRIVER	"lego_nxt_usb"
#define NODE_WAIT_MS	5000	/* claim: for /dev/nxtN to appear */

/* A brick as a USB device: its sysfs directory and what is in there. */
struct usb_brick {
	char dir[PATH_MAX];	/* /sys/devices/.../1-1 */
	char node[64];		/* /dev/bus/usb/001/002 */
	char serial[32];
};

static int read_line(const char *dir, const char *attr, char *buf, size_t size)
{
	char path[PATH_MAX + 64];
	size_t n;
	FILE *f;

	snprintf(path, sizeof(path), "%s/%s", dir, attr);
	f = fopen(path, "r");
	if (!f)
		return -1;
	n = fread(buf, 1, size - 1, f);
	fclose(f);
	buf[n] = 0;
	buf[strcspn(buf, "\n")] = 0;
	return 0;
}

static int is_nxt(const char *dir)
{
	char vid[8], pid[8];

	return !read_line(dir, "idVendor", vid, sizeof(vid)) &&
	       !read_line(dir, "idProduct", pid, sizeof(pid)) &&
	       !strcmp(vid, "0694") && !strcmp(pid, "0002");
}

/* Fill @b from the USB device directory @dir: 0, or -1 if not an NXT. */
static int brick_at(const char *dir, struct usb_brick *b)
{
	char bus[16], dev[16];

	if (!is_nxt(dir) || read_line(dir, "busnum", bus, sizeof(bus)) ||
	    read_line(dir, "devnum", dev, sizeof(dev)))
		return -1;
	snprintf(b->dir, sizeof(b->dir), "%s", dir);
	snprintf(b->node, sizeof(b->node), "/dev/bus/usb/%03d/%03d", atoi(bus), atoi(dev));
	if (read_line(dir, "serial", b->serial, sizeof(b->serial)))
		snprintf(b->serial, sizeof(b->serial), "?");
	return 0;
}

/*
 * The brick behind a device node: /dev/nxtN (its interface's parent) or
 * the raw /dev/bus/usb/BBB/DDD (the USB device itself).
 */
static int brick_of_node(const char *cmd, const char *path, struct usb_brick *b)
{
	char link[64], real[PATH_MAX], *slash;
	struct stat st;

	if (stat(path, &st)) {
		fprintf(stderr, "nxtctl: %s: %s: %s\n", cmd, path, strerror(errno));
		return EXIT_DEVICE;
	}
	if (!S_ISCHR(st.st_mode))
		goto not_nxt;
	snprintf(link, sizeof(link), "/sys/dev/char/%u:%u", major(st.st_rdev),
		 minor(st.st_rdev));
	if (!realpath(link, real))
		goto not_nxt;
	if (!brick_at(real, b))
		return EXIT_OK;
	/* /dev/nxtN: .../1-1/1-1:1.0/lego-nxt/nxt0, its device the interface. */
	snprintf(link + strlen(link), sizeof(link) - strlen(link), "/device");
	if (!realpath(link, real))
		goto not_nxt;
	slash = strrchr(real, '/');
	if (slash) {
		*slash = 0;
		if (!brick_at(real, b))
			return EXIT_OK;
	}
not_nxt:
	fprintf(stderr, "nxtctl: %s: %s is not an NXT brick ", cmd, path);
	fprintf(stderr, "(neither /dev/nxtN nor its /dev/bus/usb node)\n");
	return EXIT_DEVICE;
}

/* The driver bound to interface 0: 0 and its name, or -1 and errno. */
static int get_driver(int fd, char *name, size_t size)
{
	struct usbdevfs_getdriver gd = { .interface = 0 };

	if (ioctl(fd, USBDEVFS_GETDRIVER, &gd) < 0)
		return -1;
	gd.driver[sizeof(gd.driver) - 1] = 0;
	snprintf(name, size, "%s", gd.driver);
	return 0;
}

static int usb_ioctl(int fd, unsigned int code)
{
	struct usbdevfs_ioctl c = { .ifno = 0, .ioctl_code = code, .data = NULL };

	return ioctl(fd, USBDEVFS_IOCTL, &c);
}

static int open_usb(const char *cmd, const struct usb_brick *b)
{
	int fd = open(b->node, O_RDWR | O_CLOEXEC);

	if (fd < 0) {
		int err = errno;

		fprintf(stderr, "nxtctl: %s: cannot open %s: %s\n", cmd, b->node, strerror(err));
		if (err == EACCES || err == EPERM)
			fputs("nxtctl: the udev rules give it to the group lego and\n"
			      "nxtctl: the user at the seat; see nxtctl(1)\n", stderr);
	}
	return fd;
}

/* /dev/nxtN of a bound brick, from its interface's lego-nxt directory. */
static int node_of(const struct usb_brick *b, char *node, size_t size)
{
	char pattern[PATH_MAX + 32];
	glob_t g;
	int ret = -1;

	snprintf(pattern, sizeof(pattern), "%s/*:1.0/lego-nxt/nxt*", b->dir);
	if (glob(pattern, 0, NULL, &g))
		return -1;
	snprintf(node, size, "/dev/%s", strrchr(g.gl_pathv[0], '/') + 1);
	ret = 0;
	globfree(&g);
	return ret;
}

/*
 * Every NXT on the USB buses, with --serial only that one, and with
 * @released only those that lego_nxt_usb does not have (no driver, or
 * usbfs for a libusb program). Returns how many
 * matched, the first in @b.
 */
static int scan_bricks(const char *serial, int released, struct usb_brick *b,
		       char *names, size_t size)
{
	struct usb_brick cur;
	char dir[PATH_MAX], drv[PATH_MAX + 300], real[PATH_MAX];
	struct dirent *e;
	int n = 0;
	DIR *d;

	*names = 0;
	d = opendir(SYS_USB);
	if (!d)
		return 0;
	while ((e = readdir(d))) {
		if (e->d_name[0] == '.' || strchr(e->d_name, ':'))
			continue;
		snprintf(dir, sizeof(dir), SYS_USB "/%s", e->d_name);
		if (brick_at(dir, &cur))
			continue;
		if (serial && strcasecmp(serial, cur.serial))
			continue;
		snprintf(drv, sizeof(drv), "%s/%s:1.0/driver", dir, e->d_name);
		if (released && realpath(drv, real) && !strcmp(strrchr(real, '/') + 1, NXT_DRIVER))
			continue;
		if (!n)
			*b = cur;
		if (strlen(names) + strlen(cur.node) + strlen(cur.serial) + 8 < size)
			sprintf(names + strlen(names), "\n  %s (%s)", cur.node, cur.serial);
		n++;
	}
	closedir(d);
	return n;
}

/*
 * Which brick: -d DEVICE (/dev/nxtN or /dev/bus/usb/BBB/DDD), --serial,
 * else for release the brick nxtctl would use ($NXT_DEVICE, the first
 * /dev/nxt*), for claim the only released one.
 */
static int pick_brick(const char *cmd, const char *serial, int released,
		      struct usb_brick *b)
{
	char names[1024];
	const char *dev = dev_path;
	glob_t g;
	int n, ret;

	if (dev && serial)
		return usage_error(cmd, "%s: -d and --serial exclude each other", cmd);
	if (!dev && !serial && !released) {
		dev = getenv("NXT_DEVICE");
		if (!dev || !*dev) {
			if (glob("/dev/nxt[0-9]*", 0, NULL, &g)) {
				fprintf(stderr, "nxtctl: %s: no NXT brick found ", cmd);
				fputs("(no /dev/nxt* device)\n", stderr);
				return EXIT_DEVICE;
			}
			ret = brick_of_node(cmd, g.gl_pathv[0], b);
			globfree(&g);
			return ret;
		}
	}
	if (dev)
		return brick_of_node(cmd, dev, b);
	n = scan_bricks(serial, released, b, names, sizeof(names));
	if (n == 1)
		return EXIT_OK;
	if (!n) {
		fprintf(stderr, "nxtctl: %s: no %sNXT brick%s%s on USB\n", cmd,
			released ? "released " : "", serial ? " with serial " : "",
			serial ? serial : "");
		return EXIT_DEVICE;
	}
	fprintf(stderr, "nxtctl: %s: %d %sbricks; choose one with -d or --serial:%s\n",
		cmd, n, released ? "released " : "", names);
	return EXIT_USAGE;
}

static int cmd_release_claim(const char *cmd, int claim, int argc, char **argv)
{
	struct opt opts[] = { { .name = "serial", .has_arg = 1 }, {} };
	char drv[256], node[64], *pos[1];
	struct usb_brick b;
	int npos, ret, fd, waited;

	ret = parse_opts(cmd, argc, argv, opts, pos, &npos, 0, 0);
	if (ret)
		return ret;
	ret = pick_brick(cmd, opts[0].set ? opts[0].arg : NULL, claim, &b);
	if (ret)
		return ret;
	fd = open_usb(cmd, &b);
	if (fd < 0)
		return EXIT_DEVICE;
	if (get_driver(fd, drv, sizeof(drv))) {
		if (errno != ENODATA) {
			ret = sys_error(cmd, errno);
			goto out;
		}
		drv[0] = 0;
	}

	if (!claim) {
		if (!drv[0] || strcmp(drv, NXT_DRIVER)) {
			/* Released already, or in a libusb program's hands. */
			printf("%s %s: released already%s%s\n", b.serial, b.node,
			       drv[0] ? ", claimed by " : "", drv);
			goto out;
		}
		if (usb_ioctl(fd, USBDEVFS_DISCONNECT) < 0) {
			ret = sys_error("release: USBDEVFS_DISCONNECT", errno);
			goto out;
		}
		printf("%s %s: released\n", b.serial, b.node);
		goto out;
	}

	if (!strcmp(drv, NXT_DRIVER))
		goto claimed;
	if (drv[0]) {
		fprintf(stderr, "nxtctl: claim: %s: %s: the brick is in use by %s ",
			b.node, strerror(EBUSY), drv);
		fputs("(a libusb program?); close it first\n", stderr);
		ret = EXIT_DEVICE;
		goto out;
	}
	if (usb_ioctl(fd, USBDEVFS_CONNECT) < 0) {
		ret = sys_error("claim: USBDEVFS_CONNECT", errno);
		goto out;
	}
	if (get_driver(fd, drv, sizeof(drv)) || strcmp(drv, NXT_DRIVER)) {
		fprintf(stderr, "nxtctl: claim: %s: %s did not take the brick: ",
			b.node, NXT_DRIVER);
		fprintf(stderr, "is the module loaded (modprobe %s)?\n", NXT_DRIVER);
		ret = EXIT_DEVICE;
		goto out;
	}
claimed:
	/* The driver made /dev/nxtN; udev may still be setting its mode. */
	for (waited = 0; ; waited += 20) {
		if (!node_of(&b, node, sizeof(node)) && access(node, F_OK) == 0)
			break;
		if (waited >= NODE_WAIT_MS) {
			fprintf(stderr, "nxtctl: claim: %s: %s: no /dev/nxtN appeared\n",
				b.node, strerror(ETIMEDOUT));
			ret = EXIT_DEVICE;
			goto out;
		}
		nanosleep(&(struct timespec){ 0, 20 * 1000000L }, NULL);
	}
	printf("%s %s: claimed as %s\n", b.serial, b.node, node);
out:
	close(fd);
	return ret;
}

int cmd_release(int argc, char **argv)
{
	return cmd_release_claim("release", 0, argc, argv);
}

int cmd_claim(int argc, char **argv)
{
	return cmd_release_claim("claim", 1, argc, argv);
}
