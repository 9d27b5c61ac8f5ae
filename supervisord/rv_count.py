"""The kernel judge's violations counted in the field: lines of an rv trace in, counts out.

A robot's kernel built with the rtapp monitors (docs/kernel-judge.md) writes one ``error_*``
event per violation: ``TASK-PID [CPU] FLAGS TIMESTAMP: error_MONITOR: COMM[PID]: violation
detected``. :class:`ViolationCounter` counts those of the daemon's threads (the loop
``srcsd``, its lanes ``srcsd-*``: SR-9.7) by monitor and thread, for ``srcs-rv``
(:mod:`supervisord.rv_watch`) to hand to the exporter (SR-9.9).

Pure, and bounded whatever the kernel, or whoever names a thread, writes: a line over
:data:`MAX_LINE` bytes is dropped as it comes, at most :data:`MAX_KEYS` (monitor, thread)
pairs are kept, every byte is looked at a bounded number of times (no regular expression runs
on more than one line's bytes), and nothing raises on any bytes. A line it cannot read is
counted, never guessed at. The system tier's verdict (tests/system/rv.py) reads the same lines
with their stacks; this is its field twin, without the allow-list: the field counts, the tier
judges.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Final

MONITORS: Final = ("pagefault", "sleep", "wakeup")
"""The rtapp container's monitors (Linux 7.3)."""
MAX_LINE: Final = 512
"""Bytes a line may have, its newline included; a violation's line is about 100."""
MAX_KEYS: Final = 64
"""Distinct (monitor, thread) pairs kept; past it a violation counts in ``overflow``."""
DAEMON_THREAD: Final = re.compile(r"srcsd(-[\w.-]*)?", re.ASCII)
"""The loop ``srcsd`` and its lanes ``srcsd-*`` (SR-9.7). A kernel ``comm`` is at most 15
bytes; what matches here has no colon or space, so no thread can name itself into another's
count (see :func:`read_line`)."""
LOOP_THREAD: Final = "srcsd"

_SUFFIX = "]: violation detected"
_MARK = ": error_"
_LOST = re.compile(r"CPU:\d+ \[LOST (\d+) EVENTS\]", re.ASCII)  # trace_pipe's own line


@dataclass(frozen=True, slots=True)
class Event:
    """One ``error_MONITOR`` event: the judged task's name and the trace's timestamp (seconds
    on the instance's trace clock; ``None`` when the line's clock is not in seconds)."""

    monitor: str
    task: str
    seconds: float | None


@dataclass(frozen=True, slots=True)
class Lost:
    """trace_pipe's ``CPU:N [LOST M EVENTS]``: the ring overwrote ``events`` before a read."""

    events: int


def read_line(line: str) -> Event | Lost | None:
    """The event (or lost-events notice) of one line, or ``None`` when it is neither.

    Read from the right: the judged task's ``COMM[PID]`` ends the line and is preceded by the
    last ``: error_``; the running task before it (``TASK-PID``) may hold spaces, brackets and
    colons of its own. Since a ``comm`` has at most 15 bytes and ``: error_sleep: srcsd`` has
    20, no task can spell a daemon thread's violation inside its name."""
    text = line.rstrip()
    lost = _LOST.fullmatch(text.strip())
    if lost is not None:
        return Lost(int(lost[1]))
    if not text.endswith(_SUFFIX):
        return None
    head = text[: -len(_SUFFIX)]
    bracket = head.rfind("[")
    if bracket < 0 or not head[bracket + 1 :].isdigit():
        return None
    mark = head.rfind(_MARK, 0, bracket)
    if mark < 0:
        return None
    monitor, sep, task = head[mark + len(_MARK) : bracket].partition(": ")
    if not sep or monitor not in MONITORS:
        return None
    stamp = head[:mark].rsplit(None, 1)
    return Event(monitor, task, _seconds(stamp[-1]) if stamp else None)


def _seconds(text: str) -> float | None:
    """A trace timestamp (``12345.678901``), or ``None`` when the clock is a counter or the
    text is no number."""
    if "." not in text or len(text) > 32:
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) and value >= 0 else None


def _skipped(line: str) -> bool:
    """Blank lines, the trace file's ``#`` header, and a stack trigger's lines (an
    integrator's own ``stacktrace`` trigger on the event): read, and nothing to count."""
    stripped = line.strip()
    return (
        not stripped
        or stripped.startswith("#")
        or stripped.startswith("=> ")
        or stripped.endswith("<stack trace>")
    )


@dataclass
class ViolationCounter:
    """Running counts over every byte fed (:meth:`feed`): the daemon's violations by
    (monitor, thread), those past :data:`MAX_KEYS` by monitor (``overflow``), other tasks'
    (``others``, not the daemon's: not judged), the lines it could not read, the events the
    ring reported lost, and the timestamp of the daemon's last violation."""

    violations: dict[tuple[str, str], int] = field(default_factory=dict)
    overflow: dict[str, int] = field(default_factory=dict)
    others: int = 0
    unreadable: int = 0
    lost_reported: int = 0
    last_seconds: float | None = None
    _partial: bytearray = field(default_factory=bytearray, repr=False)
    _discarding: bool = field(default=False, repr=False)

    def feed(self, data: bytes) -> None:
        """Bytes of the trace as read, cut anywhere: whole lines are counted, a line's start
        is kept (at most :data:`MAX_LINE` bytes) for the next call. Each byte is searched for
        the newline once."""
        start = 0
        while start < len(data):
            end = data.find(b"\n", start)
            if end < 0:
                self._keep(data, start, len(data))
                return
            if self._discarding:
                self._discarding = False  # the end of a line already counted unreadable
            elif len(self._partial) + end - start >= MAX_LINE:
                self.unreadable += 1
                self._partial.clear()
            else:
                self._partial += data[start:end]
                self._line(bytes(self._partial))
                self._partial.clear()
            start = end + 1

    def _keep(self, data: bytes, start: int, end: int) -> None:
        if self._discarding:
            return
        if len(self._partial) + end - start >= MAX_LINE:
            # Too long already: counted once, and its bytes dropped up to its newline.
            self.unreadable += 1
            self._partial.clear()
            self._discarding = True
            return
        self._partial += data[start:end]

    def _line(self, raw: bytes) -> None:
        line = raw.decode("utf-8", errors="replace")
        if _skipped(line):
            return
        read = read_line(line)
        if read is None:
            self.unreadable += 1
        elif isinstance(read, Lost):
            self.lost_reported += read.events
        elif DAEMON_THREAD.fullmatch(read.task) is None:
            self.others += 1
        else:
            self._count(read)

    def _count(self, event: Event) -> None:
        key = (event.monitor, event.task)
        if key in self.violations or len(self.violations) < MAX_KEYS:
            self.violations[key] = self.violations.get(key, 0) + 1
        else:
            self.overflow[event.monitor] = self.overflow.get(event.monitor, 0) + 1
        if event.seconds is not None:
            self.last_seconds = max(event.seconds, self.last_seconds or 0.0)

    def total(self) -> int:
        """The daemon's violations counted, overflow included."""
        return sum(self.violations.values()) + sum(self.overflow.values())
