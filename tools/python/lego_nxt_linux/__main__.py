# SPDX-License-Identifier: GPL-3.0-or-later
"""Run one of nxt-python's commands with this backend importable as
``nxt.backend.lego_nxt_linux``, wherever the two packages are installed.

nxt-python finds the backends named in its configuration file
(``backends = lego_nxt_linux`` in ``~/.nxt-python.conf``) in its own
``nxt.backend`` package. An installation of lego-nxt-linux in the same
environment as nxt-python puts a module there; when they are in different
places (this package on ``PYTHONPATH``, or from a Debian package while
nxt-python is in a virtual environment), run the command through this
module instead::

    python3 -m lego_nxt_linux nxt-test
    python3 -m lego_nxt_linux nxt-push Program.rxe
"""
import importlib
import sys

from . import backend

COMMANDS = {
    "nxt-push": "push",
    "nxt-screenshot": "screenshot",
    "nxt-server": "server",
    "nxt-test": "test",
}


def main():
    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        print("usage: python3 -m lego_nxt_linux {%s} [ARGS...]" % ",".join(COMMANDS),
              file=sys.stderr)
        return 2
    sys.modules.setdefault("nxt.backend.lego_nxt_linux", backend)
    command = sys.argv[1]
    sys.argv = [command] + sys.argv[2:]
    return importlib.import_module("nxt.command." + COMMANDS[command]).run()


if __name__ == "__main__":
    sys.exit(main())
