# SPDX-License-Identifier: GPL-3.0-or-later
"""The lego_nxt_linux backend under the name nxt-python's configuration
file and locator look for: ``nxt.backend.NAME``.

nxt-python 3.x imports each name of ``backends = ...`` in
``~/.nxt-python.conf`` as the module ``nxt.backend.NAME`` and calls its
``get_backend()``. This module is installed into nxt-python's own
``nxt/backend`` directory (it belongs to the lego-nxt-linux distribution,
which must be installed in the same environment as nxt-python), so that::

    [default]
    backends = lego_nxt_linux

makes nxt-python's commands (nxt-test, nxt-push, nxt-screenshot,
nxt-server) and ``nxt.locator.find()`` use ``/dev/nxtN``.
"""
from lego_nxt_linux.backend import Backend, get_backend

__all__ = ["Backend", "get_backend"]
