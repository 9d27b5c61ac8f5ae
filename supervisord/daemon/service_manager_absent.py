"""What srcsd runs without when no service manager gives it (SR-0.4, docs/containers.md).

``srcsd@.service`` gives the daemon seven things that a start by hand or in a container does
not: systemd's watchdog, real-time scheduling, a sandbox, restarts, the runtime directory,
(through udev and the package's rule) a group of its own on the VSC's device, and the limit
that lets it lock its memory (``LimitMEMLOCK=``, SR-9.6: a lock refused, or turned off by
``[realtime] lock_memory``, is said here too, whoever started it). The daemon
runs without any of them, so it says at its start, once, one line per part, which it lacks
and what the container or the person starting it must provide instead.

:func:`absent` is pure: the facts in (:class:`Surroundings`), the findings out, in a fixed
order. :func:`surroundings` reads the facts of this process and machine; the start calls both
(``supervisord/cli/srcsd.py``) and logs each finding as one warning.
"""

from __future__ import annotations

import dataclasses
import enum
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from supervisord.config.model import DaemonConfig, HidDevice, SerialPort
from supervisord.daemon.memory_lock import LOCKED, MemoryLock
from supervisord.daemon.notify import watchdog_usec

UDEV_CONTROL: Final = Path("/run/udev/control")
"""The socket systemd-udevd listens on: there when udev runs on this machine (the package's
postinst asks the same before ``udevadm trigger``)."""

GUIDE: Final = "docs/containers.md"
MEMLOCK_ADVICE: Final = "128 MiB"
"""The lock's limit a start without the unit is advised to give: the unit's own
``LimitMEMLOCK=`` (``units/srcsd@.service``)."""


class Part(enum.Enum):
    """A part of what the unit gives, as the start-up line names it."""

    WATCHDOG = "systemd's watchdog"
    REALTIME = "real-time scheduling"
    SANDBOX = "a sandbox"
    RESTART = "a restart"
    RUNTIME_DIRECTORY = "a runtime directory"
    DEVICE_GROUP = "udev's group on the device"
    MEMORY_LOCK = "locked memory"


@dataclasses.dataclass(frozen=True)
class Device:
    """A device node the daemon opens, as it is now: ``None`` fields when it is not there
    (a VSC not plugged in yet)."""

    path: Path
    uid: int | None = None
    gid: int | None = None
    mode: int | None = None


@dataclasses.dataclass(frozen=True)
class Surroundings:
    """The facts :func:`absent` judges, each read from this process or machine."""

    environ: Mapping[str, str]
    pid: int
    realtime: bool
    """The process runs SCHED_FIFO or SCHED_RR (the unit's ``CPUSchedulingPolicy=fifo``)."""
    no_new_privs: bool
    """``NoNewPrivs: 1`` in /proc/self/status (the unit's ``NoNewPrivileges=yes``)."""
    udev: bool
    """udev runs on this machine (:data:`UDEV_CONTROL` is a socket)."""
    socket_dirs: tuple[Path, ...]
    devices: tuple[Device, ...]
    uid: int = 0
    groups: tuple[int, ...] = ()
    memory: MemoryLock = LOCKED
    """What became of the start's memory lock (SR-9.6)."""


@dataclasses.dataclass(frozen=True)
class Absent:
    """One part the daemon runs without: ``fact`` says how it knows, ``instead`` what to
    provide in its place."""

    part: Part
    fact: str
    instead: str

    def line(self) -> str:
        return f"runs without {self.part.value} ({self.fact}): {self.instead} ({GUIDE})"


def _watchdog(env: Mapping[str, str], pid: int) -> bool:
    """As :class:`~supervisord.daemon.notify.Notifier` reads it: a socket to ping and a
    period meant for this process."""
    return bool(env.get("NOTIFY_SOCKET")) and watchdog_usec(env, pid) > 0


def _device_text(device: Device) -> str:
    if device.mode is None:
        return f"{device.path} (not there yet)"
    return f"{device.path} (uid {device.uid}, gid {device.gid}, mode {device.mode:04o})"


def absent(facts: Surroundings) -> list[Absent]:
    """Each part no service manager gives this start, in :class:`Part`'s order (SR-0.4)."""
    env = facts.environ
    found: list[Absent] = []
    if not _watchdog(env, facts.pid):
        found.append(
            Absent(
                Part.WATCHDOG,
                "no NOTIFY_SOCKET and WATCHDOG_USEC",
                "a hung loop is not killed (the VSC's key-85 watchdog still opens its relays); "
                "check it from outside: the container "
                "engine's health check running `srcsctl status` (exit 3: no srcsd answers), "
                "and a restart when it fails",
            )
        )
    if not facts.realtime:
        found.append(
            Absent(
                Part.REALTIME,
                "not SCHED_FIFO",
                "the loop waits behind every busy program; start it with `chrt -f 10` under "
                "`prlimit --rttime=1000000:2000000`, which the engine must allow "
                "(--cap-add=SYS_NICE; a kernel with RT group scheduling needs a budget, "
                "docker's --cpu-rt-runtime=950000)",
            )
        )
    if not facts.no_new_privs:
        found.append(
            Absent(
                Part.SANDBOX,
                "NoNewPrivs is 0",
                "run it as the user srcsd, never root, with no new privileges and no "
                "capabilities (`setpriv --reuid=srcsd --no-new-privs --bounding-set=-all`, "
                "--security-opt=no-new-privileges) on a read-only root but its record's and "
                "sockets' directories",
            )
        )
    if not env.get("INVOCATION_ID"):
        found.append(
            Absent(
                Part.RESTART,
                "no INVOCATION_ID: not a systemd unit",
                "nothing here starts it again when it exits; give the container a restart "
                "policy (--restart=on-failure) or a supervisor of its own; exit 78 is a "
                "configuration error, not to be restarted",
            )
        )
    if not env.get("RUNTIME_DIRECTORY"):
        dirs = " and ".join(str(d) for d in facts.socket_dirs)
        found.append(
            Absent(
                Part.RUNTIME_DIRECTORY,
                "no RUNTIME_DIRECTORY",
                f"{dirs} must exist before the start, writable by srcsd only, and be shared "
                "with the robot's programs (a volume or a tmpfs)",
            )
        )
    if not facts.udev and facts.devices:
        devices = ", ".join(_device_text(d) for d in facts.devices)
        groups = ", ".join(str(g) for g in facts.groups)
        found.append(
            Absent(
                Part.DEVICE_GROUP,
                "udev does not run here",
                f"opened with the permissions it has: {devices}, srcsd as uid {facts.uid}, "
                f"groups {groups}; pass the device in with a group srcsd is in "
                "(--device and --group-add)",
            )
        )
    if not facts.memory.locked:
        found.append(
            Absent(
                Part.MEMORY_LOCK,
                facts.memory.fact(),
                "the loop may wait on a page fault under memory pressure; give it "
                f"RLIMIT_MEMLOCK of {MEMLOCK_ADVICE} (LimitMEMLOCK=, `prlimit --memlock=`, "
                f"--ulimit memlock=) or CAP_IPC_LOCK (--cap-add=IPC_LOCK); "
                '[realtime] lock_memory = "required" refuses to start without it',
            )
        )
    return found


def devices(config: DaemonConfig) -> tuple[Path, ...]:
    """The device nodes the config's VSC link opens (none for CAN: an interface, no node)."""
    link = config.vsc.link
    if isinstance(link, SerialPort):
        return (link.port,)
    if isinstance(link, HidDevice):
        return (link.hidraw,)
    return ()


def _device(path: Path) -> Device:
    try:
        info = path.stat()
    except OSError:
        return Device(path)
    return Device(path, info.st_uid, info.st_gid, stat.S_IMODE(info.st_mode))


def _no_new_privs() -> bool:
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as status:
            return any(line.split() == ["NoNewPrivs:", "1"] for line in status)
    except OSError:
        return False


def _realtime() -> bool:
    """The process's policy is SCHED_FIFO or SCHED_RR, with or without SCHED_RESET_ON_FORK,
    which the unit's CPUSchedulingResetOnFork=yes (SR-9.8) or'es into what the kernel reports
    (seen: the unit's own start said it ran without real-time scheduling)."""
    policy = os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK
    return policy in (os.SCHED_FIFO, os.SCHED_RR)


def _udev() -> bool:
    try:
        return stat.S_ISSOCK(UDEV_CONTROL.stat().st_mode)
    except OSError:
        return False


def surroundings(config: DaemonConfig, memory: MemoryLock = LOCKED) -> Surroundings:
    """The facts of this process and machine now, for :func:`absent`; ``memory``: what the
    start's lock did (SR-9.6)."""
    dirs = dict.fromkeys((config.api.socket.parent, config.api.operator_path.parent))
    return Surroundings(
        environ=dict(os.environ),
        pid=os.getpid(),
        realtime=_realtime(),
        no_new_privs=_no_new_privs(),
        udev=_udev(),
        socket_dirs=tuple(dirs),
        devices=tuple(_device(path) for path in devices(config)),
        uid=os.getuid(),
        groups=tuple(sorted({os.getgid(), *os.getgroups()})),
        memory=memory,
    )
