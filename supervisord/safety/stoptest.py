"""The field stop test's result (SR-12.1, docs/srcsctl.md "The field stop test"): pure values.

``srcsctl stoptest`` has the operator press the remote's e-stop (and, with ``--wired``, the
VSC's wired one); for each press the daemon measured, on its monotonic clock, from the read of
the VSC heartbeat that reported the e-stop (the stop record's ``mono_ns``) to each output's
off write returning with a read-back that matches. :class:`StopTestResult` holds those
numbers and judges them against :data:`LIMIT_MS`; the safety core records it as a
``stoptest`` record (the event :class:`~supervisord.safety.events.StopTested`).

No clock, no I/O: the daemon measures, this module only compares.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from supervisord.timebase import NS_PER_MS

LIMIT_MS: Final = 50
"""SR-12.1: from the read of the VSC heartbeat that reports the e-stop to each output reading
back off, at most this. One stop measured on the robot's own computer, not a bench's p99
(SR-9.1's 2 ms): five times the worst single stop the loaded bench saw (10 ms,
docs/performance.md) and one serial heartbeat interval, so a supervisor a whole heartbeat late
fails. With the VSC's own indication within 250 ms of the button (manual, its absolute worst
case) and its next heartbeat at most 50 ms (serial) or 100 ms (CAN) later, every output is
off within 350 ms (400 ms on CAN) of the button."""

MAX_STEPS: Final = 2  # the remote's e-stop, then the wired one
MAX_OUTPUTS: Final = 64  # far beyond any robot's outputs: a bound on what a record carries


class Source(enum.Enum):
    """Which e-stop the operator pressed: the VSC heartbeat's named source (PR-2.6)."""

    REMOTE = "remote"
    WIRED = "wired"


@dataclass(frozen=True, slots=True)
class OutputOff:
    """One output in one step: ``off_ns`` from the e-stop's frame to the off write returning
    with a matching read-back, or ``None`` when no such read-back came (an output fault, or
    the output was not on at the stop). A category-1 output (SR-1.4) is judged after its
    ``off_delay_ms``: it is meant to stay on that long."""

    name: str
    off_ns: int | None
    off_delay_ms: int = 0  # a category-1 output's delay after the motion outputs (SR-1.4)

    def passed(self, limit_ms: int) -> bool:
        """Off within the limit, after the output's own off delay if it has one."""
        limit_ns = (limit_ms + self.off_delay_ms) * NS_PER_MS
        return self.off_ns is not None and 0 <= self.off_ns <= limit_ns

    @property
    def off_ms(self) -> float | None:
        return None if self.off_ns is None else round(self.off_ns / NS_PER_MS, 3)


@dataclass(frozen=True, slots=True)
class StopStep:
    """One press: its source, the stop record it made (``seq``) and that record's ``mono_ns``
    (the frame's read stamp), and every output's time to off."""

    source: Source
    seq: int
    stop_ns: int
    outputs: tuple[OutputOff, ...]

    def passed(self, limit_ms: int) -> bool:
        return bool(self.outputs) and all(o.passed(limit_ms) for o in self.outputs)


@dataclass(frozen=True, slots=True)
class StopTestResult:
    """A finished field stop test: its steps and the limit they were judged against."""

    steps: tuple[StopStep, ...]
    limit_ms: int = LIMIT_MS

    @property
    def passed(self) -> bool:
        return bool(self.steps) and all(step.passed(self.limit_ms) for step in self.steps)

    @property
    def text(self) -> str:
        """One line for the record's ``reason`` and the journal: the verdict, then each
        step's slowest output."""
        parts = []
        for step in self.steps:
            times = [o.off_ns for o in step.outputs]
            if not times or None in times:
                missing = [o.name for o in step.outputs if o.off_ns is None] or ["no outputs"]
                parts.append(f"{step.source.value}: not off: {', '.join(missing)}")
            else:
                slowest = max(o for o in times if o is not None) / NS_PER_MS
                parts.append(f"{step.source.value}: every output off within {slowest:.1f} ms")
        verdict = "passed" if self.passed else "FAILED"
        delays = any(o.off_delay_ms for step in self.steps for o in step.outputs)
        limit = f"{self.limit_ms} ms" + (" after each output's off delay" if delays else "")
        return f"{verdict} (limit {limit}): {'; '.join(parts) or 'no steps'}"

    def json(self) -> dict[str, object]:
        """The record's ``stoptest`` object (docs/record.md)."""
        return {
            "result": "passed" if self.passed else "failed",
            "limit_ms": self.limit_ms,
            "steps": [
                {
                    "source": step.source.value,
                    "seq": step.seq,
                    "stop_ns": step.stop_ns,
                    "passed": step.passed(self.limit_ms),
                    "outputs": [
                        {
                            "name": o.name,
                            "off_ns": o.off_ns,
                            "off_ms": o.off_ms,
                            "off_delay_ms": o.off_delay_ms,
                            "passed": o.passed(self.limit_ms),
                        }
                        for o in step.outputs
                    ],
                }
                for step in self.steps
            ],
            "text": self.text,
        }


class StopTestFormatError(ValueError):
    """Not a result :meth:`StopTestResult.json` wrote."""


def _int(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise StopTestFormatError(f"{what}: not an integer: {value!r}"[:200])
    return value


def result_from_json(data: object) -> StopTestResult:
    """The result :meth:`StopTestResult.json` wrote (the flight recorder reads it back);
    derived fields (``passed``, ``off_ms``, ``text``) are recomputed, never trusted."""
    if not isinstance(data, Mapping) or not isinstance(data.get("steps"), list):
        raise StopTestFormatError("not a stop test result")
    steps = []
    for step in data["steps"][:MAX_STEPS]:
        if not isinstance(step, Mapping) or not isinstance(step.get("outputs"), list):
            raise StopTestFormatError("not a stop test step")
        try:
            source = Source(step.get("source"))
        except ValueError as error:
            raise StopTestFormatError(str(error)) from error
        outputs = []
        for output in step["outputs"][:MAX_OUTPUTS]:
            if not isinstance(output, Mapping) or not isinstance(output.get("name"), str):
                raise StopTestFormatError("not a stop test output")
            off, delay = output.get("off_ns"), _int(output.get("off_delay_ms", 0), "off_delay_ms")
            outputs.append(
                OutputOff(output["name"], None if off is None else _int(off, "off_ns"), delay)
            )
        steps.append(
            StopStep(
                source,
                _int(step.get("seq"), "seq"),
                _int(step.get("stop_ns"), "stop_ns"),
                tuple(outputs),
            )
        )
    return StopTestResult(tuple(steps), _int(data.get("limit_ms"), "limit_ms"))
