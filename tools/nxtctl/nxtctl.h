/* SPDX-License-Identifier: GPL-2.0 */
/*
 * nxtctl: drive a LEGO MINDSTORMS NXT brick through /dev/nxtN.
 * Shared declarations of nxtctl.c (the commands) and files.c (the flash
 * file system through system commands).
 */
#ifndef NXTCTL_H
#define NXTCTL_H

#include <stddef.h>
#include <linux/types.h>
#include <linux/lego_nxt.h>

#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))

/* Exit codes, see Documentation/lego/nxtctl.rst */
#define EXIT_OK		0
#define EXIT_BRICK	1	/* the brick answered with an error status */
#define EXIT_USAGE	2	/* bad command line */
#define EXIT_DEVICE	3	/* device, transport or local I/O error */
#define EXIT_HELP	(-1)	/* --help printed: exit 0 without running */

/* System command opcodes used by nxtctl. */
#define NXT_SYS_OPEN_READ	0x80
#define NXT_SYS_OPEN_WRITE	0x81
#define NXT_SYS_READ		0x82
#define NXT_SYS_WRITE		0x83
#define NXT_SYS_CLOSE		0x84
#define NXT_SYS_DELETE		0x85
#define NXT_SYS_FIND_FIRST	0x86
#define NXT_SYS_FIND_NEXT	0x87
#define NXT_SYS_GET_VERSIONS	0x88
#define NXT_SYS_SET_BRICK_NAME	0x98
#define NXT_SYS_GET_DEVICE_INFO	0x9b

/* Data bytes of one Read reply and one Write telegram over USB. */
#define NXT_READ_CHUNK		58
#define NXT_WRITE_CHUNK		(NXT_TELEGRAM_MAX - 3)

extern int nxt_fd;
extern const char *dev_path;

const char *status_name(unsigned int status);
int brick_error(const char *what, unsigned int status);
int sys_error(const char *what, int err);
int usage_error(const char *cmd, const char *fmt, ...);
int transact(struct nxt_transaction *t, const char *what);
int system_cmd(struct nxt_transaction *t, __u8 op, const void *args,
	       size_t len, const char *what);
int check_name(const char *cmd, const char *name);

void progress_end(void);

int cmd_upload(int argc, char **argv);
int cmd_download(int argc, char **argv);
int cmd_ls(int argc, char **argv);
int cmd_rm(int argc, char **argv);
int cmd_release(int argc, char **argv);
int cmd_claim(int argc, char **argv);
int cmd_trace(int argc, char **argv);

/* Options of a subcommand: "--name" or "--name VALUE". */
struct opt {
	const char *name;
	int has_arg;
	int set;
	const char *arg;
};

int parse_opts(const char *cmd, int argc, char **argv, struct opt *opts,
	       char **pos, int *npos, int min, int max);

/* Wire data is little-endian whatever the host's byte order. */
static inline __u16 get_le16(const __u8 *p)
{
	return p[0] | p[1] << 8;
}

static inline __u32 get_le32(const __u8 *p)
{
	return p[0] | p[1] << 8 | p[2] << 16 | (__u32)p[3] << 24;
}

static inline void put_le16(__u8 *p, __u16 v)
{
	p[0] = v;
	p[1] = v >> 8;
}

static inline void put_le32(__u8 *p, __u32 v)
{
	p[0] = v;
	p[1] = v >> 8;
	p[2] = v >> 16;
	p[3] = v >> 24;
}

#endif /* NXTCTL_H */
