"""The daemon's own status (docs/api.md "status") assembled from real parts: a link port on a
memory link, an output bank with sim outputs (one not acquired), a record path, the refusal
log, the loop's counters, the timings and the schedule; each field read from its part."""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

from supervisord import __version__
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.loop_status import Counters, loop_status
from supervisord.daemon.maintenance import Schedule
from supervisord.daemon.output_bank import OutputBank
from supervisord.daemon.record_path import RecordPath
from supervisord.daemon.refusal_log import RefusalLog
from supervisord.daemon.stoptimes import StopTimes
from supervisord.daemon.timings import Timings
from supervisord.links.base import Backoff
from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.testkit.clock import FakeClock
from supervisord.timebase import NS_PER_MS

MS = NS_PER_MS
START = 1_000_000 * MS


def _wall() -> dt.datetime:
    return dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)


def test_each_field_of_the_status_is_its_parts_own(tmp_path: Path) -> None:
    """docs/api.md "status", SR-1.4, SR-8.5, SR-9.6: the uptime since the start, the link's
    status and counts from its port (the rejections by name, sorted), the outputs not acquired
    from the bank, only the category-1 outputs' delays, the record counts from the record
    path, the refusals from the refusal log and the internal faults from the loop's counters,
    each in its own field."""
    safety = SafetyConfig(
        outputs=(
            OutputSpec("drive", OutputRole.MOTION),
            OutputSpec("brakes", OutputRole.POWER, off_delay_ms=300),
        )
    )
    clock = FakeClock(START)
    port = LinkPort(MemoryLink(MemoryPort()), clock, Timings(), Backoff(100, 400))
    port.open(START)
    port.rejections.update({"wrong_length": 1, "bad_checksum": 2})  # as the port counts them
    drive = SimOutput(SimSpec(name="drive", path=tmp_path / "drive"))
    brakes = SimOutput(SimSpec(name="brakes", path=tmp_path / "missing" / "brakes"))
    bank = OutputBank([drive, brakes], clock, StopTimes())
    bank.open(START)  # ``brakes`` cannot be acquired: its folder is missing
    records = RecordPath(safety, RecordWriter(tmp_path / "stops.jsonl"), wall_clock=_wall)
    refusals, counters = RefusalLog(), Counters(internal_faults=2)
    for n in range(3):
        refusals.refused(START + n * MS)

    status = loop_status(
        START + 1_500 * MS,
        started_ns=START,
        safety=safety,
        port=port,
        bank=bank,
        records=records,
        refusals=refusals,
        counters=counters,
        timings=Timings(),
        schedule=Schedule({}),
        memory_locked=False,
    )

    assert (status.pid, status.version, status.uptime_s) == (os.getpid(), __version__, 1.5)
    assert (status.link.open, status.link.opens) == (True, 1)
    assert list(status.rejections.items()) == [("bad_checksum", 2), ("wrong_length", 1)]
    assert status.outputs_not_acquired == ("brakes",)
    assert status.outputs_off_delay_ms == {"brakes": 300}  # ``drive`` is category 0
    assert (status.record_errors, status.records_dropped) == (0, 0)
    assert status.sink == records.status()
    assert (status.rate_limited, status.internal_faults) == (3, 2)
    assert status.memory_locked is False
    assert set(status.histograms) == set(Timings().histograms())


def test_a_status_before_the_start_has_no_uptime(tmp_path: Path) -> None:
    """docs/api.md "status": no start, no uptime (``None``, not a count from zero)."""
    clock = FakeClock(START)
    status = loop_status(
        START,
        started_ns=None,
        safety=SafetyConfig(),
        port=LinkPort(MemoryLink(MemoryPort()), clock, Timings(), None),
        bank=OutputBank([], clock, StopTimes()),
        records=RecordPath(SafetyConfig(), None, wall_clock=_wall),
        refusals=RefusalLog(),
        counters=Counters(),
        timings=Timings(),
        schedule=Schedule({}),
        memory_locked=None,
    )
    assert status.uptime_s is None
    assert (status.rate_limited, status.internal_faults, status.memory_locked) == (0, 0, None)
