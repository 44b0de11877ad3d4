/* SPDX-License-Identifier: GPL-2.0 */
/*
 * The typed direct-command ioctls in the order the fuzz inputs and the
 * benchmark's records number them (tests/fuzz/make-seeds.py and
 * tests/bench/proto/make-streams.py use the same order): a command's number
 * is its index here.
 */
#ifndef LEGO_TEST_NXT_IOCTLS_H
#define LEGO_TEST_NXT_IOCTLS_H

#include <linux/lego_nxt.h>

static const unsigned int nxt_test_ioctls[] = {
	NXT_IOC_START_PROGRAM, NXT_IOC_STOP_PROGRAM, NXT_IOC_PLAY_SOUND_FILE,
	NXT_IOC_PLAY_TONE, NXT_IOC_SET_OUTPUT_STATE, NXT_IOC_SET_INPUT_MODE,
	NXT_IOC_GET_OUTPUT_STATE, NXT_IOC_GET_INPUT_VALUES,
	NXT_IOC_RESET_INPUT_SCALED_VALUE, NXT_IOC_MESSAGE_WRITE,
	NXT_IOC_RESET_MOTOR_POSITION, NXT_IOC_GET_BATTERY_LEVEL,
	NXT_IOC_STOP_SOUND_PLAYBACK, NXT_IOC_KEEP_ALIVE, NXT_IOC_LS_GET_STATUS,
	NXT_IOC_LS_WRITE, NXT_IOC_LS_READ, NXT_IOC_GET_CURRENT_PROGRAM_NAME,
	NXT_IOC_MESSAGE_READ,
};

#endif
