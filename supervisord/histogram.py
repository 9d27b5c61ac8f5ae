"""A fixed-bucket histogram of monotonic-clock durations, for the loop's own timing.

The loop observes three durations with it (docs/fleet.md "Timing histograms"): the VSC
heartbeat period, the user heartbeat period, and the stop-to-off latency. ``observe`` is a
handful of integer operations (one ``bisect`` over a short tuple of integer bounds, three
additions), so that the VSC heartbeat, observed on every one the loop reads, keeps the cheap
path cheap (SR-9.4); the stop-to-off observation is made only after the outputs are written
and the frames sent (SR-6, SR-10: the stop path first). Every time is an integer of
nanoseconds (SR-2.11); seconds appear only in :meth:`Histogram.snapshot`, for the wire.

Pure: no clock, no I/O, imports nothing of the project.
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass
from itertools import pairwise
from typing import Final

_US: Final = 1_000
_MS: Final = 1_000_000

HEARTBEAT_BOUNDS_NS: Final = (
    5 * _MS,
    10 * _MS,
    20 * _MS,  # the user heartbeat at 50 Hz (SR-5, the fastest allowed)
    25 * _MS,  # 40 Hz
    30 * _MS,
    40 * _MS,  # 25 Hz
    45 * _MS,
    50 * _MS,  # 20 Hz: the slowest user heartbeat, and the serial VSC's heartbeat
    55 * _MS,
    60 * _MS,
    75 * _MS,
    100 * _MS,  # the CAN VSC's heartbeat (10 Hz)
    110 * _MS,
    150 * _MS,
    200 * _MS,  # the serial VSC timeout's default (SR-2.2)
    300 * _MS,  # the CAN VSC timeout's default
    500 * _MS,
    1000 * _MS,  # the longest VSC timeout a config may set
)
"""Upper bounds of the heartbeat-period buckets: dense around the nominal periods (20 to 50 ms
for the user heartbeat, 50 and 100 ms for the VSC's), with 5 ms steps either side of 50 ms to
show jitter (SR-9.3 allows 2 ms at p99), then the link timeouts, so a period past the timeout
(the link-loss stop) lands in its own bucket. docs/fleet.md "Timing histograms"."""

STOP_TO_OFF_BOUNDS_NS: Final = (
    100 * _US,
    250 * _US,
    500 * _US,
    1 * _MS,
    2 * _MS,  # SR-9.1's p99 target
    5 * _MS,  # SR-9.2's margin past the link timeout
    10 * _MS,
    25 * _MS,
    50 * _MS,
    100 * _MS,
    250 * _MS,  # the loop's overrun limit (an internal fault)
    1000 * _MS,
)
"""Upper bounds of the stop-to-off buckets: 0.1 ms (a GPIO write right after the read) to
100 ms and past it, with the bounds SR-9.1 and SR-9.2 name, so their targets read off the
``_bucket`` series directly."""


@dataclass(frozen=True, slots=True)
class Snapshot:
    """A histogram as the wire carries it (docs/api.md "status"): the buckets' upper bounds in
    seconds, the cumulative count at each, the sum in seconds and the count (the ``+Inf``
    bucket's count)."""

    le: tuple[float, ...]
    counts: tuple[int, ...]
    sum: float
    count: int


class Histogram:
    """Counts of durations (nanoseconds) per bucket, their sum and their number."""

    __slots__ = ("_counts", "bounds_ns", "count", "sum_ns")

    def __init__(self, bounds_ns: tuple[int, ...]) -> None:
        if not bounds_ns or any(b <= a for a, b in pairwise(bounds_ns)):
            raise ValueError("bucket bounds must be increasing and not empty")
        if bounds_ns[0] <= 0:
            raise ValueError("bucket bounds must be positive")
        self.bounds_ns = bounds_ns
        self._counts = [0] * (len(bounds_ns) + 1)  # per bucket, not cumulative; last is +Inf
        self.sum_ns = 0
        self.count = 0

    def observe(self, value_ns: int) -> None:
        """Count one duration. A negative one (impossible on a monotonic clock) counts as 0."""
        if value_ns < 0:  # noqa: PLR1730 - a comparison, not a call: on every heartbeat
            value_ns = 0
        # ``le`` semantics: a value equal to a bound belongs to that bound's bucket.
        self._counts[bisect_left(self.bounds_ns, value_ns)] += 1
        self.sum_ns += value_ns
        self.count += 1

    def snapshot(self) -> Snapshot:
        """The cumulative view, in seconds (computed here, not on ``observe``)."""
        cumulative: list[int] = []
        running = 0
        for n in self._counts[:-1]:
            running += n
            cumulative.append(running)
        return Snapshot(
            tuple(b / 1e9 for b in self.bounds_ns),
            tuple(cumulative),
            self.sum_ns / 1e9,
            self.count,
        )
