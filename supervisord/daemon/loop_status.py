"""What ``status`` says about the daemon itself, assembled from the loop's parts' own status.

The listener asks the loop for a look (:class:`~supervisord.daemon.listener.Look`) when it
builds a ``status`` reply (docs/api.md "status"); the loop answers with :func:`loop_status`,
given its parts as arguments: each part says its own (the link port its link and counts, the
output bank what is not acquired, the record path its sink's counts, the schedule the periodic
tests), and this adds the process's (pid, version, uptime) and the loop's own counters. It
holds nothing and calls nothing back.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from supervisord import __version__
from supervisord.api.status import LoopStatus
from supervisord.api.views import histogram_status
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.maintenance import Schedule
from supervisord.daemon.output_bank import OutputBank
from supervisord.daemon.record_path import RecordPath
from supervisord.daemon.refusal_log import RefusalLog
from supervisord.daemon.timings import Timings
from supervisord.safety.config import SafetyConfig
from supervisord.timebase import seconds_since

__all__ = ["Counters", "loop_status"]


@dataclass
class Counters:
    """What the loop itself has seen, for ``srcsctl status`` (the link's counts are its
    port's, the records' its record path's, the refusals' the refusal log's)."""

    internal_faults: int = 0  # the loop failed and stopped with the ``internal`` cause (SR-2)
    started_ns: int | None = None  # when the loop started, for the uptime (``None``: not yet)


def loop_status(
    now: int,
    *,
    started_ns: int | None,
    safety: SafetyConfig,
    port: LinkPort,
    bank: OutputBank,
    records: RecordPath,
    refusals: RefusalLog,
    counters: Counters,
    timings: Timings,
    schedule: Schedule,
    memory_locked: bool | None,
) -> LoopStatus:
    """The daemon's own status at ``now`` (the loop's clock): its version and uptime since
    ``started_ns`` (``None``: not started), the link and the loop's counters."""
    return LoopStatus(
        pid=os.getpid(),
        version=__version__,
        uptime_s=seconds_since(now, started_ns),
        link=port.status(now),
        outputs_not_acquired=bank.not_acquired(),
        # SR-1.4: each category-1 output's delay after the motion outputs (docs/outputs.md
        # "Stop categories"); an output not named is category 0.
        outputs_off_delay_ms={o.name: o.off_delay_ms for o in safety.outputs if o.off_delay_ms},
        messages=port.messages,
        rejections=dict(sorted(port.rejections.items())),
        record_errors=records.record_errors,
        records_dropped=records.records_dropped,
        # records_pending, journal_errors and _dropped, log_lines_dropped, record_reopens,
        # flight_windows, flight_errors (a snapshot's too) and flight_dropped
        sink=records.status(),
        rate_limited=refusals.count,  # SR-8.5
        internal_faults=counters.internal_faults,
        histograms={name: histogram_status(h) for name, h in timings.histograms().items()},
        # the periodic tests: each one's interval, last pass's age, overdue (SR-12.2)
        maintenance=schedule.status(now),
        memory_locked=memory_locked,  # SR-9.6
    )
