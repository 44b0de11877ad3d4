// SPDX-License-Identifier: GPL-2.0
/*
 * 6.10: __assign_str() in trace events takes only the field's name. The
 * one-argument call below is expanded (and stringified) only; with the
 * older two-argument macro it is a preprocessing error.
 */
#include <linux/compiler.h>
#include <linux/stringify.h>
#include <trace/stages/stage6_event_callback.h>

static const char lego_probe[] __maybe_unused = __stringify(__assign_str(field));
