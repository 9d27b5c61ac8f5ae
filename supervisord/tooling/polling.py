"""Polling until something holds: the one loop the simulator's control client and the test
kit's waits share (each raises its own error, naming what it waited for)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def poll_until(
    read: Callable[[], T],
    done: Callable[[T], object],
    timeout: float,
    pause: Callable[[float], object],
    interval: float,
) -> tuple[bool, T]:
    """Call ``read`` until ``done`` holds for what it returned, ``pause(interval)`` between
    calls, for ``timeout`` seconds at most (one read always). Returns whether it held, and the
    last value read (for the caller's error message)."""
    end = time.monotonic() + timeout
    while True:
        value = read()
        if done(value):
            return True, value
        if time.monotonic() > end:
            return False, value
        pause(interval)
