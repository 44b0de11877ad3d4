# SPDX-License-Identifier: GPL-2.0
#
# LEGO MINDSTORMS drivers for Linux: build, test and install.
#
#   make               build the modules against KDIR (default: the running kernel)
#   make check         the whole test suite in a QEMU test VM (installs what it needs)
#   make checkpatch    checkpatch.pl --strict on every source file
#   make sparse        the modules with sparse (C=2)
#   make demo          four emulated EV3 sensors and an NXT brick in the test VM

KDIR ?= /lib/modules/$(shell uname -r)/build
LEGO_SRC := $(CURDIR)
export LEGO_SRC

KBUILD_ARGS := -C $(KDIR) M=$(CURDIR) W=1

.PHONY: all modules sparse clean checkpatch check deps vm-run demo help

all: modules

modules:
	$(MAKE) $(KBUILD_ARGS) modules

sparse:
	$(MAKE) $(KBUILD_ARGS) C=2 modules

clean:
	$(MAKE) -C $(KDIR) M=$(CURDIR) clean 2>/dev/null || \
		find . -name '*.o' -o -name '*.ko' -o -name '*.mod*' -o -name '.*.cmd' | xargs rm -f

checkpatch:
	@tests/checkpatch.sh

deps:
	@tests/install-deps.sh

check:
	@tests/check.sh

demo:
	@tests/demo/run.sh

help:
	@sed -n '3,10p' Makefile
