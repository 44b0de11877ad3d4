// SPDX-License-Identifier: GPL-2.0
/* kzalloc_obj(): a zeroed allocation of an object's type, typed. */
#include <linux/slab.h>

#ifndef kzalloc_obj
#error no kzalloc_obj
#endif
