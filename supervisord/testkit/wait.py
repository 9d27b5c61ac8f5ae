"""Waiting in the test kit: poll until something holds, or fail the test naming what.

Deadlines are coarse on purpose (a functional suite on a shared machine); the rules' own
latencies (SR-9) are measured by ``bench/``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from supervisord.tooling.polling import poll_until

WAIT_S = 10.0  # how long any "until" waits before the scenario fails


class FaultHarnessError(AssertionError):
    """A scenario's promise did not hold (an AssertionError, so pytest shows it as a failure)."""


def wait_until(
    condition: Callable[[], Any],
    timeout: float = WAIT_S,
    poll: float = 0.01,
    what: str = "",
    pause: Callable[[float], object] = time.sleep,
) -> Any:
    """Poll ``condition`` until it returns something true; return that. Raise
    ``FaultHarnessError`` naming ``what`` after ``timeout`` seconds. ``pause(poll)`` runs
    between polls (a ROS 2 node spins its executor there instead of sleeping)."""
    held, value = poll_until(condition, bool, timeout, pause, poll)
    if not held:
        raise FaultHarnessError(f"timed out after {timeout} s waiting for {what or condition}")
    return value
