/* SPDX-License-Identifier: GPL-2.0 */
/* The reference parser of ev3_ref.c: ev3_uart_proto.c without its fast path. */
#ifndef _LEGO_FUZZ_EV3_REF_H
#define _LEGO_FUZZ_EV3_REF_H

#include "ev3_uart_proto.h"

void ref_ev3_uart_parser_init(struct ev3_uart_parser *p);
size_t ref_ev3_uart_parser_feed(struct ev3_uart_parser *p, const u8 *buf,
				size_t len, struct ev3_uart_event *ev);
void ref_ev3_uart_parser_line_error(struct ev3_uart_parser *p,
				    struct ev3_uart_event *ev);
void ref_ev3_uart_parser_start_data(struct ev3_uart_parser *p);
int ref_ev3_uart_parser_select(struct ev3_uart_parser *p, u8 mode);
bool ref_ev3_uart_parser_tick(struct ev3_uart_parser *p,
			      struct ev3_uart_event *ev);
int ref_ev3_uart_parser_probe(struct ev3_uart_parser *p, u32 speed);
u32 ref_ev3_uart_parser_probe_end(struct ev3_uart_parser *p);

#endif /* _LEGO_FUZZ_EV3_REF_H */
