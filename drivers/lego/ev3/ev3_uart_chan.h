/* SPDX-License-Identifier: GPL-2.0 */
/*
 * LEGO MINDSTORMS EV3 UART sensors: from a sensor's description to IIO
 * channels and the names of its modes.
 *
 * Everything here is computed from what a sensor sent in its handshake, so
 * none of it may trust the description beyond what the parser checked:
 * counts are bounded where arrays are filled, and the scale and offset
 * arithmetic never overflows, traps or truncates silently. Pure functions,
 * no IIO or device calls, so that KUnit and the libFuzzer target reach them.
 */
#ifndef _EV3_UART_CHAN_H
#define _EV3_UART_CHAN_H

#include <linux/types.h>
#include <linux/iio/types.h>

#include "ev3_uart_proto.h"

/*
 * At most one channel per value, and a DATA payload holds at most 32 values
 * (32 of type s8): 512 channels for 16 modes, plus the timestamp.
 */
#define EV3_UART_MAX_CHANS	(EV3_UART_MAX_MODES * EV3_UART_MAX_PAYLOAD)

/* The longest mode token: a name, or "#" and a mode number. */
#define EV3_UART_TOKEN_LEN	EV3_UART_NAME_LEN

/**
 * struct ev3_uart_chan - one IIO channel: one value of one mode
 * @mode: the mode the value belongs to
 * @index: which value of that mode's DATA message
 * @type: an &enum iio_chan_type
 * @modifier: an &enum iio_modifier, or 0 for an indexed channel
 * @channel: index among the indexed channels of @type
 * @realbits: bits of the value on the wire
 * @decimals: for float values, the decimals kept in _raw (may be fewer than
 *	the mode's, so that the scale keeps its precision); else 0
 * @scale_val: integer part of the scale (IIO_VAL_INT_PLUS_NANO)
 * @scale_val2: its nano part, of the same sign as @scale_val
 * @offset_val: integer part of the offset (IIO_VAL_INT_PLUS_MICRO)
 * @offset_val2: its micro part, of the same sign as @offset_val
 *
 * processed = (raw + offset) * scale is the value in the IIO unit of @type.
 */
struct ev3_uart_chan {
	u8 mode;
	u8 index;
	u8 type;
	u8 modifier;
	u16 channel;
	u8 realbits;
	u8 decimals;
	s32 scale_val;
	s32 scale_val2;
	s32 offset_val;
	s32 offset_val2;
};

int ev3_uart_chan_scale(const struct ev3_uart_mode *m, u64 unit_nano,
			struct ev3_uart_chan *c);
unsigned int ev3_uart_chans_build(const struct ev3_uart_sensor *desc,
				  struct ev3_uart_chan *chans,
				  unsigned int max);
int ev3_uart_chan_read(const struct ev3_uart_sensor *desc,
		       const struct ev3_uart_chan *c, const u8 *data,
		       size_t len, s32 *out);

int ev3_uart_mode_token(const struct ev3_uart_sensor *desc, u8 mode,
			char *buf, size_t size);
int ev3_uart_find_mode(const struct ev3_uart_sensor *desc, const char *str);

/* "1.0.00.0000": see ev3_uart_version_string(). */
#define EV3_UART_VERSION_LEN	11
int ev3_uart_version_string(u32 version, char *buf, size_t size);

#endif /* _EV3_UART_CHAN_H */
