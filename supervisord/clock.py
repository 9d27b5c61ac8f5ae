"""The daemon's one clock (SR-2.11): the monotonic clock, in integer nanoseconds.

Only the loop reads it (``Supervisor(clock=...)``, this by default); everything the loop
drives (the safety core, the API server and listener, the outputs, the links' timers) is
handed ``now`` by the loop and reads no clock of its own. A test then drives the whole loop
on a clock of its own (``docs/testing.md`` "Time in tests"), and no deadline of one part can
be compared with a time of another clock (``tests/test_one_clock.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Final

Clock = Callable[[], int]
"""A monotonic clock: integer nanoseconds, never going back."""

MONOTONIC: Final[Clock] = time.monotonic_ns
