# SPDX-License-Identifier: GPL-2.0
#
# Prints the LEGO_HAVE_* flags the top-level Kbuild finds in a kernel source
# tree, without kbuild: the same probes decide what tools/upstream/intree.py
# writes in place of drivers/lego/lego_compat.h's shims.
#   make -s -f tools/upstream/probe.mk LEGO_SRC=CHECKOUT srctree=KERNEL
include $(LEGO_SRC)/Kbuild

.PHONY: print
print:
	@echo $(patsubst -DLEGO_HAVE_%,%,$(filter -DLEGO_HAVE_%,$(subdir-ccflags-y)))
