"""The test session's network: a namespace of its own with loopback only (docs/testing.md).

The rule: no test, bench or demo sends to an address outside 127.0.0.0/8 or ::1 unless it
runs inside a network namespace that it made. The simplest design that keeps it for every
test is to make the whole session such a namespace: as root, before any test runs, the
session process leaves the machine's network namespace for a new one in which ``lo`` is the
only device, up, with multicast on and 224.0.0.0/4 routed to it. Every process a test
starts inherits it, so python-can's ``udp_multicast`` buses (which join their group on the
default device and bind their port on every address) reach only this session's processes:
nothing leaves the machine, and two sessions at once cannot hear each other.

Without root (or without iproute2) the session stays where it is; the tests that need
multicast then skip, saying why, and :class:`SocketAudit` fails any test whose process
binds, connects or sends off loopback.
"""

from __future__ import annotations

import ctypes
import ipaddress
import os
import shutil
import socket
import subprocess
import threading
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final

from supervisord.testkit.namespaces import loopback_only

CLONE_NEWNET: Final = 0x40000000  # <sched.h>; os.unshare arrives only in Python 3.12
AUDITED_EVENTS: Final = frozenset(
    {"socket.bind", "socket.connect", "socket.sendto", "socket.sendmsg"}
)


def interfaces() -> set[str]:
    """The network devices this process can use."""
    return {name for _, name in socket.if_nameindex()}


def is_private(devices: Iterable[str] | None = None) -> bool:
    """Nothing can leave: loopback is the only device (of ``devices``, or of this process)."""
    return set(interfaces() if devices is None else devices) <= {"lo"}


def enter_private_namespace() -> str | None:
    """Move this process into a new network namespace with ``lo`` up and multicast routed to
    it. Returns ``None`` when done, or why it could not be done (then nothing changed)."""
    if is_private():
        return None  # already inside one (e.g. a fault scenario's own namespace)
    ip = shutil.which("ip")
    if os.geteuid() != 0 or ip is None:
        return "needs root and iproute2 (./dev test as root makes one)"
    if threading.active_count() != 1:
        return "the session already runs threads, which would stay in the old namespace"
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(CLONE_NEWNET) != 0:
        return f"unshare(CLONE_NEWNET) failed: {os.strerror(ctypes.get_errno())}"
    for command in loopback_only(ip):
        subprocess.run(command, check=True, capture_output=True, timeout=30)
    return None


def leaves_machine(address: object, devices: Iterable[str]) -> bool:
    """Whether a socket bound, connected or sending to ``address`` can reach beyond this
    machine, given the devices of its namespace. Unix-socket paths never do; an IP address
    does unless it is loopback or the namespace has no device but ``lo``. An empty host (or
    a wildcard) binds every device, so it counts as leaving."""
    if is_private(devices) or not isinstance(address, tuple) or not address:
        return False
    host = address[0]
    if not isinstance(host, str):
        return False
    try:
        return not ipaddress.ip_address(host.split("%", 1)[0]).is_loopback
    except ValueError:
        return host != "localhost"  # "" (every address) or a name that may resolve anywhere


@dataclass
class SocketAudit:
    """Every bind, connect and send of this process off loopback, while the namespace is
    not private: the offences of the current test (a ``sys.addaudithook`` callback)."""

    devices: frozenset[str] = field(default_factory=lambda: frozenset(interfaces()))
    offences: list[str] = field(default_factory=list)

    def __call__(self, event: str, args: tuple[object, ...]) -> None:
        if event in AUDITED_EVENTS and len(args) >= 2 and leaves_machine(args[1], self.devices):
            self.offences.append(f"{event} {args[1]!r}")

    def take(self) -> list[str]:
        offences, self.offences = self.offences, []
        return offences
