# SPDX-License-Identifier: GPL-3.0-or-later
"""nxt-python support for the lego_nxt kernel driver (USB and Bluetooth).

Pass :func:`lego_nxt_linux.get_backend` (or a :class:`Backend`) to
``nxt.locator.find(backends=[...])`` to reach NXT bricks through
``/dev/nxtN``.
"""
from .backend import Backend, DevNodeSock, get_backend, list_devices

__all__ = ["Backend", "DevNodeSock", "get_backend", "list_devices"]
__version__ = "0.1.0"
