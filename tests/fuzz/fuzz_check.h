/* SPDX-License-Identifier: GPL-2.0 */
/*
 * Shared by the fuzz targets: an invariant that must hold, whatever the
 * input. A failed one aborts, which libFuzzer reports as a crash and saves
 * the input.
 */
#ifndef _LEGO_FUZZ_CHECK_H
#define _LEGO_FUZZ_CHECK_H

#include <stdio.h>
#include <stdlib.h>

#define CHECK(cond) do {						\
	if (!(cond)) {							\
		fprintf(stderr, "%s:%d: invariant failed: %s\n",	\
			__FILE__, __LINE__, #cond);			\
		abort();						\
	}								\
} while (0)

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size);
size_t LLVMFuzzerMutate(unsigned char *data, size_t size, size_t max_size);
size_t LLVMFuzzerCustomMutator(unsigned char *data, size_t size,
			       size_t max_size, unsigned int seed);

#endif /* _LEGO_FUZZ_CHECK_H */
