"""Leaving the hold of the VSC's mode (SR-3.3; docs/safety.md "Leaving a hold of the VSC's
mode"): a flapping VSC cannot chatter the outputs or flood the record. The pure core, on a fake
clock: every time is exact, nothing sleeps."""

from __future__ import annotations

import itertools
from dataclasses import replace

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.safety import State
from supervisord.safety.decision import Decision
from supervisord.safety.vsc import SETTLE_DWELL_NS, TAKEOVER_DWELL_NS, TAKEOVER_MIN_HEARTBEATS

from .rig import LOCAL, MS, OPERATIONAL, PAUSE, ROBOT, Rig

FREE = replace(ROBOT, clients=())
"""No required client: a flap of seconds needs no client heartbeats to stay out of STOPPED."""
MENU = 0x0A
MAX_RUN_ENTRIES_PER_S = 5
"""SR-3.3: entries into RUN from a mode's hold are at least the 200 ms dwell apart."""
MAX_RECORDS_PER_S = 15
"""SR-3.3: per second at most 5 entries into RUN, 5 into HOLD and 5 renames of the hold."""


def _running() -> Rig:
    rig = Rig(FREE)
    rig.bring_up()
    assert rig.last.state is State.RUN
    return rig


def _drive_on_edges(decisions: list[Decision]) -> int:
    levels = [d.outputs["drive"] for d in decisions]
    return sum(1 for before, after in itertools.pairwise(levels) if after and not before)


def test_the_dwell_is_the_takeovers() -> None:
    """SR-3.3: the settling dwell and its heartbeat count are the takeover's (SR-4.5)."""
    assert SETTLE_DWELL_NS == TAKEOVER_DWELL_NS == 200 * MS
    assert TAKEOVER_MIN_HEARTBEATS == 3


def test_a_vsc_flapping_every_10_ms_in_run_holds_once_and_runs_after_the_dwell() -> None:
    """SR-3.3, SR-3.1: Operational and Local alternating every 10 ms for 5 s in RUN (which
    toggled the drive 243 times before this rule): the drive goes off at the first Local and
    stays off, power stays on, no record after the first; once the VSC stays Operational the
    robot runs again after exactly the dwell of Operational heartbeats."""
    rig = _running()
    start = len(rig.decisions)
    for i in range(501):  # from Local to Local
        rig.advance(10)
        rig.vsc(LOCAL if i % 2 == 0 else OPERATIONAL)
    flap = rig.decisions[start:]
    assert all(d.state is State.HOLD for d in flap)
    assert all(d.outputs == {"drive": False, "lights": True} for d in flap)
    assert _drive_on_edges(rig.decisions[start - 1 :]) == 0
    assert sum(len(d.records) for d in flap) == 1
    # Operational from now on, every 50 ms: RUN at the heartbeat 200 ms after the first one.
    rig.advance(50)
    first = rig.vsc(OPERATIONAL).now
    for _ in range(3):
        rig.advance(50)
        assert rig.vsc(OPERATIONAL).state is State.HOLD
    rig.advance(50)
    resumed = rig.vsc(OPERATIONAL)
    assert resumed.now - first == 200 * MS
    assert resumed.state is State.RUN
    assert resumed.outputs == {"drive": True, "lights": True}


@pytest.mark.parametrize(("last_ms", "state"), [(200, State.RUN), (199.999999, State.HOLD)])
def test_the_hold_settles_at_exactly_200_ms_of_operational(last_ms: float, state: State) -> None:
    """SR-3.3: after a glitch (one Local heartbeat), Operational heartbeats whose first and
    last are 200 ms apart end the hold; a nanosecond less does not (``>=``)."""
    rig = _running()
    rig.advance(50)
    assert rig.vsc(LOCAL).state is State.HOLD
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is State.HOLD  # a glitch is no operator's act
    rig.advance(100)
    assert rig.vsc(OPERATIONAL).state is State.HOLD
    rig.advance(last_ms - 100)
    assert rig.vsc(OPERATIONAL).state is state


def test_two_operational_heartbeats_200_ms_apart_do_not_settle_the_hold() -> None:
    """SR-3.3: the dwell needs 3 heartbeats, as a takeover does: a late read stretches a span,
    it cannot add heartbeats."""
    rig = _running()
    rig.advance(50)
    rig.vsc(LOCAL)
    rig.advance(50)
    rig.vsc(OPERATIONAL)
    rig.advance(150)  # within the 200 ms vsc_timeout: the run is unbroken
    assert rig.vsc(OPERATIONAL).state is State.HOLD  # 2 heartbeats, 150 ms
    rig.advance(60)
    assert rig.vsc(OPERATIONAL).state is State.RUN  # 3 heartbeats, 210 ms


SLOW = replace(FREE, vsc_timeout_ms=1000, rearm_hold_ms=100, local_reset=True)
"""A VSC with a long timeout: heartbeats 300 ms apart are an unbroken run (SR-2.2)."""


def test_two_heartbeats_spanning_the_dwell_do_not_settle_the_hold_however_far_apart() -> None:
    """SR-3.3: with a timeout long enough that two Operational heartbeats 300 ms apart are
    unbroken, they still do not end the hold: it takes three, however long the span."""
    rig = Rig(SLOW)
    rig.bring_up()
    rig.advance(50)
    rig.vsc(LOCAL)
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is State.HOLD  # a glitch is no operator's act
    rig.advance(300)
    assert rig.vsc(OPERATIONAL).state is State.HOLD  # 2 heartbeats, 300 ms
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is State.RUN  # 3 heartbeats, 350 ms


def test_after_a_silence_the_hold_counts_its_heartbeats_again() -> None:
    """SR-3.3, SR-2.2: a silence of ``vsc_timeout`` in the Operational run that may end a
    glitch's hold starts the run again at the first heartbeat after it, counted as one: after a
    local reset (SR-4) the hold stays until that run has three heartbeats spanning the dwell."""
    rig = Rig(SLOW)
    rig.bring_up()
    rig.advance(50)
    rig.vsc(LOCAL)
    rig.advance(50)
    rig.vsc(OPERATIONAL)
    rig.advance(1000)
    lost = rig.vsc(OPERATIONAL)  # a silence of the whole timeout: stopped
    assert lost.state is State.STOPPED
    assert "vsc_link_lost" in lost.latched_names
    rig.advance(300)
    rig.vsc(OPERATIONAL)  # 2 heartbeats since the silence, 300 ms
    assert rig.reset().state is State.HOLD
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is State.RUN  # 3 heartbeats, 350 ms


@pytest.mark.parametrize(("pause_ms", "state"), [(200, State.RUN), (150, State.HOLD)])
def test_the_operators_pause_resumes_at_once_and_a_short_one_waits(
    pause_ms: int, state: State
) -> None:
    """SR-3.3: a pause that is an operator's act (re-arm rule 4: 200 ms, 3 heartbeats) ends
    with the first Operational heartbeat, with no wait; a shorter one waits for the dwell."""
    rig = _running()
    rig.advance(50)
    rig.vsc(PAUSE)
    rig.run_for(pause_ms, PAUSE, clients=())
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is state


def test_a_vsc_flapping_between_two_holding_modes_renames_the_hold_at_most_every_200_ms() -> None:
    """SR-3.3: Local and Menu alternating every 10 ms keep the robot on HOLD, and the hold's
    name changes at most once per dwell (5 records a second, not 100)."""
    rig = _running()
    start = len(rig.decisions)
    for i in range(100):  # one second
        rig.advance(10)
        rig.vsc(LOCAL if i % 2 == 0 else MENU)
    flap = rig.decisions[start:]
    assert all(d.state is State.HOLD for d in flap)
    records = [r for d in flap for r in d.records]
    assert 1 <= len(records) <= 1 + 1000 // 200
    names = {c.cause.name for r in records for c in r.changes}
    assert names == {"vsc_mode:local", "vsc_mode:menu"}


def test_a_repeated_heartbeat_renames_the_hold_once_the_dwell_has_passed() -> None:
    """SR-3.3, SR-7.1: a hold named after Local for 200 ms takes the name of the mode the VSC
    has reported since (Pause) with the first heartbeat after the dwell, with its record, even
    when that heartbeat repeats the one before it (found by the exhaustive exploration: such a
    heartbeat took the cheap path, which left the stale name in the decision and delayed the
    record until another input took the full step)."""
    rig = Rig(FREE)
    rig.open_link()
    rig.key85(1)
    rig.vsc(LOCAL)  # the hold is named vsc_mode:local from here
    for mode in (OPERATIONAL, OPERATIONAL, PAUSE):
        rig.advance(50)
        rig.vsc(mode)
    assert "vsc_mode:local" in rig.last.active_names  # 150 ms: too soon to rename
    rig.advance(50)
    decision = rig.vsc(PAUSE)  # 200 ms, the same mode and word as the heartbeat before
    assert "vsc_mode:pause" in decision.active_names
    assert "vsc_mode:local" not in decision.active_names
    changes = {(c.cause.name, c.kind.value) for r in decision.records for c in r.changes}
    assert changes == {("vsc_mode:local", "cleared"), ("vsc_mode:pause", "raised")}


_MODES = st.sampled_from([OPERATIONAL, OPERATIONAL, LOCAL, PAUSE, MENU])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(1, 120), _MODES), min_size=1, max_size=300))
def test_any_mode_sequence_enters_run_at_most_every_200_ms(steps: list[tuple[int, int]]) -> None:
    """SR-3.3, SR-3.1: whatever modes a VSC reports at whatever intervals (up to 120 ms, inside
    the 200 ms timeout), the robot is never STOPPED (power stays on), and entries into RUN are
    at least 200 ms apart, so at most 5 drive-on edges and 15 records in any second."""
    rig = _running()
    start = len(rig.decisions)
    for gap_ms, mode in steps:
        rig.advance(gap_ms)
        rig.vsc(mode)
    decisions = rig.decisions[start - 1 :]
    assert all(d.state is not State.STOPPED for d in decisions)  # a flap stops nothing
    entries = [
        after.now
        for before, after in itertools.pairwise(decisions)
        if after.state is State.RUN and before.state is not State.RUN
    ]
    assert all(b - a >= 200 * MS for a, b in itertools.pairwise(entries)), entries
    times = [d.now for d in decisions[1:] for _ in d.records]
    for i, t in enumerate(times):
        window = [u for u in times[i:] if u - t < 1000 * MS]
        assert len(window) <= MAX_RECORDS_PER_S, window
        runs = [u for u in entries if t <= u < t + 1000 * MS]
        assert len(runs) <= MAX_RUN_ENTRIES_PER_S
