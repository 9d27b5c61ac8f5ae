"""The daemon's memory, locked at its start: the loop never waits on a page fault (SR-9.6,
docs/safety-manual.md "Assumptions of use").

Under memory pressure the kernel pages out what a process has not touched lately; the loop's
next turn would then wait for the disk (a major fault) or at least for the kernel (a minor
one) on the stop path. ``mlockall(MCL_CURRENT | MCL_FUTURE)`` keeps every page the process
has, and every page it maps later, in memory and populated. Python has no ``os.mlockall``: the
call goes to the C library through ctypes, no dependency.

``MCL_FUTURE`` locks every future mapping whole, at its ``mmap``, and counts it in full
against ``RLIMIT_MEMLOCK`` (the unit's ``LimitMEMLOCK=``): a mapping that does not fit fails,
and Python raises ``MemoryError``. Two of the C library's defaults would make that likely
(measured: ``bench/memory_lock.py``): each thread's stack is 8 MiB (``RLIMIT_STACK``),
populated whole once locked, and each thread that calls ``malloc`` gets an arena of its own
that reserves 64 MiB of address space, all of it counted. :func:`prepare` makes threads' stacks
:data:`THREAD_STACK_BYTES` and keeps one arena (``mallopt(M_ARENA_MAX, 1)``), before any thread
starts: the daemon then locks about 37 MiB, well inside the unit's 128 MiB.

What a refusal does is the configuration's choice (``[realtime] lock_memory``,
:class:`~supervisord.config.realtime.LockMode`): by default the daemon runs without the lock
(availability: a robot with a VSC is still stopped by it), says so once at its start with the
fix (a line of ``supervisord/daemon/service_manager_absent.py``, SR-0.4) and in ``status``
(``memory_locked``) and the exporter (``srcs_memory_locked``); ``required`` refuses to start;
``off`` does not lock (for tests that need the daemon unlocked: the kernel's page-fault
monitor must see the fault they plant).
"""

from __future__ import annotations

import ctypes
import dataclasses
import os
import resource
import threading
from typing import Final

from supervisord.config.realtime import LockMode

MCL_CURRENT: Final = 1
MCL_FUTURE: Final = 2
"""mlockall(2)'s flags (the same values on every Linux architecture Debian builds)."""
M_ARENA_MAX: Final = -8
"""mallopt(3)'s parameter: how many malloc arenas the process may have (glibc)."""
THREAD_STACK_BYTES: Final = 512 << 10
"""Each thread's stack (the loop's, the main thread's, is the process's own): 512 KiB, a
sixteenth of the default, each locked whole: a lane runs shallow Python (a record's JSON, a
log line, an fsync), and Python 3.11 does not grow the C stack for a call between Python
functions."""


@dataclasses.dataclass(frozen=True, slots=True)
class MemoryLock:
    """What became of the lock: ``locked``, or why not (``reason``: the error's text, or the
    configuration's ``off``); ``limit`` the process's ``RLIMIT_MEMLOCK`` in bytes (``None``:
    unlimited)."""

    mode: LockMode
    locked: bool
    reason: str = ""
    limit: int | None = None

    def fact(self) -> str:
        """Why it is not locked, as the start-up line says it (SR-0.4)."""
        if self.mode is LockMode.OFF:
            return 'lock_memory = "off"'
        limit = "unlimited" if self.limit is None else f"{self.limit // 1024} KiB"
        return f"mlockall: {self.reason}, RLIMIT_MEMLOCK {limit}"


LOCKED: Final = MemoryLock(LockMode.ON, locked=True)
"""A lock that held (what the unit gives)."""


def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def memlock_limit() -> int | None:
    """The soft ``RLIMIT_MEMLOCK`` in bytes (``None``: unlimited)."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_MEMLOCK)
    return None if soft == resource.RLIM_INFINITY else soft


def prepare() -> None:
    """Make what ``MCL_FUTURE`` will lock small: threads' stacks of
    :data:`THREAD_STACK_BYTES` and one malloc arena. Before any thread starts, whatever the
    mode (the unlocked daemon differs from the locked one by the lock alone)."""
    threading.stack_size(THREAD_STACK_BYTES)
    _libc().mallopt(M_ARENA_MAX, 1)  # 0 only on a C library without it: nothing to do


def lock(mode: LockMode) -> MemoryLock:
    """Lock the process's memory, now and future, unless ``mode`` is ``off``; a refusal is
    returned, never raised (the caller decides by ``mode``)."""
    limit = memlock_limit()
    if mode is LockMode.OFF:
        return MemoryLock(mode, locked=False, limit=limit)
    libc = _libc()
    if libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0:
        return MemoryLock(mode, locked=True, limit=limit)
    reason = os.strerror(ctypes.get_errno())
    # A refused MCL_CURRENT may leave MCL_FUTURE set (mlockall(2) sets the flags first):
    # unset it, or every later mapping would be refused against a limit already too small.
    libc.munlockall()
    return MemoryLock(mode, locked=False, reason=reason, limit=limit)
