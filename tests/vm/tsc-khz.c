// SPDX-License-Identifier: GPL-2.0
/*
 * tsc-khz - print the host's TSC rate in kHz, measured against
 * CLOCK_MONOTONIC_RAW over 100 ms.
 *
 * Under TCG on an x86 host, QEMU gives the guest the host's TSC. The guest
 * kernel has no ACPI, so no HPET or PM timer to calibrate it against, and
 * its PIT calibration fails when the host is busy: the TSC is then marked
 * unstable and the guest runs on refined-jiffies (4 ms timers). vm-run
 * passes this figure as tsc_early_khz= instead.
 */
#include <stdint.h>
#include <stdio.h>
#include <time.h>
#include <x86intrin.h>

static double now(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC_RAW, &ts);
	return ts.tv_sec + ts.tv_nsec / 1e9;
}

int main(void)
{
	struct timespec pause = { 0, 100 * 1000 * 1000 };
	double t0, t1;
	uint64_t c0, c1;

	t0 = now();
	c0 = __rdtsc();
	nanosleep(&pause, NULL);
	t1 = now();
	c1 = __rdtsc();
	if (t1 <= t0 || c1 <= c0)
		return 1;
	printf("%.0f\n", (c1 - c0) / (t1 - t0) / 1000);
	return 0;
}
