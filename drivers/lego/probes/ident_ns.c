// SPDX-License-Identifier: GPL-2.0
/*
 * Before 6.13, symbol namespaces are identifiers (MODULE_IMPORT_NS(FOO));
 * since, string literals, and an identifier no longer compiles.
 */
#include <linux/module.h>

MODULE_IMPORT_NS(LEGO_PROBE_NAMESPACE);
