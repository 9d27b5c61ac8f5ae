"""The service unit's scheduling settings, as the benches and tests apply them.

``units/srcsd@.service`` runs the daemon with ``Nice=``, ``CPUSchedulingPolicy=fifo`` at
``CPUSchedulingPriority=`` and ``LimitRTTIME=soft:hard`` (docs/install.md "Scheduling",
SR-9). The timing benches run the loops under the same settings with ``--loaded``,
and ``bench.rt_budget`` starts the daemon under them; this module reads them from the unit file
(one parser for all) and applies them. It imports nothing of the product.
"""

from __future__ import annotations

import contextlib
import os
import re
import resource
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

UNIT = Path(__file__).resolve().parents[1] / "units" / "srcsd@.service"
_UNITS_US = {"us": 1, "usec": 1, "ms": 1000, "msec": 1000, "s": 1_000_000, "sec": 1_000_000}


@dataclass(frozen=True)
class Scheduling:
    """``nice``; the SCHED_FIFO ``priority`` (0: the unit sets no FIFO policy); RLIMIT_RTTIME
    ``soft_us`` and ``hard_us`` in microseconds (``None``: not set, or infinity)."""

    nice: int = 0
    priority: int = 0
    soft_us: int | None = None
    hard_us: int | None = None


def span_us(text: str) -> int | None:
    """A systemd time span as ``LimitRTTIME=`` takes it: plain microseconds, or a number with
    one of the units us, ms, s; ``None`` for ``infinity``."""
    text = text.strip()
    if text == "infinity":
        return None
    match = re.fullmatch(r"(\d+)\s*([a-z]*)", text)
    if match is None or match.group(2) not in ("", *_UNITS_US):
        raise ValueError(f"not a time span this bench reads: {text!r}")
    return int(match.group(1)) * _UNITS_US.get(match.group(2), 1)


def read_unit(unit: Path = UNIT) -> Scheduling:
    """The unit file's ``Nice=``, FIFO priority (only with ``CPUSchedulingPolicy=fifo``) and
    ``LimitRTTIME=`` (one value: soft and hard alike)."""
    nice, fifo, priority, soft, hard = 0, False, 1, None, None
    for line in unit.read_text().splitlines():
        key, _, value = line.strip().partition("=")
        if key == "Nice":
            nice = int(value)
        elif key == "CPUSchedulingPolicy":
            fifo = value.strip() == "fifo"
        elif key == "CPUSchedulingPriority":
            priority = int(value)
        elif key == "LimitRTTIME":
            first, _, second = value.partition(":")
            soft = span_us(first)
            hard = span_us(second) if second else soft
    return Scheduling(nice, priority if fifo else 0, soft, hard)


def apply_in_child(scheduling: Scheduling) -> None:
    """For ``preexec_fn``, between fork and exec as systemd's exec does: the RLIMIT_RTTIME,
    the nice value and the FIFO policy, before the program runs (so its start-up is under
    them too). Needs root for a FIFO policy or a negative nice value."""
    if scheduling.soft_us is not None:
        hard = scheduling.hard_us if scheduling.hard_us is not None else resource.RLIM_INFINITY
        resource.setrlimit(resource.RLIMIT_RTTIME, (scheduling.soft_us, hard))
    if scheduling.nice:
        os.setpriority(os.PRIO_PROCESS, 0, scheduling.nice)
    if scheduling.priority:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(scheduling.priority))


@contextlib.contextmanager
def rttime_limit(scheduling: Scheduling) -> Iterator[None]:
    """This process, and the children it starts meanwhile, under the unit's soft
    RLIMIT_RTTIME (nothing if the unit sets none), the previous one afterwards. The soft limit
    is the one that ends a Python process (SIGXCPU); the hard one is left as it was, because a
    process cannot raise its own hard limit back without CAP_SYS_RESOURCE."""
    if scheduling.soft_us is None:
        yield
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_RTTIME)
    if hard != resource.RLIM_INFINITY and hard < scheduling.soft_us:
        raise ValueError(f"RLIMIT_RTTIME's hard limit {hard} us is below the unit's soft one")
    resource.setrlimit(resource.RLIMIT_RTTIME, (scheduling.soft_us, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_RTTIME, (soft, hard))
