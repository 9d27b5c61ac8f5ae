"""The systemd notification protocol (sd_notify(3)): READY, STATUS, WATCHDOG, STOPPING.

Written against the protocol rather than libsystemd so it needs nothing at run time and can be
tested with a datagram socket of the test's own. Without ``NOTIFY_SOCKET`` (not started by
systemd) every call does nothing.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Mapping


def watchdog_usec(env: Mapping[str, str], pid: int) -> int:
    """systemd's watchdog period for process ``pid`` in ``env`` (``WATCHDOG_USEC``, when
    ``WATCHDOG_PID`` is unset or names it), or 0 for none, as sd_watchdog_enabled(3) reads it."""
    usec = env.get("WATCHDOG_USEC", "")
    owner = env.get("WATCHDOG_PID", "")
    mine = not owner or owner == str(pid)
    return int(usec) if usec.isdigit() and mine else 0


class Notifier:
    """Sends state lines to the service manager. Never raises: a lost notification must not
    unwind the main loop (systemd's watchdog then acts, which is the safe outcome)."""

    def __init__(self, environ: dict[str, str] | None = None) -> None:
        env = os.environ if environ is None else environ
        address = env.get("NOTIFY_SOCKET", "")
        # An abstract socket is written "@name" and is "\0name" on the wire.
        self._address = "\0" + address[1:] if address.startswith("@") else address
        self._socket: socket.socket | None = None
        if self._address:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            self._socket.setblocking(False)
        self.watchdog_usec = watchdog_usec(env, os.getpid())
        self.failures = 0

    @property
    def enabled(self) -> bool:
        return self._socket is not None

    @property
    def watchdog_interval_ns(self) -> int | None:
        """How often to send WATCHDOG=1: half of WatchdogSec, as sd_watchdog_enabled(3) advises."""
        return self.watchdog_usec * 500 if self.watchdog_usec else None

    def send(self, **fields: str) -> bool:
        """Send ``KEY=value`` lines, e.g. ``send(READY="1", STATUS="RUN")``."""
        if self._socket is None:
            return False
        text = "".join(f"{key}={value}\n" for key, value in fields.items())
        try:
            self._socket.sendto(text.encode(), self._address)
        except OSError:
            self.failures += 1
            return False
        return True

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None
