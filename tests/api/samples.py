"""Typed replies for tests that need a whole ``status`` without a daemon: a fixed loop
snapshot and daemon object around a given state (docs/api.md "status")."""

from __future__ import annotations

from supervisord.api.replies import RequestId, StatusReply
from supervisord.api.status import (
    SINK_COUNTERS,
    DaemonStatus,
    EstopAvailable,
    LinkStatus,
    LoopStatus,
    StateReport,
)
from supervisord.vocabulary import State

LOOP = LoopStatus(
    pid=1234,
    version="0.0-test",
    uptime_s=1.5,
    link=LinkStatus(
        description="serial /dev/null",
        open=False,
        opens=0,
        open_failures=1,
        since_s=1.5,
        last_error="no such device",
        error_frames=None,
    ),
    outputs_not_acquired=(),
    outputs_off_delay_ms={},
    messages=0,
    rejections={},
    record_errors=0,
    records_dropped=0,
    sink=dict.fromkeys(SINK_COUNTERS, 0),
    rate_limited=0,
    internal_faults=0,
    histograms={},
)


STOPPED = StateReport(state=State.STOPPED, mono_ns=1, causes=(), outputs={}, heartbeat_estop=1)
"""A state with nothing to say but STOPPED."""


def status_reply(
    report: StateReport = STOPPED, request_id: RequestId = None, loop: LoopStatus = LOOP
) -> StatusReply:
    """A ``status`` reply of ``report`` from a daemon whose loop says ``loop`` and that has
    seen nothing else."""
    return StatusReply(
        id=request_id,
        report=report,
        estop_available=EstopAvailable(available=False, missing=("the VSC is not heard",)),
        daemon=DaemonStatus(
            robot="test", loop=loop, clients=(), connections=1, remote=None, in_state_s=1.5
        ),
    )
