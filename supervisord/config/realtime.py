"""``[realtime]``: what the daemon's start does about the memory lock (SR-9.6;
docs/configuration.md ``[realtime]``), read by the configuration and applied by
:mod:`supervisord.daemon.memory_lock`, which stands above the configuration."""

from __future__ import annotations

import enum
from typing import Final

from supervisord import strict


class LockMode(enum.Enum):
    """``lock_memory``: whether the start locks the daemon's memory, and what a refusal does."""

    ON = "on"
    """Lock; when refused, run without it, said once at the start and in ``status``."""
    REQUIRED = "required"
    """Lock; when refused, the daemon does not start (exit 1)."""
    OFF = "off"
    """Do not lock: for tests that plant a page fault in the loop (said at the start as a
    refusal is)."""


LOCK_MEMORY: Final = strict.Choice(
    name="lock_memory",
    doc="Lock the daemon's memory at its start (mlockall), so that the loop never waits on a "
    "page fault under memory pressure (SR-9.6). The unit's LimitMEMLOCK= allows it.",
    values={
        LockMode.ON.value: "lock; when refused, run without it, said at the start, in status "
        "(memory_locked) and by the exporter",
        LockMode.REQUIRED.value: "lock; when refused, do not start (exit 1)",
        LockMode.OFF.value: "do not lock (for tests only: the loop may fault)",
    },
    default=LockMode.ON.value,
    example=LockMode.REQUIRED.value,
)

REALTIME: Final = (LOCK_MEMORY,)
"""``[realtime]``'s keys."""
