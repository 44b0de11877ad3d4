/* SPDX-License-Identifier: GPL-2.0 */
/* Kernel integer types over the system's <linux/types.h> (__u8, __le16...). */
#ifndef _LEGO_SHIM_TYPES_H
#define _LEGO_SHIM_TYPES_H

#include_next <linux/types.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

typedef __u8 u8;
typedef __u16 u16;
typedef __u32 u32;
typedef __u64 u64;
typedef __s8 s8;
typedef __s16 s16;
typedef __s32 s32;
typedef __s64 s64;

#endif /* _LEGO_SHIM_TYPES_H */
