"""Ctrl-C and SIGTERM end a following command (``log -f``, ``fleet -f``, ``watch``,
``decode --follow``) with exit 0."""

from __future__ import annotations

import signal


def interruptible() -> None:
    """Ctrl-C and SIGTERM end a following command, even when it was started with SIGINT
    ignored (a background job of a script: Python then installs no handler of its own,
    which is what once made ``watch`` outlive its SIGINT in a test)."""

    def interrupt(_sig: int, _frame: object) -> None:
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, interrupt)
