// SPDX-License-Identifier: GPL-2.0
/* LEGO MINDSTORMS NXT brick: the trace events' definitions. */
#define CREATE_TRACE_POINTS
#include "nxt_usb_trace.h"

/* The transports' own events. */
EXPORT_TRACEPOINT_SYMBOL_GPL(nxt_usb_stall);
EXPORT_TRACEPOINT_SYMBOL_GPL(nxt_usb_reset);
