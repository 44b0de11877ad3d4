/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensors: trace events (trace system
 * lego_ev3_uart). Emitted by the line discipline (ev3_uart_ldisc.c) on what
 * the protocol parser reports, never from the parser's byte loop: disabled,
 * each costs a patched-out branch. Documentation/lego/tracing.rst shows how
 * to capture them.
 */
#undef TRACE_SYSTEM
#define TRACE_SYSTEM lego_ev3_uart

#if !defined(_EV3_UART_TRACE_H) || defined(TRACE_HEADER_MULTI_READ)
#define _EV3_UART_TRACE_H

#include <linux/tracepoint.h>

#include "lego_compat.h"

#ifndef _EV3_UART_TRACE_ONCE
#define _EV3_UART_TRACE_ONCE
/* What a received or sent message was (ev3_uart_rx, ev3_uart_tx). */
enum ev3_uart_trace_msg {
	EV3_UART_TRACE_TYPE,
	EV3_UART_TRACE_ACK,
	EV3_UART_TRACE_NACK,
	EV3_UART_TRACE_SELECT,
	EV3_UART_TRACE_WRITE,
	EV3_UART_TRACE_DATA,
	EV3_UART_TRACE_CMD,
	EV3_UART_TRACE_INFO,
	EV3_UART_TRACE_SPEED,
};

/* How a DATA message was accepted (ev3_uart_rx). */
enum ev3_uart_trace_accept {
	EV3_UART_TRACE_NONE,
	EV3_UART_TRACE_CSUM,
	EV3_UART_TRACE_QUIRK_RGB_RAW,
	EV3_UART_TRACE_QUIRK_US_DC_IN,
};

/* What happened to a sensor (ev3_uart_sensor). */
enum ev3_uart_trace_sensor {
	EV3_UART_TRACE_REGISTERED,
	EV3_UART_TRACE_LOST,
	EV3_UART_TRACE_CLOSED,
	EV3_UART_TRACE_FAILED,
};
#endif

TRACE_DEFINE_ENUM(EV3_UART_TRACE_TYPE);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_ACK);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_NACK);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_SELECT);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_WRITE);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_DATA);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_CMD);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_INFO);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_SPEED);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_NONE);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_CSUM);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_QUIRK_RGB_RAW);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_QUIRK_US_DC_IN);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_REGISTERED);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_LOST);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_CLOSED);
TRACE_DEFINE_ENUM(EV3_UART_TRACE_FAILED);

/*
 * A message received: TYPE (a handshake starts; @arg is the sensor type),
 * CMD (@arg: the command), INFO (@arg: the mode, @info the INFO type), ACK
 * (the handshake is complete; @arg is the number of modes) or DATA (@arg is
 * the mode). @hdr: its header; @len: the whole message's length (DATA: the
 * payload's). CMD and INFO are traced only while this event is enabled
 * (the parser reports them then only).
 */
TRACE_EVENT(ev3_uart_rx,
	    TP_PROTO(const char *tty, u8 msg, u8 hdr, u8 arg, u8 info, u8 len,
		     u8 accept, bool mode_changed),
	    TP_ARGS(tty, msg, hdr, arg, info, len, accept, mode_changed),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u8, msg)
			     __field(u8, hdr)
			     __field(u8, arg)
			     __field(u8, info)
			     __field(u8, len)
			     __field(u8, accept)
			     __field(bool, mode_changed)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->msg = msg;
			   __entry->hdr = hdr;
			   __entry->arg = arg;
			   __entry->info = info;
			   __entry->len = len;
			   __entry->accept = accept;
			   __entry->mode_changed = mode_changed;),
	    TP_printk("tty=%s msg=%s hdr=0x%02x arg=%u info=0x%02x len=%u accept=%s mode_changed=%d",
		      __get_str(tty),
		      __print_symbolic(__entry->msg,
				       { EV3_UART_TRACE_TYPE, "TYPE" },
				       { EV3_UART_TRACE_ACK, "ACK" },
				       { EV3_UART_TRACE_NACK, "NACK" },
				       { EV3_UART_TRACE_SELECT, "SELECT" },
				       { EV3_UART_TRACE_WRITE, "WRITE" },
				       { EV3_UART_TRACE_DATA, "DATA" },
				       { EV3_UART_TRACE_CMD, "CMD" },
				       { EV3_UART_TRACE_INFO, "INFO" }),
		      __entry->hdr, __entry->arg, __entry->info, __entry->len,
		      __print_symbolic(__entry->accept,
				       { EV3_UART_TRACE_NONE, "-" },
				       { EV3_UART_TRACE_CSUM, "checksum" },
				       { EV3_UART_TRACE_QUIRK_RGB_RAW, "rgb-raw-quirk" },
				       { EV3_UART_TRACE_QUIRK_US_DC_IN, "us-dc-in-quirk" }),
		      __entry->mode_changed)
);

/* The sensor's handshake, complete (its ACK came). */
TRACE_EVENT(ev3_uart_handshake,
	    TP_PROTO(const char *tty, u8 type, u8 num_modes, u8 num_view_modes,
		     u32 speed),
	    TP_ARGS(tty, type, num_modes, num_view_modes, speed),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u8, type)
			     __field(u8, num_modes)
			     __field(u8, num_view_modes)
			     __field(u32, speed)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->type = type;
			   __entry->num_modes = num_modes;
			   __entry->num_view_modes = num_view_modes;
			   __entry->speed = speed;),
	    TP_printk("tty=%s type=%u modes=%u view_modes=%u speed=%u",
		      __get_str(tty), __entry->type, __entry->num_modes,
		      __entry->num_view_modes, __entry->speed)
);

/*
 * A message sent to the sensor: ACK, NACK, SELECT (@arg: the mode), WRITE
 * (@arg: its first byte) or SPEED (the fast sync probe, at the speed it
 * offers); @len bytes; @ret 0 or the tty's error.
 */
TRACE_EVENT(ev3_uart_tx,
	    TP_PROTO(const char *tty, u8 msg, u8 hdr, u8 arg, u8 len, int ret),
	    TP_ARGS(tty, msg, hdr, arg, len, ret),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u8, msg)
			     __field(u8, hdr)
			     __field(u8, arg)
			     __field(u8, len)
			     __field(int, ret)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->msg = msg;
			   __entry->hdr = hdr;
			   __entry->arg = arg;
			   __entry->len = len;
			   __entry->ret = ret;),
	    TP_printk("tty=%s msg=%s hdr=0x%02x arg=%u len=%u ret=%d",
		      __get_str(tty),
		      __print_symbolic(__entry->msg,
				       { EV3_UART_TRACE_TYPE, "TYPE" },
				       { EV3_UART_TRACE_ACK, "ACK" },
				       { EV3_UART_TRACE_NACK, "NACK" },
				       { EV3_UART_TRACE_SELECT, "SELECT" },
				       { EV3_UART_TRACE_WRITE, "WRITE" },
				       { EV3_UART_TRACE_DATA, "DATA" },
				       { EV3_UART_TRACE_CMD, "CMD" },
				       { EV3_UART_TRACE_INFO, "INFO" },
				       { EV3_UART_TRACE_SPEED, "SPEED" }),
		      __entry->hdr, __entry->arg, __entry->len, __entry->ret)
);

/* The tty was switched to @speed baud (@ret: 0 or -EINVAL if it could not). */
TRACE_EVENT(ev3_uart_speed,
	    TP_PROTO(const char *tty, u32 speed, int ret),
	    TP_ARGS(tty, speed, ret),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u32, speed)
			     __field(int, ret)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->speed = speed;
			   __entry->ret = ret;),
	    TP_printk("tty=%s speed=%u ret=%d", __get_str(tty), __entry->speed,
		      __entry->ret)
);

/* The parser went from state @from to @to (enum ev3_uart_state), and why. */
TRACE_EVENT(ev3_uart_state,
	    TP_PROTO(const char *tty, u8 from, u8 to, const char *reason),
	    TP_ARGS(tty, from, to, reason),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u8, from)
			     __field(u8, to)
			     __string(reason, reason)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->from = from;
			   __entry->to = to;
			   lego_assign_str(reason, reason);),
	    TP_printk("tty=%s from=%s to=%s reason=\"%s\"", __get_str(tty),
		      __print_symbolic(__entry->from,
				       { 0, "SYNC" },
				       { 1, "INFO" },
				       { 2, "ACKED" },
				       { 3, "DATA" },
				       { 4, "PROBE" }),
		      __print_symbolic(__entry->to,
				       { 0, "SYNC" },
				       { 1, "INFO" },
				       { 2, "ACKED" },
				       { 3, "DATA" },
				       { 4, "PROBE" }),
		      __get_str(reason))
);

/* A sensor was registered, lost, dropped on close, or failed to register. */
TRACE_EVENT(ev3_uart_sensor,
	    TP_PROTO(const char *tty, u8 what, u8 type, const char *driver,
		     const char *dev, u32 speed),
	    TP_ARGS(tty, what, type, driver, dev, speed),
	    TP_STRUCT__entry(__string(tty, tty)
			     __field(u8, what)
			     __field(u8, type)
			     __string(driver, driver)
			     __string(dev, dev)
			     __field(u32, speed)),
	    TP_fast_assign(lego_assign_str(tty, tty);
			   __entry->what = what;
			   __entry->type = type;
			   lego_assign_str(driver, driver);
			   lego_assign_str(dev, dev);
			   __entry->speed = speed;),
	    TP_printk("tty=%s event=%s type=%u driver=%s dev=%s speed=%u",
		      __get_str(tty),
		      __print_symbolic(__entry->what,
				       { EV3_UART_TRACE_REGISTERED, "registered" },
				       { EV3_UART_TRACE_LOST, "lost" },
				       { EV3_UART_TRACE_CLOSED, "closed" },
				       { EV3_UART_TRACE_FAILED, "failed" }),
		      __entry->type, __get_str(driver), __get_str(dev),
		      __entry->speed)
);

#endif /* _EV3_UART_TRACE_H */

/* This part must be outside the header guard. */
#undef TRACE_INCLUDE_PATH
#define TRACE_INCLUDE_PATH .
#undef TRACE_INCLUDE_FILE
#define TRACE_INCLUDE_FILE ev3_uart_trace

#include <trace/define_trace.h>
