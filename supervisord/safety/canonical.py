"""The canonical form of the core's state: what the exhaustive exploration compares states by
(``verify/``, docs/verification.md "The time abstraction").

A state is a pair ``(facts, clocks)``. ``facts`` is every discrete fact a later input can
depend on; ``clocks`` holds every time the core keeps, each as a :data:`Clock`: its age at
``now`` (``now - t``; negative for a deadline still ahead) and the constants its guards
compare that age with. Every guard on a time in the core is ``age >= c`` or ``age < c`` for a
constant ``c`` of its clock, so ages at or above the largest constant behave alike and are
clipped to it: two states whose facts are equal and whose clocks agree after clipping answer
every later input alike. Values that no guard reads (sequence numbers, the raise and clear
times of causes, measured trip times) are left out.
"""

from __future__ import annotations

Clock = tuple[str, int, tuple[int, ...]]
"""``(name, age, limits)``: ``age`` is ``now - t`` clipped to ``max(limits)``; ``limits`` are
the constants the core compares the age with, which the exploration also advances time to."""

Canonical = tuple[tuple[object, ...], tuple[Clock, ...]]
"""``(facts, clocks)``."""


def clock(name: str, at: int, now: int, *limits: int) -> Clock:
    """The clock of the time ``at`` seen at ``now``, clipped to the largest of ``limits``."""
    return name, min(now - at, max(limits)), limits
