/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensor protocol: message framing.
 *
 * Pure functions with no tty, timer or device calls, so that they can be
 * tested with KUnit and fuzzed in userspace.
 */
#ifndef _EV3_UART_PROTO_H
#define _EV3_UART_PROTO_H

#include <linux/types.h>

/* Message header: 0bTTLLLCCC, T = message type, L = log2(payload), C = command/mode. */
#define EV3_UART_MSG_TYPE_MASK		0xc0
#define EV3_UART_MSG_SIZE_MASK		0x38
#define EV3_UART_MSG_SIZE_SHIFT		3
#define EV3_UART_MSG_CMD_MASK		0x07

/**
 * enum ev3_uart_msg_type - the two top bits of a message header
 * @EV3_UART_MSG_SYS: one-byte system message (SYNC, NACK, ACK)
 * @EV3_UART_MSG_CMD: command (TYPE, MODES, SPEED, SELECT, WRITE)
 * @EV3_UART_MSG_INFO: mode information, with an extra info-type byte
 * @EV3_UART_MSG_DATA: sensor values for one mode
 */
enum ev3_uart_msg_type {
	EV3_UART_MSG_SYS	= 0x00,
	EV3_UART_MSG_CMD	= 0x40,
	EV3_UART_MSG_INFO	= 0x80,
	EV3_UART_MSG_DATA	= 0xc0,
};

/* The largest payload any sensor or host uses; the header allows 128. */
#define EV3_UART_MAX_PAYLOAD		32
/* Header + INFO byte + payload + checksum. */
#define EV3_UART_MAX_MSG_LEN		(EV3_UART_MAX_PAYLOAD + 3)

u8 ev3_uart_checksum(const u8 *msg, size_t len);
unsigned int ev3_uart_payload_len(u8 hdr);
unsigned int ev3_uart_msg_len(u8 hdr);

#endif /* _EV3_UART_PROTO_H */
