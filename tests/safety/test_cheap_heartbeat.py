"""The cheap path also sends the user heartbeat when it is the only thing due (SR-9.4).

``tests/safety/test_cheap_path.py`` proves the cheap path equal to the full path over random
inputs, deadlines included; these tests pin down that the heartbeat tick really takes it, and
that it still declines when something else falls due at the same time.
"""

from __future__ import annotations

import dataclasses
import itertools

from supervisord.protocol.messages import FeedbackSet, UserHeartbeat
from supervisord.safety import DisplayUpdate, State
from supervisord.safety.decision import again
from tests.safety.rig import MS, Rig

HEARTBEAT_MS = 50  # ROBOT's heartbeat_hz 20 (SR-5.1)


def test_the_heartbeat_tick_in_run_sends_the_heartbeat_without_recomputing() -> None:
    """SR-5.1, SR-9.4: in RUN, the tick at the user heartbeat's time sends one heartbeat with
    byte 0, keeps the 50 ms cadence and recomputes no cause; state and outputs are unchanged."""
    rig = Rig()
    rig.bring_up()
    assert rig.state is State.RUN
    refreshes = rig.count_refreshes()
    sent: list[int] = []
    for _ in range(10):
        rig.beat()  # the required client stays alive (SR-2.4; a client's beat is a full step)
        rig.vsc()  # and so does the VSC (SR-2.2)
        rig.now = rig.last.next_deadline
        before = len(refreshes)
        decision = rig.tick()
        assert len(refreshes) == before  # the tick itself recomputed nothing
        if decision.frames:
            assert decision.frames == (UserHeartbeat(0),)
            sent.append(decision.now)
        assert decision.state is State.RUN
        assert decision.outputs == {"drive": True, "lights": True}
        assert not decision.records
    assert len(sent) >= 5
    assert all((b - a) % (HEARTBEAT_MS * MS) == 0 for a, b in itertools.pairwise(sent))


def test_the_heartbeat_tick_takes_the_full_path_when_a_timeout_expires_with_it() -> None:
    """SR-2.2, SR-5.2: when the VSC's 200 ms timeout expires at the very tick the user heartbeat
    is due, the cheap path declines: the full step raises ``vsc_link_lost`` and the heartbeat
    of that tick carries byte 1; every heartbeat tick before it was cheap."""
    rig = Rig()
    rig.bring_up()
    while not rig.last.frames:  # to a tick that sent a heartbeat: a heartbeat time
        rig.beat()
        rig.vsc()
        rig.now = rig.last.next_deadline
        rig.tick()
    last_vsc = rig.now
    rig.vsc()  # the VSC's last heartbeat, at a heartbeat time: its timeout falls on one too
    refreshes = rig.count_refreshes()
    while True:
        rig.beat()
        rig.now = rig.last.next_deadline
        before = len(refreshes)
        decision = rig.tick()
        if decision.state is not State.RUN:
            break
        assert len(refreshes) == before  # a cheap heartbeat tick
        assert decision.frames == (UserHeartbeat(0),)
    assert decision.now == last_vsc + 200 * MS
    assert refreshes[before:] == [decision.now, decision.now]  # this tick took the full step
    assert "vsc_link_lost" in decision.active_names
    assert decision.frames == (UserHeartbeat(1),)


def _to_a_heartbeat_time(rig: Rig) -> None:
    """Tick on until a tick sends the user heartbeat, everyone alive: ``rig.now`` is then one
    of the heartbeat's times (the cadence keeps them 50 ms apart)."""
    for _ in range(HEARTBEAT_MS):  # a heartbeat is due within 50 ms
        if rig.last.frames:
            return
        rig.beat()
        rig.vsc()
        rig.now = rig.last.next_deadline
        rig.tick()
    raise AssertionError("no user heartbeat within 50 ms")


def test_the_heartbeat_tick_takes_the_full_path_when_a_client_times_out_with_it() -> None:
    """SR-2.4, SR-5.2: when a required client's 500 ms timeout expires at the very tick the
    user heartbeat is due, the cheap path declines: the full step raises ``client_lost`` at
    that nanosecond, and the heartbeat of that tick carries byte 1."""
    rig = Rig()
    rig.bring_up()
    _to_a_heartbeat_time(rig)
    last_beat = rig.now
    rig.beat()  # the client's last heartbeat, at a heartbeat time: its timeout falls on one
    for _ in range(500 // HEARTBEAT_MS):  # heartbeat ticks up to the client's timeout
        rig.vsc()  # the VSC stays alive (SR-2.2)
        rig.now = rig.last.next_deadline
        decision = rig.tick()
        if decision.state is not State.RUN:
            break
    assert decision.now == last_beat + 500 * MS
    assert "client_lost:planner" in decision.active_names
    assert decision.frames == (UserHeartbeat(1),)


def test_the_heartbeat_tick_takes_the_full_path_when_a_display_frame_is_due_with_it() -> None:
    """PR-2, SR-9.4: a display value waiting for its 50 ms rate slot goes at the slot, also
    when the slot is the very tick the user heartbeat is due: the cheap path declines and the
    tick sends both."""
    rig = Rig()
    rig.bring_up()
    _to_a_heartbeat_time(rig)
    rig.beat()
    rig.vsc()
    first = rig.feed(DisplayUpdate(rig.now, FeedbackSet(1, 5)))  # goes at once: a slot starts
    assert FeedbackSet(1, 5) in first.frames
    waiting = rig.feed(DisplayUpdate(rig.now, FeedbackSet(2, 7)))  # waits for the next slot
    assert FeedbackSet(2, 7) not in waiting.frames
    assert waiting.next_deadline == rig.now + HEARTBEAT_MS * MS  # the slot and the heartbeat
    rig.now = waiting.next_deadline
    decision = rig.tick()
    assert set(decision.frames) == {UserHeartbeat(0), FeedbackSet(2, 7)}


def test_the_cheap_decision_is_the_previous_one_at_a_new_time() -> None:
    """SR-9.4: the cheap path's decision, set slot by slot (``again``), equals the one the
    frozen class builds from the previous decision with the new time, byte, deadline and
    frames and no records, refusals or re-arm: every field set, none left from before."""
    rig = Rig()
    rig.bring_up()
    previous = dataclasses.replace(
        rig.tick(),
        records=(object(),),  # type: ignore[arg-type]  # only compared, never read
        refusals=(object(),),  # type: ignore[arg-type]
        rearm=object(),  # type: ignore[arg-type]
    )
    later = again(previous, previous.now + 7, 1, previous.now + 9, (UserHeartbeat(1),))
    expected = dataclasses.replace(
        previous,
        now=previous.now + 7,
        heartbeat_estop=1,
        next_deadline=previous.now + 9,
        frames=(UserHeartbeat(1),),
        records=(),
        refusals=(),
        rearm=None,
    )
    assert later == expected  # a frozen dataclass compares every field
