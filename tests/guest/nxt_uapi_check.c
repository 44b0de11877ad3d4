// SPDX-License-Identifier: GPL-2.0
/*
 * Prints the sizes, some offsets and the ioctl numbers of
 * include/uapi/linux/lego_nxt.h as the C compiler sees them, for the guest
 * tests to compare with their own description of the interface.
 */
#include <stddef.h>
#include <stdio.h>
#include <linux/lego_nxt.h>

#define SIZE(t)		printf("%s %zu\n", #t, sizeof(struct nxt_##t))
#define OFFSET(t, m)	printf("%s.%s %zu\n", #t, #m, offsetof(struct nxt_##t, m))
#define IOCTL(n)	printf("%s %lu\n", #n, (unsigned long)NXT_IOC_##n)

int main(void)
{
	SIZE(transaction);
	SIZE(status_only);
	SIZE(program);
	SIZE(sound_file);
	SIZE(tone);
	SIZE(output_state);
	SIZE(input_mode);
	SIZE(input_values);
	SIZE(input_port);
	SIZE(motor_position);
	SIZE(message);
	SIZE(battery);
	SIZE(keep_alive);
	SIZE(ls_status);
	SIZE(ls_write);
	SIZE(ls_read);
	OFFSET(output_state, tacho_limit);
	OFFSET(input_values, raw);
	OFFSET(message, status);
	OFFSET(ls_write, tx_data);
	IOCTL(TRANSACT);
	IOCTL(SET_TIMEOUT);
	IOCTL(GET_TIMEOUT);
	IOCTL(START_PROGRAM);
	IOCTL(STOP_PROGRAM);
	IOCTL(PLAY_SOUND_FILE);
	IOCTL(PLAY_TONE);
	IOCTL(SET_OUTPUT_STATE);
	IOCTL(SET_INPUT_MODE);
	IOCTL(GET_OUTPUT_STATE);
	IOCTL(GET_INPUT_VALUES);
	IOCTL(RESET_INPUT_SCALED_VALUE);
	IOCTL(MESSAGE_WRITE);
	IOCTL(RESET_MOTOR_POSITION);
	IOCTL(GET_BATTERY_LEVEL);
	IOCTL(STOP_SOUND_PLAYBACK);
	IOCTL(KEEP_ALIVE);
	IOCTL(LS_GET_STATUS);
	IOCTL(LS_WRITE);
	IOCTL(LS_READ);
	IOCTL(GET_CURRENT_PROGRAM_NAME);
	IOCTL(MESSAGE_READ);
	return 0;
}
