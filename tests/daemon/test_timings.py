"""The loop's own timing histograms (docs/fleet.md "Timing histograms"): the
histogram type, and the loop's observations on a clock the test drives, with a real
pseudo-terminal VSC peer and real sim outputs."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import cast

import pytest

from supervisord.api.views import histogram_status
from supervisord.daemon import lifecycle
from supervisord.daemon.loop import Supervisor
from supervisord.histogram import (
    HEARTBEAT_BOUNDS_NS,
    STOP_TO_OFF_BOUNDS_NS,
    Histogram,
)
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs.base import ReadBack
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.codes import VscMode
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import ManualClock, _arm, run_until, serve_for, state

MS = 1_000_000


def test_observe_counts_each_value_in_its_le_bucket() -> None:
    """A value equal to a bound counts in that bound's bucket, a larger one in the next; the
    counts are cumulative, the last finite bucket short of ``count`` by the +Inf ones, and
    the sum is in seconds."""
    histogram = Histogram((1 * MS, 10 * MS, 100 * MS))
    for value in (0, 1 * MS, 1 * MS + 1, 10 * MS, 250 * MS):
        histogram.observe(value)
    snapshot = histogram.snapshot()
    assert snapshot.le == (0.001, 0.01, 0.1)
    assert snapshot.counts == (2, 4, 4)
    assert snapshot.count == 5
    assert snapshot.sum == pytest.approx((12 * MS + 1 + 250 * MS) / 1e9)


def test_a_negative_duration_counts_as_zero() -> None:
    """A negative duration (impossible on the monotonic clock, SR-2.11) counts in the first
    bucket as 0 s, so the sum never goes down."""
    histogram = Histogram((1 * MS,))
    histogram.observe(-5)
    assert histogram.snapshot().counts == (1,)
    assert histogram.sum_ns == 0


def test_bounds_must_increase() -> None:
    """Bounds that do not increase, or are not positive, are refused when built."""
    for bounds in ((), (2 * MS, 1 * MS), (1 * MS, 1 * MS), (0, 1 * MS)):
        with pytest.raises(ValueError, match="bucket bounds"):
            Histogram(bounds)


def test_the_shipped_bounds_hold_the_targets_they_cite() -> None:
    """The heartbeat buckets have the nominal periods (SR-5) and the default timeouts as
    bounds; the stop-to-off buckets have the 2 ms target and run from 0.1 ms to past 100 ms."""
    assert {20 * MS, 50 * MS, 100 * MS, 200 * MS, 300 * MS} <= set(HEARTBEAT_BOUNDS_NS)
    assert STOP_TO_OFF_BOUNDS_NS[0] == 100_000
    assert 2 * MS in STOP_TO_OFF_BOUNDS_NS
    assert STOP_TO_OFF_BOUNDS_NS[-1] > 100 * MS


def test_the_wire_view_is_cumulative_with_count_as_inf() -> None:
    """``histogram_status`` carries ``le``, cumulative ``counts``, ``sum`` and ``count`` by name,
    as docs/api.md "status" says."""
    histogram = Histogram((1 * MS, 2 * MS))
    histogram.observe(1 * MS)
    histogram.observe(5 * MS)
    assert histogram_status(histogram).json() == {
        "le": [0.001, 0.002],
        "counts": [1, 1],
        "sum": 0.006,
        "count": 2,
    }


class _SlowOffOutput(SimOutput):
    """A sim output whose write of "off" takes ``off_ns`` of the daemon's (manual) clock."""

    def __init__(self, spec: SimSpec, clock: ManualClock, off_ns: int) -> None:
        super().__init__(spec)
        self.clock, self.off_ns = clock, off_ns

    def _write(self, on: bool, now: int) -> ReadBack:
        if not on:
            self.clock.advance(self.off_ns)
        return super()._write(on, now)


@pytest.fixture
def timed(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer, ManualClock]]:
    clock = ManualClock()
    port = PtyPort(tmp_path / "vsc")
    output = _SlowOffOutput(SimSpec(name="drive"), clock, 3 * MS)
    supervisor = Supervisor(
        SafetyConfig(rearm_hold_ms=100, outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(port.path)),
        [output],
        RecordWriter(tmp_path / "stops.jsonl"),
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
    )
    yield supervisor, VscPeer(port, clock=clock.seconds), clock
    lifecycle.shutdown(supervisor)
    port.close()


def _histogram(supervisor: Supervisor, name: str) -> dict[str, object]:
    return supervisor.snapshot(supervisor.clock()).histograms[name].json()


def _count_at(histogram: dict[str, object], le: float) -> int:
    bounds = cast(list[float], histogram["le"])
    return cast(list[int], histogram["counts"])[bounds.index(le)]


def test_status_carries_the_heartbeat_periods_the_loop_saw(
    timed: tuple[Supervisor, VscPeer, ManualClock],
) -> None:
    """Against a peer sending a VSC heartbeat every 50 ms, every VSC period the loop observed
    is 50 ms (within the test clock's 1 us rounding, so in the 55 ms bucket and past the
    45 ms one); the user heartbeat (20 Hz by default) is observed at 50 ms too (SR-5.1)."""
    supervisor, peer, _ = timed
    lifecycle.start(supervisor)
    serve_for(supervisor, peer, 1.0)
    vsc = _histogram(supervisor, "vsc_heartbeat_period_seconds")
    count = cast(int, vsc["count"])
    assert count >= 15
    assert _count_at(vsc, 0.045) == 0
    assert _count_at(vsc, 0.055) == count
    assert cast(float, vsc["sum"]) == pytest.approx(count * 0.05, rel=0.01)
    user = _histogram(supervisor, "user_heartbeat_period_seconds")
    assert cast(int, user["count"]) >= 15
    assert _count_at(user, 0.045) == 0
    assert _count_at(user, 0.055) == user["count"]


def test_heartbeats_read_together_are_one_period_never_a_zero(
    timed: tuple[Supervisor, VscPeer, ManualClock],
) -> None:
    """SR-2.2, docs/fleet.md "Timing histograms": the VSC period is measured between reads
    that brought heartbeats. A peer that sends its heartbeats two at a time, in one write,
    adds one 50 ms period per write: no period of 0, and the periods add up to the time
    between the first and the last read."""
    supervisor, peer, _ = timed
    lifecycle.start(supervisor)
    serve_for(supervisor, peer, 0.3)
    before = _histogram(supervisor, "vsc_heartbeat_period_seconds")
    first = supervisor.timings.last_vsc_heartbeat_ns
    peer.burst = 2
    serve_for(supervisor, peer, 0.5)
    after = _histogram(supervisor, "vsc_heartbeat_period_seconds")
    added = cast(int, after["count"]) - cast(int, before["count"])
    assert added >= 9  # one per write: 0.5 s of 50 ms writes
    assert _count_at(after, 0.045) == _count_at(before, 0.045) == 0
    assert _count_at(after, 0.055) - _count_at(before, 0.055) == added
    last = supervisor.timings.last_vsc_heartbeat_ns
    assert first is not None
    assert last is not None
    summed = cast(float, after["sum"]) - cast(float, before["sum"])
    assert summed == pytest.approx((last - first) / 1e9)


def test_a_remote_estop_is_one_stop_to_off_observation(
    timed: tuple[Supervisor, VscPeer, ManualClock],
) -> None:
    """A remote e-stop in RUN adds exactly one stop-to-off observation, from the frame's read
    stamp to the output write's return: here the write takes 3 ms of the loop's clock, so it
    lands in the 5 ms bucket and not the 2 ms one (SR-6: measured after the write)."""
    supervisor, peer, _ = timed
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    before = _histogram(supervisor, "stop_to_off_seconds")
    peer.mode, peer.estop = VscMode.LOCAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    serve_for(supervisor, peer, 0.2)
    after = _histogram(supervisor, "stop_to_off_seconds")
    assert cast(int, after["count"]) == cast(int, before["count"]) + 1
    assert _count_at(after, 0.002) == _count_at(before, 0.002)
    assert _count_at(after, 0.005) == _count_at(before, 0.005) + 1
    added = cast(float, after["sum"]) - cast(float, before["sum"])
    assert added == pytest.approx(0.003)


def test_a_link_timeout_stop_counts_from_the_deadline(
    timed: tuple[Supervisor, VscPeer, ManualClock],
) -> None:
    """A stop at the VSC link timeout (SR-2.2) is measured from the deadline, so the loop's
    wake-up counts: the 3 ms write gives one observation of at least 3 ms."""
    supervisor, peer, _ = timed
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    before = _histogram(supervisor, "stop_to_off_seconds")
    peer.silent = True
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    after = _histogram(supervisor, "stop_to_off_seconds")
    assert cast(int, after["count"]) == cast(int, before["count"]) + 1
    added = cast(float, after["sum"]) - cast(float, before["sum"])
    assert 0.003 <= added < 0.01
