"""What a takeover must show (SR-4.5, docs/safety.md "Re-arming" rule 4): the
VSC's non-Operational mode in an unbroken run of heartbeats spanning the takeover dwell, at a
rate the VSC can send. A real operator's takeover still re-arms; a flapping VSC never does."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from supervisord.safety import (
    LinkOpened,
    RearmKind,
    RecordNote,
    RefusalReason,
    SafetyConfig,
    State,
    Transport,
)
from supervisord.safety.vsc import TAKEOVER_DWELL_NS, VSC_MIN_INTERVAL_NS
from tests.safety.rig import LOCAL, MS, OPERATIONAL, PAUSE, ROBOT, Rig

DWELL_MS = TAKEOVER_DWELL_NS // MS
FASTEST_MS = VSC_MIN_INTERVAL_NS // MS


def _beat(rig: Rig, mode: int, beat_client: bool = True) -> None:
    rig.vsc(mode)
    if beat_client:
        rig.beat()


def _ever_left_stopped(rig: Rig, since: int) -> bool:
    return any(d.state is not State.STOPPED or d.rearm for d in rig.decisions[since:])


def test_a_vsc_flapping_every_10_ms_after_an_estop_never_rearms() -> None:
    """The defect rule 4 closes: after an e-stop has cleared, a VSC whose mode alternates
    Local/Operational every 10 ms (a heartbeat at each change) re-armed the robot by itself.
    For three seconds, long past the re-arm hold, it never leaves STOPPED."""
    rig = Rig()
    rig.stopped_and_cleared()
    since = len(rig.decisions)
    for i in range(300):
        rig.advance(10)
        _beat(rig, LOCAL if i % 2 == 0 else OPERATIONAL, beat_client=i % 5 == 0)
    assert not _ever_left_stopped(rig, since)
    reasons = {r.reason for d in rig.decisions[since:] for r in d.refusals}
    assert RefusalReason.TAKEOVER_TOO_SHORT in reasons


def test_one_non_operational_heartbeat_in_an_operational_stream_is_no_takeover() -> None:
    """A single heartbeat that says Local in a stream of Operational ones (a glitch) is no
    takeover, whatever its spacing: the non-Operational mode must be seen twice."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    rig.advance(50)
    _beat(rig, LOCAL)
    rig.advance(150)  # within the 200 ms link timeout, so no new stop
    refused = rig.vsc(OPERATIONAL)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
    assert "1 heartbeat" in refused.refusals[0].detail


def test_takeover_needs_the_dwell_exactly() -> None:
    """The first and last non-Operational heartbeats must be at least the dwell (200 ms)
    apart: 199 ms is refused, 200 ms re-arms (boundaries inclusive, docs/safety.md choice 1)."""
    for span_ms, runs in ((DWELL_MS - 1, False), (DWELL_MS, True)):
        rig = Rig()
        rig.stopped_and_cleared()
        rig.run_for(1000, OPERATIONAL)
        rig.advance(50)
        _beat(rig, PAUSE)
        rig.advance(span_ms - 100)
        _beat(rig, PAUSE)
        rig.advance(100)
        _beat(rig, PAUSE)
        rig.advance(50)
        decision = rig.vsc(OPERATIONAL)
        assert (decision.state is State.RUN) is runs, (span_ms, decision.refusals)
        if runs:
            assert decision.rearm is not None
            assert decision.rearm.kind is RearmKind.TAKEOVER
        else:
            assert [r.reason for r in decision.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]


def test_a_late_read_cannot_stretch_a_run_into_a_takeover() -> None:
    """SR-4.5: with a 300 ms link timeout (CAN's default), a starved loop reads a Local
    heartbeat 250 ms after the one before, though the VSC sent it 100 ms later and went
    Operational 100 ms after that (read in the same late turn): a span of 250 ms in two
    heartbeats is refused, since a VSC at its slowest rate (10 Hz) sends three in the dwell.
    Three heartbeats over the same span re-arm."""
    config = dataclasses.replace(ROBOT, vsc_timeout_ms=300)
    for local_beats, runs in ((2, False), (3, True)):
        rig = Rig(config)
        rig.stopped_and_cleared()
        rig.run_for(1000, OPERATIONAL)
        rig.advance(50)
        _beat(rig, LOCAL)
        rig.advance(150)
        for _ in range(local_beats - 2):
            _beat(rig, LOCAL)
        rig.advance(100)
        _beat(rig, LOCAL)  # read with the Operational one, in one late turn
        decision = rig.vsc(OPERATIONAL)
        assert (decision.state is State.RUN) is runs, (local_beats, decision.refusals)
        if not runs:
            assert [r.reason for r in decision.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
            assert "2 heartbeats" in decision.refusals[0].detail


def test_heartbeats_faster_than_the_vsc_can_send_are_no_takeover() -> None:
    """A run of Local heartbeats every 5 ms (four times the fastest rate the manual lets a
    VSC be set to, one per 20 ms) spanning well over the dwell is refused as too fast."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    for i in range(100):
        rig.advance(5)
        _beat(rig, LOCAL, beat_client=i % 20 == 0)
    rig.advance(5)
    refused = rig.vsc(OPERATIONAL)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.VSC_TOO_FAST]


@pytest.mark.parametrize(("beats", "rearmed"), [(13, True), (14, False)])
def test_the_rate_allows_two_heartbeats_read_together_and_no_more(
    beats: int, rearmed: bool
) -> None:
    """SR-4.5, docs/safety.md rule 4: over 220 ms from the run's first heartbeat, the run and
    the Operational heartbeat may hold 220 // 20 + 1 = 12 heartbeats at the VSC's fastest rate,
    plus 2 read together: 14 re-arm, 15 are refused as too fast."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    rig.advance(50)
    first = rig.now
    _beat(rig, LOCAL)
    for _ in range(beats - 2):  # 10 ms apart: faster than a VSC, within the allowance or not
        rig.advance(10)
        _beat(rig, LOCAL)
    rig.now = first + DWELL_MS * MS
    _beat(rig, LOCAL)  # the run spans the dwell exactly
    rig.now = first + (DWELL_MS + FASTEST_MS) * MS
    decision = rig.vsc(OPERATIONAL)
    if rearmed:
        assert decision.state is State.RUN, decision.refusals
    else:
        assert decision.state is State.STOPPED
        assert [r.reason for r in decision.refusals] == [RefusalReason.VSC_TOO_FAST]


def test_heartbeats_read_together_still_make_a_takeover() -> None:
    """Frames that arrive in one read share one time: a 20 Hz VSC whose heartbeats are read
    two at a time (a busy loop) still re-arms by the operator's takeover."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    for _ in range(6):
        rig.advance(100)
        _beat(rig, PAUSE)
        _beat(rig, PAUSE)
    rig.advance(50)
    _beat(rig, PAUSE)
    decision = rig.vsc(OPERATIONAL)
    assert decision.state is State.RUN, decision.refusals


@pytest.mark.parametrize("gap_ms", [200, 300])
def test_a_silent_gap_starts_the_run_again(gap_ms: int) -> None:
    """Heartbeats ``vsc_timeout`` or more apart (200 ms to the nanosecond, as for
    ``vsc_link_lost``, SR-2.2) do not make one run: after a gap the dwell is counted again from
    the first heartbeat after it (fresh evidence after a lost link)."""
    config = dataclasses.replace(ROBOT, rearm_hold_ms=100)
    rig = Rig(config)
    rig.stopped_and_cleared()
    rig.run_for(1000, LOCAL)
    rig.advance(gap_ms - 50)  # the next VSC heartbeat comes 50 ms later: vsc_link_lost
    rig.beat()
    # conditions clear for 150 ms >= the 100 ms hold
    refused = rig.take_over(150)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
    assert rig.take_over(300).state is State.RUN


def test_a_reconnect_starts_the_run_again() -> None:
    """A VSC reconnect is a new start (SR-4.4): Local heartbeats from before it do not count
    towards the dwell of a takeover after it."""
    rig = Rig(dataclasses.replace(ROBOT, rearm_hold_ms=100))
    rig.bring_up()
    rig.run_for(1000, LOCAL)
    rig.feed(LinkOpened(rig.now))
    rig.key85(1)
    refused = rig.take_over(150)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]


def test_refusals_of_a_flapping_vsc_are_recorded_at_most_once_a_second() -> None:
    """A flapping VSC cannot fill the record with refused takeovers (its rotation would drop
    the stop they are about): the same refusal is reported at most once a second."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    since = len(rig.decisions)
    for i in range(500):  # five seconds of a 100 Hz flap: 250 takeovers too short
        rig.advance(10)
        _beat(rig, LOCAL if i % 2 == 0 else OPERATIONAL, beat_client=i % 5 == 0)
    refused = [
        r for d in rig.decisions[since:] for r in d.records if r.note is RecordNote.REARM_REFUSED
    ]
    assert [r.trigger.now - refused[0].trigger.now for r in refused] == [
        i * 1000 * MS for i in range(5)
    ]
    assert all(r.reason.startswith(RefusalReason.TAKEOVER_TOO_SHORT.value) for r in refused)
    assert not _ever_left_stopped(rig, since)


def test_a_different_refusal_is_reported_at_once() -> None:
    """Quieting a repeated refusal never hides a new reason: a takeover too short, then one
    refused for another reason right after, are both reported."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    rig.advance(50)
    _beat(rig, LOCAL)
    rig.advance(50)
    assert [r.reason for r in rig.vsc(OPERATIONAL).refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
    rig.advance(10)
    rig.estop()
    assert [r.reason for r in rig.take_over(300).refusals] == [RefusalReason.CONDITIONS_ACTIVE]


def _flap_feed(rig: Rig, runs: list[list[int]]) -> None:
    """Feed what a flapping VSC reports: runs of heartbeats, alternately Local and
    Operational, each heartbeat after its gap (ms). A Local run is cut short so that its first
    and last heartbeats are less than the dwell apart."""
    for index, gaps in enumerate(runs):
        mode = LOCAL if index % 2 == 0 else OPERATIONAL
        span = 0
        for position, gap in enumerate(gaps):
            if position > 0:
                span += gap
                if mode == LOCAL and span >= DWELL_MS:
                    break
            rig.advance(gap)
            _beat(rig, mode, beat_client=position % 3 == 0)


@settings(max_examples=60, deadline=None)
@given(
    config=st.sampled_from(
        [ROBOT, dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False)]
    ),
    runs=st.lists(st.lists(st.integers(1, 49), min_size=1, max_size=12), min_size=1, max_size=40),
)
def test_a_vsc_flapping_faster_than_the_dwell_never_rearms(
    config: SafetyConfig, runs: list[list[int]]
) -> None:
    """Whatever its pattern, a VSC that never reports a non-Operational mode in heartbeats
    spanning the dwell (heartbeats 1-49 ms apart) never ends STOPPED after a stop, however
    long the conditions have been clear."""
    rig = Rig(config)
    rig.stopped_and_cleared()
    rig.run_for(600, OPERATIONAL)
    since = len(rig.decisions)
    _flap_feed(rig, runs)
    assert not _ever_left_stopped(rig, since)


@settings(max_examples=60, deadline=None)
@given(
    transport=st.sampled_from([Transport.SERIAL, Transport.CAN]),
    period_ms=st.integers(FASTEST_MS, 100),
    extra_ms=st.integers(0, 3000),
    from_mode=st.sampled_from([LOCAL, PAUSE]),
    read_together=st.booleans(),
)
def test_an_operators_takeover_rearms(
    transport: Transport, period_ms: int, extra_ms: int, from_mode: int, read_together: bool
) -> None:
    """A VSC sending at any documented rate (one heartbeat per 20-100 ms), in Local or Pause
    for at least the dwell after the conditions cleared, then Operational: RUN at once,
    also when its heartbeats are read two at a time."""
    assume(not read_together or 2 * period_ms < 200)  # a pair late by a whole timeout is a stop
    config = ROBOT
    if transport is Transport.CAN:
        config = dataclasses.replace(ROBOT, transport=transport, require_watchdog=False)
    rig = Rig(config)
    rig.stopped_and_cleared()
    rig.run_for(600, from_mode)
    step = 2 * period_ms if read_together else period_ms
    elapsed = 0
    while elapsed < DWELL_MS + extra_ms:
        rig.advance(step)
        elapsed += step
        _beat(rig, from_mode)
        if read_together:
            _beat(rig, from_mode)
    rig.advance(period_ms)
    decision = rig.vsc(OPERATIONAL)
    assert decision.state is State.RUN, decision.refusals
    assert decision.rearm is not None
    assert decision.rearm.kind is RearmKind.TAKEOVER


def test_a_granted_takeover_ends_the_quiet_of_a_refusal() -> None:
    """docs/safety.md "Re-arming": the quiet of a repeated refusal lasts until a takeover is
    granted: after a re-arm and a new stop, the same refusal less than a second after the
    first is reported again (it is about the new stop)."""
    rig = Rig(dataclasses.replace(ROBOT, rearm_hold_ms=100))
    rig.stopped_and_cleared()
    first = rig.take_over(100)  # two Local heartbeats, 50 ms apart: too short
    assert [r.reason for r in first.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
    assert rig.take_over(250).state is State.RUN
    rig.advance(10)
    rig.estop()
    rig.advance(10)
    rig.release()
    again = rig.take_over(100)
    assert again.now - first.now < 1000 * MS
    assert [r.reason for r in again.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]


def test_a_stop_raised_by_the_runs_last_heartbeat_is_no_new_cause_during_it() -> None:
    """SR-4.2, SR-4.3 (docs/safety.md "Re-arming" rules 2 and 3): the run's heartbeats must
    come after the last stop began, and the heartbeat that began it (a Local one carrying an
    e-stop word) does: a takeover right after it is refused for the hold time alone (SR-4.1),
    not as a new cause during the re-arm."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(300, LOCAL)
    rig.advance(50)
    assert "vsc_estop" in rig.vsc(LOCAL, estop=0b11).active_names
    rig.beat()
    rig.advance(50)
    refused = rig.vsc(OPERATIONAL)
    assert [r.reason for r in refused.refusals] == [RefusalReason.HOLD_TIME_NOT_ELAPSED]


@pytest.mark.parametrize(("beats", "rearmed"), [(22, True), (23, False)])
def test_the_rate_is_the_manuals_fastest_heartbeat_of_20_ms(beats: int, rearmed: bool) -> None:
    """SR-4.5, docs/safety.md rule 4, the numbers pinned (manual §8.3.6: a VSC sends at most
    one heartbeat per 20 ms): over 380 ms from the run's first heartbeat, 380 // 20 + 1 = 20
    heartbeats plus 2 read together may come, the Operational one among them: 22 re-arm, 23
    are refused as too fast (at 19 ms, 23 would pass)."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, OPERATIONAL)
    rig.advance(50)
    first = rig.now
    _beat(rig, LOCAL)
    for _ in range(beats - 2):  # 10 ms apart, the run spans the 200 ms dwell
        rig.advance(10)
        _beat(rig, LOCAL)
    assert rig.now - first >= 200 * MS
    rig.now = first + 380 * MS
    decision = rig.vsc(OPERATIONAL)
    if rearmed:
        assert decision.state is State.RUN, decision.refusals
    else:
        assert decision.state is State.STOPPED
        assert [r.reason for r in decision.refusals] == [RefusalReason.VSC_TOO_FAST]
