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

#include "legonxt.h"

#define ARRAY_SIZE(a)	(sizeof(a) / sizeof((a)[0]))

/* Exit codes, see Documentation/lego/nxtctl.rst */
#define EXIT_OK		0
#define EXIT_BRICK	1	/* the brick answered with an error status */
#define EXIT_USAGE	2	/* bad command line */
#define EXIT_DEVICE	3	/* device, transport or local I/O error */
#define EXIT_HELP	(-1)	/* --help printed: exit 0 without running */

/* What nxtctl accepts beyond the firmware's own limits. */
#define TONE_MIN_HZ	200	/* what the brick's speaker plays */
#define TONE_MAX_HZ	14000
#define POWER_MAX	100	/* motor power and turn ratio */
#define INBOXES		10	/* mailbox-send: the program's inboxes */
#define REMOTE_INBOXES	20	/* mailbox-read: 10 to 19 for the PC */

extern int nxt_fd;
extern const char *dev_path;

const char *status_name(unsigned int status);
int brick_error(const char *what, unsigned int status);
int sys_error(const char *what, int err);
int usage_error(const char *cmd, const char *fmt, ...);
void load_telegram(struct nxt_transaction *t, const struct lnxt_msg *m);
int transact(struct nxt_transaction *t, const char *what);
int exchange(const struct lnxt_msg *m, struct nxt_transaction *t, int *status,
	     const char *what);
int command(const struct lnxt_msg *m, struct nxt_transaction *t, const char *what);
int bad_reply(const char *what);
int check_name(const char *cmd, const char *name);

void progress_end(void);

int cmd_upload(int argc, char **argv);
int cmd_download(int argc, char **argv);
int cmd_ls(int argc, char **argv);
int cmd_rm(int argc, char **argv);
int cmd_release(int argc, char **argv);
int cmd_claim(int argc, char **argv);
int cmd_trace(int argc, char **argv);
int cmd_attach(int argc, char **argv);
int cmd_connect(int argc, char **argv);
int cmd_disconnect(int argc, char **argv);

/* Options of a subcommand: "--name" or "--name VALUE". */
struct opt {
	const char *name;
	int has_arg;
	int set;
	const char *arg;
};

int parse_opts(const char *cmd, int argc, char **argv, struct opt *opts,
	       char **pos, int *npos, int min, int max);

#endif /* NXTCTL_H */
