/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS NXT brick: trace events (trace system lego_nxt_usb).
 * Every event names the brick's USB device (e.g. "1-1"); @xfer identifies
 * the transaction, which is the open file's own (one per open /dev/nxtN)
 * or a sysfs query's. Documentation/lego/tracing.rst shows how to capture
 * them.
 */
#undef TRACE_SYSTEM
#define TRACE_SYSTEM lego_nxt_usb

#if !defined(_NXT_USB_TRACE_H) || defined(TRACE_HEADER_MULTI_READ)
#define _NXT_USB_TRACE_H

#include <linux/tracepoint.h>

#include "lego_compat.h"

#ifndef _NXT_USB_TRACE_ONCE
#define _NXT_USB_TRACE_ONCE
/* Why a packet from the brick was dropped (nxt_usb_drop). */
enum nxt_usb_trace_drop {
	NXT_USB_TRACE_DRAIN,
	NXT_USB_TRACE_STALE,
	NXT_USB_TRACE_MISMATCH,
};

/* What happened to the brick as a whole (nxt_usb_reset). */
enum nxt_usb_trace_reset {
	NXT_USB_TRACE_PRE_RESET,
	NXT_USB_TRACE_POST_RESET,
	NXT_USB_TRACE_SUSPEND,
	NXT_USB_TRACE_RESUME,
	NXT_USB_TRACE_RESET_RESUME,
	NXT_USB_TRACE_DISCONNECT,
};
#endif

TRACE_DEFINE_ENUM(NXT_USB_TRACE_DRAIN);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_STALE);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_MISMATCH);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_PRE_RESET);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_POST_RESET);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_SUSPEND);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_RESUME);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_RESET_RESUME);
TRACE_DEFINE_ENUM(NXT_USB_TRACE_DISCONNECT);

/* A telegram was submitted (@ret: 0, or usb_submit_urb()'s error). */
TRACE_EVENT(nxt_usb_tx,
	    TP_PROTO(const char *dev, const void *xfer, u8 type, u8 opcode,
		     unsigned int len, int ret),
	    TP_ARGS(dev, xfer, type, opcode, len, ret),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(const void *, xfer)
			     __field(u8, type)
			     __field(u8, opcode)
			     __field(unsigned int, len)
			     __field(int, ret)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->xfer = xfer;
			   __entry->type = type;
			   __entry->opcode = opcode;
			   __entry->len = len;
			   __entry->ret = ret;),
	    TP_printk("dev=%s xfer=%p type=0x%02x opcode=0x%02x len=%u ret=%d",
		      __get_str(dev), __entry->xfer, __entry->type,
		      __entry->opcode, __entry->len, __entry->ret)
);

/* The reply to the transaction @xfer came (type 0x02, its status byte). */
TRACE_EVENT(nxt_usb_rx,
	    TP_PROTO(const char *dev, const void *xfer, u8 type, u8 opcode,
		     u8 status, unsigned int len),
	    TP_ARGS(dev, xfer, type, opcode, status, len),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(const void *, xfer)
			     __field(u8, type)
			     __field(u8, opcode)
			     __field(u8, status)
			     __field(unsigned int, len)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->xfer = xfer;
			   __entry->type = type;
			   __entry->opcode = opcode;
			   __entry->status = status;
			   __entry->len = len;),
	    TP_printk("dev=%s xfer=%p type=0x%02x opcode=0x%02x status=0x%02x len=%u",
		      __get_str(dev), __entry->xfer, __entry->type,
		      __entry->opcode, __entry->status, __entry->len)
);

/* The transaction @xfer (telegram @opcode) ended: @err 0 or its error. */
TRACE_EVENT(nxt_usb_done,
	    TP_PROTO(const char *dev, const void *xfer, u8 opcode, int err),
	    TP_ARGS(dev, xfer, opcode, err),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(const void *, xfer)
			     __field(u8, opcode)
			     __field(int, err)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->xfer = xfer;
			   __entry->opcode = opcode;
			   __entry->err = err;),
	    TP_printk("dev=%s xfer=%p opcode=0x%02x err=%d", __get_str(dev),
		      __entry->xfer, __entry->opcode, __entry->err)
);

/* The transaction @xfer ran out of time; @what says how it stood. */
TRACE_EVENT(nxt_usb_timeout,
	    TP_PROTO(const char *dev, const void *xfer, u8 opcode, const char *what),
	    TP_ARGS(dev, xfer, opcode, what),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(const void *, xfer)
			     __field(u8, opcode)
			     __string(what, what)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->xfer = xfer;
			   __entry->opcode = opcode;
			   lego_assign_str(what, what);),
	    TP_printk("dev=%s xfer=%p opcode=0x%02x what=\"%s\"", __get_str(dev),
		      __entry->xfer, __entry->opcode, __get_str(what))
);

/* An endpoint stalled (@in: the IN one); @stalls IN stalls in a row. */
TRACE_EVENT(nxt_usb_stall,
	    TP_PROTO(const char *dev, bool in, unsigned int stalls),
	    TP_ARGS(dev, in, stalls),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(bool, in)
			     __field(unsigned int, stalls)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->in = in;
			   __entry->stalls = stalls;),
	    TP_printk("dev=%s endpoint=%s stalls=%u", __get_str(dev),
		      __entry->in ? "in" : "out", __entry->stalls)
);

/* A USB reset, suspend, resume or disconnect of the brick. */
TRACE_EVENT(nxt_usb_reset,
	    TP_PROTO(const char *dev, u8 what),
	    TP_ARGS(dev, what),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(u8, what)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->what = what;),
	    TP_printk("dev=%s event=%s", __get_str(dev),
		      __print_symbolic(__entry->what,
				       { NXT_USB_TRACE_PRE_RESET, "pre_reset" },
				       { NXT_USB_TRACE_POST_RESET, "post_reset" },
				       { NXT_USB_TRACE_SUSPEND, "suspend" },
				       { NXT_USB_TRACE_RESUME, "resume" },
				       { NXT_USB_TRACE_RESET_RESUME, "reset_resume" },
				       { NXT_USB_TRACE_DISCONNECT, "disconnect" }))
);

/* A drain of stale replies starts, for @ms (or until @orphan_op's reply). */
TRACE_EVENT(nxt_usb_drain,
	    TP_PROTO(const char *dev, unsigned int ms, bool orphan, u8 orphan_op),
	    TP_ARGS(dev, ms, orphan, orphan_op),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(unsigned int, ms)
			     __field(bool, orphan)
			     __field(u8, orphan_op)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->ms = ms;
			   __entry->orphan = orphan;
			   __entry->orphan_op = orphan_op;),
	    TP_printk("dev=%s ms=%u orphan=%d orphan_op=0x%02x", __get_str(dev),
		      __entry->ms, __entry->orphan, __entry->orphan_op)
);

/*
 * A packet from the brick was dropped: drained (stale, during a drain),
 * stale (no transaction waits for a reply), or not the reply awaited.
 */
TRACE_EVENT(nxt_usb_drop,
	    TP_PROTO(const char *dev, u8 why, const u8 *buf, unsigned int len,
		     bool drain_end),
	    TP_ARGS(dev, why, buf, len, drain_end),
	    TP_STRUCT__entry(__string(dev, dev)
			     __field(u8, why)
			     __field(u8, type)
			     __field(u8, opcode)
			     __field(unsigned int, len)
			     __field(bool, drain_end)),
	    TP_fast_assign(lego_assign_str(dev, dev);
			   __entry->why = why;
			   __entry->type = len > 0 ? buf[0] : 0;
			   __entry->opcode = len > 1 ? buf[1] : 0;
			   __entry->len = len;
			   __entry->drain_end = drain_end;),
	    TP_printk("dev=%s why=%s type=0x%02x opcode=0x%02x len=%u drain_end=%d",
		      __get_str(dev),
		      __print_symbolic(__entry->why,
				       { NXT_USB_TRACE_DRAIN, "drained" },
				       { NXT_USB_TRACE_STALE, "stale" },
				       { NXT_USB_TRACE_MISMATCH, "mismatch" }),
		      __entry->type, __entry->opcode, __entry->len,
		      __entry->drain_end)
);

#endif /* _NXT_USB_TRACE_H */

/* This part must be outside the header guard. */
#undef TRACE_INCLUDE_PATH
#define TRACE_INCLUDE_PATH .
#undef TRACE_INCLUDE_FILE
#define TRACE_INCLUDE_FILE nxt_usb_trace

#include <trace/define_trace.h>
