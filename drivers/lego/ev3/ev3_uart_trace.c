// SPDX-License-Identifier: GPL-2.0
/* LEGO MINDSTORMS EV3 UART sensors: the trace events' definitions. */
#define CREATE_TRACE_POINTS
#include "ev3_uart_trace.h"
