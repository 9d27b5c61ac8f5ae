"""What a fleet stop's acknowledgement says of the outputs: each one read back now, and when
(SR-8.20; docs/api.md "fleet_stop").

The acknowledgement is the truth, not an echo of the decision: after the decision is applied,
every output the loop holds off is written off again and read back (a stop re-asserts off,
``Output.set``), so the reply carries what each line reads, and the clock when the last of
those read-backs returned. An output on at that moment (a category-1 power output still
braking, SR-1.4) is not written: it is reported on, with no read-back, and goes off at its
delay. A read-back that disagrees is handed back to the loop, which gives it to the core as
every other (``output_fault``, a stop, SR-6).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from supervisord.outputs.base import Output, ReadBack


@dataclass(frozen=True, slots=True)
class OutputCheck:
    """One output at the check: ``level`` the loop asks for, ``readback`` what the line read
    (``None``: not read: not open, or on and left alone)."""

    name: str
    level: bool
    readback: bool | None


@dataclass(frozen=True, slots=True)
class OffCheck:
    """Every output at the check, the clock when the last read-back returned (``checked_ns``,
    monotonic), the record's sequence offset of this start, and the read-backs that
    disagreed (the loop feeds them to the core)."""

    outputs: tuple[OutputCheck, ...]
    checked_ns: int
    sequence_offset: int
    faults: tuple[ReadBack, ...] = ()


def check_off(
    outputs: Mapping[str, Output], clock: Callable[[], int], sequence_offset: int
) -> OffCheck:
    """Write every open output that is off off again and read it back (SR-8.20)."""
    rows: list[OutputCheck] = []
    faults: list[ReadBack] = []
    for name, output in outputs.items():
        if not output.is_open or output.requested:
            rows.append(OutputCheck(name, output.requested, None))
            continue
        readback = output.set(False, clock())
        observed = readback.observed if readback.fault is None else None
        if readback.fault is None and observed is None:
            observed = readback.written  # CAN: a frame that went out is the read-back
        rows.append(OutputCheck(name, False, observed))
        if not readback.ok:
            faults.append(readback)
    return OffCheck(tuple(rows), clock(), sequence_offset, tuple(faults))
