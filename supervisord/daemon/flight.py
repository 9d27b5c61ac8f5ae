"""The flight recorder's ring: the last seconds of the safety core's inputs, kept by the loop, and
the bases a replay can start from (SR-7.10, SR-7.11; ``docs/record.md`` "The flight recorder").

The loop appends every input it gives the core (:meth:`Supervisor._feed`: VSC messages, link
events, client requests, read-backs, ticks) to :attr:`FlightRecorder.inputs`, a deque with a
``maxlen``: one append of the event's reference and one count, nothing that can wait or
raise, no allocation of its own.

A window is worth something only if it can be replayed, and the core's state where the window
starts is not its start state. So the recorder keeps two *bases*: the core's state at the
daemon's start (a fresh core: nothing to keep but the time) or a snapshot of the core
(:mod:`supervisord.safety.snapshot`) taken by the loop between two turns, every
:attr:`FlightSettings.window_s`, or sooner when half the ring has filled since the last one.
The older base is at least ``window_s`` before any stop, the newer one less; a window starts at
the older when the ring still reaches back to it, else at the newer. A snapshot costs the loop
some hundreds of microseconds once per ``window_s``, before it waits, never between an input
and its outputs (``docs/performance.md`` "The flight recorder").

At a stop the loop takes :meth:`FlightRecorder.window`: a tuple of the ring (its references,
copied) with the bases that reach into it, handed to the sink's flight lane, which encodes and
writes it (``supervisord/record/flight.py``). The loop never waits for it.

No clock of its own: the loop hands ``now`` (SR-2.11).
"""

from __future__ import annotations

import dataclasses
from collections import deque

from supervisord import __version__
from supervisord.record.flight import Base, Window
from supervisord.record.jsonl import DEFAULT_FLIGHT_MAX_BYTES, FLIGHT_MAX_BYTES_RANGE
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.events import Event
from supervisord.safety.snapshot import snapshot
from supervisord.timebase import NS_PER_S


@dataclasses.dataclass(frozen=True, slots=True)
class FlightSettings:
    """How much the ring keeps: at least ``window_s`` seconds before a stop (up to twice that),
    and never more than ``max_inputs`` inputs (a flood of client requests fills it sooner:
    then the window is shorter, never larger); and how many bytes the windows on disk take
    together, at most ``max_bytes``."""

    window_s: float = 5.0
    max_inputs: int = 4096
    max_bytes: int = DEFAULT_FLIGHT_MAX_BYTES
    """The windows on disk together, at most (``[record] flight_max_bytes``, SR-7.12)."""

    def __post_init__(self) -> None:
        if not 0 < self.window_s <= 60:
            raise ValueError(f"window_s must be over 0 and at most 60, not {self.window_s}")
        if not 16 <= self.max_inputs <= 1 << 20:
            raise ValueError(f"max_inputs must be 16 to {1 << 20}, not {self.max_inputs}")
        low, high = FLIGHT_MAX_BYTES_RANGE
        if not low <= self.max_bytes <= high:
            raise ValueError(f"max_bytes must be {low} to {high}, not {self.max_bytes}")


class FlightRecorder:
    """The ring of inputs and its two bases (see the module docstring)."""

    def __init__(self, config: SafetyConfig, settings: FlightSettings | None = None) -> None:
        settings = settings or FlightSettings()
        self.config = config
        self.window_ns = int(settings.window_s * NS_PER_S)
        self.inputs: deque[Event] = deque(maxlen=settings.max_inputs)
        """The inputs, oldest first; the loop appends to it directly (and counts)."""
        self.count = 0
        """Inputs appended since the start (the last one is numbered ``count - 1``)."""
        self.last_seq = 0
        """The sequence number of the last record the loop made, for the next base."""
        self.snapshot_errors = 0
        self._half = settings.max_inputs // 2
        self._older: Base | None = None
        self._newer: Base | None = None
        self._next_ns = 0

    def start(self, now: int, after_seq: int) -> None:
        """The core was made at ``now`` (a fresh core); its records follow ``after_seq``."""
        self.last_seq = after_seq
        self._older, self._newer = None, Base(self.count, now, after_seq, None)
        self._next_ns = now + self.window_ns

    def due(self, now: int) -> bool:
        """Whether the loop should take a snapshot now (two comparisons)."""
        newer = self._newer
        return now >= self._next_ns or (
            newer is not None and self.count - newer.index >= self._half
        )

    def rebase(self, core: SafetyCore, now: int) -> Exception | None:
        """A snapshot of ``core`` (between two inputs) becomes the newer base, the newer the
        older. A snapshot that fails leaves no newer base (counted; the error is returned for
        the loop to log): a window then starts at the older one, while the ring reaches it."""
        self._next_ns = now + self.window_ns
        try:
            base = Base(self.count, now, self.last_seq, snapshot(core))
        except Exception as error:  # the loop must not fail for its recorder
            self.snapshot_errors += 1
            self._older, self._newer = self._newer, None
            return error
        self._older, self._newer = self._newer, base
        return None

    def window(self, stop: StopRecord, sequence_offset: int) -> Window:
        """What the sink writes for the stop record ``stop``: the ring as a tuple and the bases
        that reach into it."""
        inputs = tuple(self.inputs)
        end = self.count
        first = end - len(inputs)
        bases = tuple(b for b in (self._older, self._newer) if b is not None and b.index >= first)
        cut = "" if bases else f"the ring's bound ({self.inputs.maxlen} inputs) cut its start"
        return Window(
            stop=stop,
            config=self.config,
            sequence_offset=sequence_offset,
            inputs=inputs,
            end=end,
            bases=bases,
            window_ns=self.window_ns,
            version=__version__,
            cut=cut,
        )
