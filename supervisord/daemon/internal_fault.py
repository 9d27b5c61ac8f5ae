"""The loop's own failures, as the ``internal`` cause's events (SR-2).

The loop woke too late after the core's deadline (:func:`late`), or a turn raised
(:func:`failed`): each becomes an :class:`~supervisord.safety.events.InternalFault` the loop
feeds to the core like any input, after switching the outputs off itself for a raise (the
decision that would have done it may be what failed). Counted for ``status``; holds nothing.
"""

from __future__ import annotations

import logging

from supervisord.daemon.loop_status import Counters
from supervisord.safety.events import InternalFault
from supervisord.timebase import NS_PER_MS

__all__ = ["OVERRUN_NS", "failed", "late"]

log = logging.getLogger("srcsd")

OVERRUN_NS = 250 * NS_PER_MS  # woke this late after the core's deadline: the loop is failing


def late(now: int, deadline: int) -> InternalFault:
    """The fault of a wake at ``now``, more than :data:`OVERRUN_NS` after ``deadline`` (the
    loop compares, once a turn, without a call: SR-9.4)."""
    return InternalFault(now, f"loop woke {(now - deadline) // NS_PER_MS} ms late")


def failed(now: int, error: Exception, counters: Counters) -> InternalFault:
    """The fault of a turn that raised ``error`` (logged with its trace, counted)."""
    counters.internal_faults += 1
    log.exception("internal fault in the main loop", exc_info=error)
    try:
        said = f"{type(error).__name__}: {error}"
    except Exception:  # an error that cannot say itself still stops (fail safe)
        said = type(error).__name__
    return InternalFault(now, said)
