/* SPDX-License-Identifier: GPL-2.0 WITH Linux-syscall-note */
/*
 * LEGO MINDSTORMS NXT brick: userspace interface of /dev/nxtN.
 *
 * A telegram is what the brick's firmware calls one command or reply: a
 * type byte, an opcode and the command's arguments, at most one 64-byte
 * USB packet.
 *
 * Two ways to talk to a brick through /dev/nxtN, for any command of any
 * firmware:
 *
 *  - write() one telegram, then read() its reply (only telegrams of type
 *    NXT_DIRECT_CMD and NXT_SYSTEM_CMD get one);
 *  - NXT_IOC_TRANSACT: one telegram and its reply in a single call.
 *
 * The driver checks that a telegram holds every byte its command reads
 * (the firmware would take stale bytes of earlier telegrams for the
 * missing ones) and routes each reply to the caller whose telegram it
 * answers. It does not build or decode commands: the reply comes back as
 * the brick sent it, its status byte (the third) included, and an errno
 * always means that the telegram or the transport failed, never that the
 * brick refused a command. liblegonxt (pkg-config legonxt) builds every
 * direct and system command, checks its arguments and decodes the replies.
 *
 * Both need a file opened for writing (EBADF otherwise): a file opened
 * O_RDONLY cannot make the brick act. NXT_IOC_SET_TIMEOUT and
 * NXT_IOC_GET_TIMEOUT send nothing and work on any open file.
 *
 * ioctl numbers 0x10 to 0x33 of NXT_IOC_MAGIC belonged to typed direct
 * commands in releases of this driver outside the kernel; they are not
 * reused, and fail with ENOTTY.
 */
#ifndef _UAPI_LINUX_LEGO_NXT_H
#define _UAPI_LINUX_LEGO_NXT_H

#include <linux/ioctl.h>
#include <linux/tty.h>
#include <linux/types.h>

#ifndef N_LEGONXT
/*
 * N_LEGONXT - the line discipline of a brick on a serial line (Bluetooth's
 * RFCOMM tty, or any tty that carries the brick's Bluetooth framing). A
 * kernel that has the driver in its tree reserves a number in
 * <linux/tty.h>; the out-of-tree module takes 8 (N_MASC), reserved for a
 * Mobitex driver that never reached the kernel and used by none in it
 * (N_DEVELOPMENT is lego_ev3_uart's). tools/upstream/series.sh drops this
 * block (unifdef).
 */
#define N_LEGONXT		8
#endif

/** NXT_TELEGRAM_MIN - shortest telegram: the type byte and the opcode */
#define NXT_TELEGRAM_MIN	2
/** NXT_TELEGRAM_MAX - longest telegram: one full-speed bulk packet */
#define NXT_TELEGRAM_MAX	64

/**
 * enum nxt_telegram_type - the first byte of every telegram
 * @NXT_DIRECT_CMD: direct command, the brick replies
 * @NXT_SYSTEM_CMD: system command, the brick replies
 * @NXT_REPLY: a reply from the brick
 * @NXT_DIRECT_CMD_NOREPLY: direct command, no reply
 * @NXT_SYSTEM_CMD_NOREPLY: system command, no reply
 */
enum nxt_telegram_type {
	NXT_DIRECT_CMD		= 0x00,
	NXT_SYSTEM_CMD		= 0x01,
	NXT_REPLY		= 0x02,
	NXT_DIRECT_CMD_NOREPLY	= 0x80,
	NXT_SYSTEM_CMD_NOREPLY	= 0x81,
};

/**
 * struct nxt_transaction - NXT_IOC_TRANSACT: one telegram and its reply
 * @telegram: in: the telegram, type byte first (any direct or system command)
 * @reply: out: the brick's reply as it came, its status byte (@reply[2])
 *	included, checked only for its type byte, its echoed opcode and its
 *	length; the bytes past @reply_length are zero
 * @length: in: length of @telegram, NXT_TELEGRAM_MIN to NXT_TELEGRAM_MAX
 * @reply_length: out: length of @reply; 0 for a telegram that asks for none
 *
 * The bytes of @telegram past @length, and @reply and @reply_length on the
 * way in, are not read.
 */
struct nxt_transaction {
	__u8 telegram[NXT_TELEGRAM_MAX];
	__u8 reply[NXT_TELEGRAM_MAX];
	__u32 length;
	__u32 reply_length;
};

#define NXT_IOC_MAGIC		0xE4

/**
 * NXT_IOC_TRANSACT - send any telegram and wait for its reply
 *
 * Success means that the reply came, whatever its status byte says.
 * Errors: EBADF (the file is not open for writing), EINVAL (@length under
 * NXT_TELEGRAM_MIN or under what the telegram's command reads, or a type
 * byte that is not a command), EMSGSIZE (@length over NXT_TELEGRAM_MAX),
 * ETIMEDOUT (no reply within the file's timeout), EPROTO (only packets
 * that were not the reply came within the timeout: wrong type, opcode,
 * length, or echoed port or inbox), EPIPE (an endpoint stalled), EIO (a
 * USB reset or suspend, or a transfer error), ENODEV (the brick was
 * unplugged), EAGAIN (O_NONBLOCK and the brick busy: nothing was sent),
 * EINTR (a signal after the telegram was sent).
 */
#define NXT_IOC_TRANSACT	_IOWR(NXT_IOC_MAGIC, 0x00, struct nxt_transaction)

/**
 * NXT_IOC_SET_TIMEOUT - set this open file's reply timeout, in milliseconds
 *
 * 1 to 60000; the default is 1000. Errors: EINVAL.
 */
#define NXT_IOC_SET_TIMEOUT	_IOW(NXT_IOC_MAGIC, 0x01, __u32)

/** NXT_IOC_GET_TIMEOUT - read this open file's reply timeout, in milliseconds */
#define NXT_IOC_GET_TIMEOUT	_IOR(NXT_IOC_MAGIC, 0x02, __u32)

/**
 * NXT_IOC_TTY_MINOR - on a tty with the N_LEGONXT discipline: the minor of
 * its brick's node (N of /dev/nxtN)
 *
 * Asked of the tty, not of /dev/nxtN (which answers ENOTTY).
 */
#define NXT_IOC_TTY_MINOR	_IOR(NXT_IOC_MAGIC, 0x03, __u32)

#endif /* _UAPI_LINUX_LEGO_NXT_H */
