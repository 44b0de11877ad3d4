// SPDX-License-Identifier: GPL-2.0
/*
 * The EV3 protocol core (drivers/lego/ev3/ev3_uart_proto.c) built without
 * its data-phase fast path, its functions renamed ref_*: the reference that
 * fuzz_ev3.c's differential check feeds the same bytes to, one at a time.
 */
#define EV3_UART_PROTO_REFERENCE

#define ev3_uart_checksum		ref_ev3_uart_checksum
#define ev3_uart_payload_len		ref_ev3_uart_payload_len
#define ev3_uart_msg_len		ref_ev3_uart_msg_len
#define ev3_uart_data_size		ref_ev3_uart_data_size
#define ev3_uart_msg_time		ref_ev3_uart_msg_time
#define ev3_uart_mul_div		ref_ev3_uart_mul_div
#define ev3_uart_f32_to_fixed		ref_ev3_uart_f32_to_fixed
#define ev3_uart_read_value		ref_ev3_uart_read_value
#define ev3_uart_scale_value		ref_ev3_uart_scale_value
#define ev3_uart_driver_name		ref_ev3_uart_driver_name
#define ev3_uart_lump_driver_name	ref_ev3_uart_lump_driver_name
#define ev3_uart_build_ack		ref_ev3_uart_build_ack
#define ev3_uart_build_nack		ref_ev3_uart_build_nack
#define ev3_uart_build_select		ref_ev3_uart_build_select
#define ev3_uart_build_speed		ref_ev3_uart_build_speed
#define ev3_uart_build_write		ref_ev3_uart_build_write
#define ev3_uart_build_lump_data	ref_ev3_uart_build_lump_data
#define ev3_uart_parser_init		ref_ev3_uart_parser_init
#define ev3_uart_parser_feed		ref_ev3_uart_parser_feed
#define ev3_uart_parser_line_error	ref_ev3_uart_parser_line_error
#define ev3_uart_parser_start_data	ref_ev3_uart_parser_start_data
#define ev3_uart_parser_select		ref_ev3_uart_parser_select
#define ev3_uart_parser_tick		ref_ev3_uart_parser_tick
#define ev3_uart_parser_probe		ref_ev3_uart_parser_probe
#define ev3_uart_parser_probe_end	ref_ev3_uart_parser_probe_end
#define ev3_uart_backoff_lost		ref_ev3_uart_backoff_lost

#include "ev3_uart_proto.c"
