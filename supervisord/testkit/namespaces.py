"""Linux namespaces for fault scenarios: a private network (``NetNamespace``) for CAN over
``udp_multicast``, a private mount (``in_private_mount``) for a disk seen by one process."""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
from pathlib import Path

MULTICAST_ROUTE = "224.0.0.0/4"


def loopback_only(ip: str, *, netns: str | None = None) -> list[list[str]]:
    """The ``ip`` commands that make a new network namespace (``netns``, or the caller's own)
    loopback only and multicast-capable: ``lo`` up with multicast on, and every multicast
    group routed to it, so ``udp_multicast`` CAN frames stay inside (docs/testing.md)."""
    target = [] if netns is None else ["-n", netns]
    return [
        [ip, *target, "link", "set", "lo", "up", "multicast", "on"],
        [ip, *target, "route", "add", MULTICAST_ROUTE, "dev", "lo"],
    ]


class NetNamespace:
    """A private network namespace with only the loopback device and a multicast route, so
    that ``udp_multicast`` CAN frames of one scenario reach no other test run on the machine.
    (python-can binds its multicast socket to the port on every address, and Linux delivers a
    group's datagrams to every socket on that port that any process joined the group for.)
    Needs root and iproute2; ``available()`` says whether it can work here."""

    _counter = itertools.count()

    def __init__(self) -> None:
        self.name = f"srcs-faults-{os.getpid()}-{next(self._counter)}"
        self.ip = shutil.which("ip") or "/usr/sbin/ip"
        self.created = False

    @staticmethod
    def available() -> bool:
        return os.geteuid() == 0 and shutil.which("ip") is not None

    def create(self) -> NetNamespace:
        for command in (
            [self.ip, "netns", "add", self.name],
            *loopback_only(self.ip, netns=self.name),
        ):
            subprocess.run(command, check=True, capture_output=True, timeout=30)  # noqa: S603
            self.created = True
        return self

    def prefix(self) -> list[str]:
        return [self.ip, "netns", "exec", self.name]

    def delete(self) -> None:
        if self.created:
            command = [self.ip, "netns", "del", self.name]
            subprocess.run(command, check=False, capture_output=True, timeout=30)  # noqa: S603
            self.created = False


def in_private_mount(mount: str, target: Path, command: list[str]) -> list[str]:
    """``command`` in a mount namespace of its own, after the shell line ``mount`` (which
    names ``target`` as ``$0``) ran there: what it mounts is seen by that process alone and
    goes away with it. Needs root and ``unshare``."""
    script = f'{mount} && exec "$@"'
    return [
        "unshare",
        "--mount",
        "--propagation",
        "private",
        "--",
        "sh",
        "-c",
        script,
        str(target),
        *command,
    ]
