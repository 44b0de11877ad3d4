# SPDX-License-Identifier: GPL-2.0
#
# LEGO MINDSTORMS drivers for Linux: build, test and install.
#
#   make               build the modules against KDIR (default: the running kernel)
#   make check         the whole test suite in a QEMU test VM (installs what it needs)
#   make check-arm64   the KUnit suites and guest tests on an arm64 kernel under
#                      qemu-system-aarch64 (TCG; slow, not in CI)
#   make checkpatch    checkpatch.pl --strict on every source file
#   make sparse        the modules with sparse (C=2)
#   make demo          four emulated EV3 sensors and an NXT brick in the test VM
#   make coverage      which functions of the drivers the last `make check`
#                      reached, function by function (tests/coverage.py)
#   make bench         benchmarks; writes tests/bench/results.md (BENCH_ARGS=--quick)
#   make fuzz          libFuzzer on the EV3 and NXT protocol cores (long run;
#                      FUZZ_ARGS= passes options to tests/fuzz/run.sh)
#   make soak          the robustness soak in the test VM (hours; SOAK_ARGS=--short)
#   make install       modules (updates/), uapi headers (INCLUDEDIR/lego-mindstorms,
#                      with lego-mindstorms.pc), tools, udev rules, systemd
#                      units, sysusers.d file; DESTDIR=, PREFIX=/usr/local, KDIR=
#   make install-userspace  the same without the modules (with DKMS)
#   make uninstall     remove what make install installed (same variables)
#   make dkms-install  copy the sources to /usr/src/lego-mindstorms-VERSION,
#                      then dkms add, build and install (for the running kernel,
#                      or DKMS_KERNEL=KVER)
#   make dkms-remove   dkms remove --all, and remove those sources
#   make dkms-source   only copy the sources DKMS builds (DESTDIR= honoured)
#   make deb           Debian packages into .build/deb/ (tests/packaging/make-deb.sh)
#   make upstream-series  the drivers as an in-tree patch series against the
#                      newest linux-source-X.Y Debian serves, into
#                      .build/upstream/X.Y/ (tools/upstream; UPSTREAM_SERIES=6.12
#                      or 6.1: against that source, into 6.12/ or 6.1/)
#   make upstream-check   that series applied to the kernel source and checked:
#                      checkpatch per patch, kernel-doc, ABI, in-tree W=1 builds
#                      (long, not in make check; UPSTREAM_STEPS= picks steps,
#                      UPSTREAM_SERIES= the series)
#
# Documentation/lego/install.rst describes installing in detail.

KDIR ?= /lib/modules/$(shell uname -r)/build
LEGO_SRC := $(CURDIR)
export LEGO_SRC

KBUILD_ARGS := -C $(KDIR) M=$(CURDIR) W=1

.PHONY: all modules sparse clean checkpatch check deps vm-run demo bench fuzz soak help
.PHONY: install install-userspace uninstall modules_install dkms-source dkms-install dkms-remove deb

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

.PHONY: check-arm64
check-arm64:
	@tests/arm64/check.sh

demo:
	@tests/demo/run.sh

.PHONY: coverage
coverage:
	@python3 tests/coverage.py --all --check tests/coverage-allow.txt \
		$(or $(LEGO_BUILD_DIR),.build)/results/gcov

bench:
	@tests/bench/run.sh $(BENCH_ARGS)

fuzz:
	@tests/fuzz/run.sh $(FUZZ_ARGS)

# Documentation/lego/soak.rst; SOAK_ARGS=--short for the five-minute version.
soak:
	@tests/soak/run.sh $(SOAK_ARGS)

help:
	@sed -n '3,/^$$/p' Makefile

# Documentation/lego/testing.rst, "The in-tree series".
.PHONY: upstream-series upstream-check
UPSTREAM_SERIES ?= newest
upstream-series:
	@tools/upstream/series.sh $(UPSTREAM_SERIES)

upstream-check:
	@tests/upstream/check.sh $(UPSTREAM_SERIES) $(UPSTREAM_STEPS)

# --- Installing -----------------------------------------------------------
#
# Modules go to /lib/modules/KVER/$(INSTALL_MOD_DIR) (under DESTDIR), where
# they take precedence over in-tree modules of the same name. depmod runs
# only for a real install (no DESTDIR): a packaging step runs it on the
# target. udev reads rules from /etc/udev/rules.d and /usr/lib/udev/rules.d
# (systemd-udevd 252 also /usr/local/lib/udev/rules.d, older udev and eudev
# do not): a local install (PREFIX other than /usr) puts them in /etc, a
# package (PREFIX=/usr) in /usr/lib. systemd reads units from both
# /usr/local/lib/systemd/system and /usr/lib/systemd/system, sysusers.d
# files only from /etc/sysusers.d and /usr/lib/sysusers.d: the same rule.
# The uapi headers go to INCLUDEDIR/lego-mindstorms/linux, not to
# INCLUDEDIR/linux, which belongs to the distribution's kernel headers:
# `pkg-config --cflags lego-mindstorms` gives -IINCLUDEDIR/lego-mindstorms.
PREFIX ?= /usr/local
DESTDIR ?=
INSTALL_MOD_DIR ?= updates
INCLUDEDIR ?= $(PREFIX)/include
ifeq ($(PREFIX),/usr)
UDEVRULESDIR ?= /usr/lib/udev/rules.d
SYSUSERSDIR ?= /usr/lib/sysusers.d
else
UDEVRULESDIR ?= /etc/udev/rules.d
SYSUSERSDIR ?= /etc/sysusers.d
endif
PKGCONFIGDIR ?= $(PREFIX)/share/pkgconfig
SYSTEMDUNITDIR ?= $(PREFIX)/lib/systemd/system
INSTALL ?= install
DEPMOD ?= depmod

# The kernel release KDIR builds for, as kbuild installs for it (Debian's
# headers have another one in include/config/kernel.release).
KRELEASE = $(or $(shell sed -n 's/^\#define UTS_RELEASE "\(.*\)"/\1/p' \
	$(KDIR)/include/generated/utsrelease.h 2>/dev/null),$(shell uname -r))
# A kernel that signs all its modules (CONFIG_MODULE_SIG_ALL) but whose key
# is not at hand, as with distribution headers: install them unsigned rather
# than with sign-file's errors (DKMS signs with its own key, see install.rst).
SIG_KEY = $(shell sed -n 's/^CONFIG_MODULE_SIG_KEY="*\([^"]*\)"*/\1/p' \
	$(KDIR)/include/config/auto.conf 2>/dev/null)
NO_SIGN = $(if $(filter-out pkcs11:%,$(SIG_KEY)),$(if $(wildcard $(SIG_KEY) \
	$(KDIR)/$(SIG_KEY)),,CONFIG_MODULE_SIG_ALL=))
UAPI_HEADERS := lego_ev3_uart.h lego_nxt.h
UAPI_DIR = $(INCLUDEDIR)/lego-mindstorms/linux
SYSUSERS_CONF := lego-mindstorms.conf
UDEV_RULES = $(notdir $(wildcard tools/udev/*.rules))
SYSTEMD_UNITS = $(notdir $(wildcard tools/systemd/*.service tools/systemd/*.socket \
	tools/systemd/*.path tools/systemd/*.timer))

# Kbuild's modules_install (it signs and compresses as the kernel's config
# says), without the test-only modules: LEGO_TESTS=n leaves out tests/kmod
# and the KUnit modules. depmod runs here, not in kbuild (which skips it
# without a System.map, as in distribution headers), and not with a DESTDIR:
# a package's module indexes are made on the target system.
INSTALL_KBUILD_ARGS = $(KBUILD_ARGS) LEGO_TESTS=n INSTALL_MOD_DIR=$(INSTALL_MOD_DIR) \
	$(if $(DESTDIR),INSTALL_MOD_PATH=$(DESTDIR)) DEPMOD=true $(NO_SIGN)
# Where kbuild puts them: the subdirectory of each in this tree is kept.
INSTALLED_MODULES = $(DESTDIR)/lib/modules/$(KRELEASE)/$(INSTALL_MOD_DIR)/drivers/lego/ev3/lego_ev3_uart.ko \
	$(DESTDIR)/lib/modules/$(KRELEASE)/$(INSTALL_MOD_DIR)/drivers/lego/nxt/lego_nxt.ko \
	$(DESTDIR)/lib/modules/$(KRELEASE)/$(INSTALL_MOD_DIR)/drivers/lego/nxt/lego_nxt_usb.ko \
	$(DESTDIR)/lib/modules/$(KRELEASE)/$(INSTALL_MOD_DIR)/drivers/lego/nxt/lego_nxt_serial.ko

modules_install:
	rm -f modules.order
	$(MAKE) $(INSTALL_KBUILD_ARGS) modules
	$(MAKE) $(INSTALL_KBUILD_ARGS) modules_install
ifeq ($(DESTDIR),)
	$(DEPMOD) -a $(KRELEASE)
endif

install: modules_install install-userspace

# Everything but the modules: with DKMS, `make dkms-install install-userspace`.
install-userspace:
	$(INSTALL) -d $(DESTDIR)$(UAPI_DIR) $(DESTDIR)$(PKGCONFIGDIR)
	$(INSTALL) -m 0644 $(addprefix include/uapi/linux/,$(UAPI_HEADERS)) $(DESTDIR)$(UAPI_DIR)/
	printf '%s\n' 'prefix=$(PREFIX)' 'includedir=$(INCLUDEDIR)' '' \
		'Name: lego-mindstorms' \
		'Description: uapi headers of the LEGO MINDSTORMS drivers (lego_nxt_usb, lego_ev3_uart)' \
		'Version: $(VERSION)' 'Cflags: -I$${includedir}/lego-mindstorms' \
		> $(DESTDIR)$(PKGCONFIGDIR)/lego-mindstorms.pc
	chmod 0644 $(DESTDIR)$(PKGCONFIGDIR)/lego-mindstorms.pc
ifneq ($(wildcard tools/Makefile),)
	$(MAKE) -C tools install DESTDIR=$(DESTDIR) PREFIX=$(PREFIX)
endif
	$(INSTALL) -d $(DESTDIR)$(SYSUSERSDIR)
	$(INSTALL) -m 0644 tools/sysusers/$(SYSUSERS_CONF) $(DESTDIR)$(SYSUSERSDIR)/
ifneq ($(UDEV_RULES),)
	$(INSTALL) -d $(DESTDIR)$(UDEVRULESDIR)
	$(INSTALL) -m 0644 $(addprefix tools/udev/,$(UDEV_RULES)) $(DESTDIR)$(UDEVRULESDIR)/
endif
ifneq ($(SYSTEMD_UNITS),)
	$(INSTALL) -d $(DESTDIR)$(SYSTEMDUNITDIR)
	$(INSTALL) -m 0644 $(addprefix tools/systemd/,$(SYSTEMD_UNITS)) $(DESTDIR)$(SYSTEMDUNITDIR)/
endif
ifeq ($(DESTDIR),)
	@# The group first: udev ignores a rule whose GROUP= names no group.
	systemd-sysusers $(SYSUSERSDIR)/$(SYSUSERS_CONF) 2>/dev/null || \
		getent group lego >/dev/null || groupadd --system lego
	@udevadm control --reload 2>/dev/null || true
	@systemctl daemon-reload 2>/dev/null || true
	@echo "The group lego may use /dev/nxtN and the EV3 sensors:"
	@echo "  usermod -a -G lego YOUR-USER  (then log in again)"
endif

uninstall:
	rm -f $(INSTALLED_MODULES) $(addsuffix .xz,$(INSTALLED_MODULES)) \
		$(addsuffix .zst,$(INSTALLED_MODULES)) $(addsuffix .gz,$(INSTALLED_MODULES))
	-rmdir -p --ignore-fail-on-non-empty $(sort $(dir $(INSTALLED_MODULES))) 2>/dev/null
ifeq ($(DESTDIR),)
	$(DEPMOD) -a $(KRELEASE)
endif
	rm -f $(addprefix $(DESTDIR)$(UAPI_DIR)/,$(UAPI_HEADERS))
	-rmdir $(DESTDIR)$(UAPI_DIR) $(DESTDIR)$(INCLUDEDIR)/lego-mindstorms 2>/dev/null
	rm -f $(DESTDIR)$(PKGCONFIGDIR)/lego-mindstorms.pc
	rm -f $(DESTDIR)$(SYSUSERSDIR)/$(SYSUSERS_CONF)
ifneq ($(wildcard tools/Makefile),)
	$(MAKE) -C tools uninstall DESTDIR=$(DESTDIR) PREFIX=$(PREFIX)
endif
	rm -f $(addprefix $(DESTDIR)$(UDEVRULESDIR)/,$(UDEV_RULES))
	rm -f $(addprefix $(DESTDIR)$(SYSTEMDUNITDIR)/,$(SYSTEMD_UNITS))

# --- DKMS -----------------------------------------------------------------
#
# dkms builds a copy of the sources in /usr/src/lego-mindstorms-VERSION:
# only what the module build needs goes there (no tests, no build output).
# (A copy of the build files without dkms.conf, as tests/build-modules.sh
# makes, has no version.)
VERSION := $(if $(wildcard $(CURDIR)/dkms.conf),$(shell sed -n 's/^PACKAGE_VERSION="\(.*\)"/\1/p' $(CURDIR)/dkms.conf))
DKMS_NAME := lego-mindstorms
DKMS_SRC := $(DESTDIR)/usr/src/$(DKMS_NAME)-$(VERSION)
DKMS_FILES := dkms.conf Makefile Kbuild drivers include
DKMS ?= dkms
# DKMS_KERNEL=KVER: build and install for that kernel, not the running one.
DKMS_K = $(if $(DKMS_KERNEL),-k $(DKMS_KERNEL))

dkms-source:
	rm -rf $(DKMS_SRC)
	$(INSTALL) -d $(DKMS_SRC)
	tar -C $(CURDIR) -cf - --exclude='*.o' --exclude='*.ko' --exclude='.*.cmd' \
		--exclude='*.mod' --exclude='*.mod.c' --exclude='modules.order' \
		--exclude='Module.symvers' $(DKMS_FILES) | tar -C $(DKMS_SRC) -xf -

# Again for the same version: the old one is removed first (from every
# kernel; AUTOINSTALL builds it for the others at their next boot).
dkms-install:
	@if [ -n "$$($(DKMS) status -m $(DKMS_NAME) -v $(VERSION))" ]; then \
		echo "$(DKMS) remove -m $(DKMS_NAME) -v $(VERSION) --all"; \
		$(DKMS) remove -m $(DKMS_NAME) -v $(VERSION) --all || exit 1; \
	fi
	$(MAKE) dkms-source
	$(DKMS) add -m $(DKMS_NAME) -v $(VERSION)
	$(DKMS) build -m $(DKMS_NAME) -v $(VERSION) $(DKMS_K)
	$(DKMS) install -m $(DKMS_NAME) -v $(VERSION) $(DKMS_K)

dkms-remove:
	$(DKMS) remove -m $(DKMS_NAME) -v $(VERSION) --all
	rm -rf $(DKMS_SRC)

# --- Debian packages ------------------------------------------------------
#
# debian/: lego-mindstorms-dkms, lego-mindstorms-tools, lego-mindstorms-dev
# and python3-lego-nxt-linux, built with dpkg-buildpackage from a copy of
# this tree, into .build/deb/ (DEB_OUT=). DEB_LINTIAN=1 runs lintian on
# them, a warning failing (make check does).
DEB_OUT ?= $(CURDIR)/.build/deb
DEB_LINTIAN ?=

deb:
	tests/packaging/make-deb.sh $(if $(DEB_LINTIAN),--lintian) $(DEB_OUT)
