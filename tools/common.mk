# SPDX-License-Identifier: GPL-2.0
#
# Shared by the Makefile of every tool. Before including it, a tool sets
#   PROG    the program's name;
#   SRCS    its sources, HDRS the headers it depends on;
#   SECTION the man page section (1 or 8); section 8 installs into sbindir.
# and may set EXTRA_LIBS. It then gets the targets all, install, uninstall
# and clean, with:
#
#   make [O=DIR] [CFLAGS=...] [WERROR=1]   build DIR/$(PROG) (default: here)
#   make install [DESTDIR=] [PREFIX=/usr/local]
#
# CFLAGS is the user's (default -O2 -g). The warnings, the uapi include path
# and the version come before it in TOOL_CFLAGS, so "make CFLAGS=-O0" keeps
# them and a user's -Wno-... still wins. WERROR=1 makes the warnings errors,
# as the project's own build checks do (tests/build-modules.sh).

O ?= $(CURDIR)
PREFIX ?= /usr/local
BINDIR ?= $(PREFIX)/bin
SBINDIR ?= $(PREFIX)/sbin
MANDIR ?= $(PREFIX)/share/man
BASHCOMPDIR ?= $(PREFIX)/share/bash-completion/completions
CC ?= cc
CFLAGS ?= -O2 -g
INSTALL ?= install

TOP := $(abspath $(dir $(lastword $(MAKEFILE_LIST)))..)
# The version is the DKMS package's; "unknown" outside the source tree.
VERSION := $(shell sed -n 's/^PACKAGE_VERSION="\([^"]*\)".*/\1/p' $(TOP)/dkms.conf 2>/dev/null)
ifeq ($(VERSION),)
VERSION := unknown
endif

WARNINGS := -Wall -Wextra -Wshadow -Wmissing-prototypes \
	-Wstrict-prototypes -Wmissing-declarations -Wformat=2 \
	-Wno-format-nonliteral -Wpointer-arith -Wwrite-strings
ifeq ($(WERROR),1)
WARNINGS += -Werror
endif
TOOL_CFLAGS := $(WARNINGS) -I$(TOP)/include/uapi -I$(TOP)/tools/lib -I$(TOP)/tools/liblegonxt -DLEGO_VERSION='"$(VERSION)"'

OUT := $(abspath $(O))
TARGET := $(OUT)/$(PROG)
DEST := $(if $(filter 8,$(SECTION)),$(SBINDIR),$(BINDIR))
MANPAGE := $(PROG).$(SECTION)
MANDEST := $(MANDIR)/man$(SECTION)/$(MANPAGE)
COMPLETION := $(PROG).bash-completion

.PHONY: all install uninstall clean

all: $(TARGET)

$(TARGET): $(SRCS) $(HDRS) Makefile $(TOP)/tools/common.mk $(wildcard $(TOP)/dkms.conf)
	@mkdir -p $(OUT)
	$(CC) $(CPPFLAGS) $(TOOL_CFLAGS) $(CFLAGS) $(LDFLAGS) -o $@ $(SRCS) $(LDLIBS) $(EXTRA_LIBS)

install: $(TARGET)
	$(INSTALL) -D -m 0755 $(TARGET) $(DESTDIR)$(DEST)/$(PROG)
	$(INSTALL) -D -m 0644 $(MANPAGE) $(DESTDIR)$(MANDEST)
	$(INSTALL) -D -m 0644 $(COMPLETION) $(DESTDIR)$(BASHCOMPDIR)/$(PROG)

uninstall:
	rm -f $(DESTDIR)$(DEST)/$(PROG) $(DESTDIR)$(MANDEST) \
		$(DESTDIR)$(BASHCOMPDIR)/$(PROG)

clean:
	rm -f $(TARGET)
