// SPDX-License-Identifier: GPL-2.0
/*
 * LEGO MINDSTORMS EV3 UART sensor protocol: message framing.
 *
 * Every message but the one-byte system messages ends in a checksum, the
 * XOR of 0xff with every byte before it. The payload length is a power of
 * two given by the header; INFO messages carry one more byte (the info type)
 * between the header and the payload.
 */
#include <linux/export.h>
#include <linux/module.h>

#include "lego_compat.h"
#include "ev3_uart_proto.h"

/**
 * ev3_uart_checksum() - compute the checksum of a message
 * @msg: the message, starting with its header
 * @len: number of bytes to cover: the whole message less its checksum byte
 *
 * Return: 0xff XOR every byte of @msg[0..@len-1].
 */
u8 ev3_uart_checksum(const u8 *msg, size_t len)
{
	u8 csum = 0xff;

	while (len--)
		csum ^= *msg++;
	return csum;
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_checksum);

/**
 * ev3_uart_payload_len() - payload length announced by a message header
 * @hdr: the message header byte
 *
 * Return: 0 for a system message, else 2^L bytes (1 to 128). Callers must
 * reject lengths above %EV3_UART_MAX_PAYLOAD themselves.
 */
unsigned int ev3_uart_payload_len(u8 hdr)
{
	if ((hdr & EV3_UART_MSG_TYPE_MASK) == EV3_UART_MSG_SYS)
		return 0;
	return 1U << ((hdr & EV3_UART_MSG_SIZE_MASK) >> EV3_UART_MSG_SIZE_SHIFT);
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_payload_len);

/**
 * ev3_uart_msg_len() - total length on the wire of the message a header starts
 * @hdr: the message header byte
 *
 * Return: 1 for a system message; header + payload + checksum for commands
 * and data; one more (the info type byte) for INFO messages.
 */
unsigned int ev3_uart_msg_len(u8 hdr)
{
	switch (hdr & EV3_UART_MSG_TYPE_MASK) {
	case EV3_UART_MSG_SYS:
		return 1;
	case EV3_UART_MSG_INFO:
		return ev3_uart_payload_len(hdr) + 3;
	default:
		return ev3_uart_payload_len(hdr) + 2;
	}
}
EXPORT_SYMBOL_IF_KUNIT(ev3_uart_msg_len);
