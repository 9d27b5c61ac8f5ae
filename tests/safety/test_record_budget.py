"""The client-record rule (SR-8.5; docs/safety.md "How many records the clients may cause"): a
user causes at most ``RECORDS_PER_UID`` records in any ``BUDGET_WINDOW_NS``; past it, the
requests that take a reason to stop away (releases, resets) are refused with
``RATE_LIMITED`` and make no record, while e-stops, holds and heartbeats always count."""

from __future__ import annotations

from dataclasses import replace

import pytest

from supervisord.safety import (
    ClientHello,
    ClientSpec,
    Event,
    LocalEstop,
    Request,
    State,
    Transport,
)
from supervisord.safety.budget import (
    BUDGET_WINDOW_NS,
    RECORDS_OF_ALL_CLIENTS,
    RECORDS_PER_UID,
    RecordBudget,
    Uid,
)
from supervisord.safety.clients import Clients
from supervisord.safety.decision import RefusalReason
from tests.safety.rig import MS, NOBODY, OPERATIONAL, ROBOT, Rig


def _records(rig: Rig, since: int) -> int:
    return sum(len(d.records) for d in rig.decisions[since:])


def _limited(rig: Rig, since: int) -> int:
    return sum(
        r.reason is RefusalReason.RATE_LIMITED for d in rig.decisions[since:] for r in d.refusals
    )


def test_a_hold_release_flood_makes_a_bounded_number_of_records() -> None:
    """A named client pipelining 1000 hold/release pairs within 100 ms causes at most
    ``RECORDS_PER_UID`` records; the releases past that are refused as ``RATE_LIMITED``,
    so the client stays on hold (motion off) and its further holds change nothing."""
    rig = Rig()
    rig.bring_up()
    start = len(rig.decisions)
    for _ in range(1000):
        rig.advance(0.05)
        rig.hold()
        rig.release(request=Request.HOLD)
    assert _records(rig, start) <= RECORDS_PER_UID
    assert _limited(rig, start) >= 1000 - RECORDS_PER_UID
    assert rig.state is State.HOLD
    assert rig.last.outputs["drive"] is False


def test_the_budget_comes_back_after_the_window() -> None:
    """Once the window has passed without records from it, the client's release is
    honoured again (a client is slowed, never locked out)."""
    rig = Rig()
    rig.bring_up()
    for _ in range(RECORDS_PER_UID):
        rig.hold()
        rig.release(request=Request.HOLD)
    rig.hold()
    refused = rig.release(request=Request.HOLD)
    assert [r.reason for r in refused.refusals] == [RefusalReason.RATE_LIMITED]
    assert not refused.records
    rig.run_for(BUDGET_WINDOW_NS // MS, OPERATIONAL)  # the VSC and the client beat on
    released = rig.release(request=Request.HOLD)
    assert not released.refusals
    assert released.state is State.RUN


def test_estops_holds_and_heartbeats_are_never_limited() -> None:
    """Past its budget a client's e-stop still stops at once and is recorded (it only adds
    a reason to stop, SR-0); its heartbeats still count."""
    rig = Rig()
    rig.bring_up()
    for _ in range(RECORDS_PER_UID):
        rig.hold()
        rig.release(request=Request.HOLD)
    stop = rig.estop()
    assert stop.state is State.STOPPED
    assert stop.records
    beat = rig.beat()
    assert not [r for r in beat.refusals if r.reason is RefusalReason.RATE_LIMITED]


def test_the_budget_is_per_user() -> None:
    """SR-8.5: one user past its budget does not limit another: a client of a second uid has
    its hold and release honoured and recorded; a second connection of the first uid shares
    the first one's budget (a release refused as ``RATE_LIMITED``)."""
    rig = Rig()
    rig.bring_up()
    rig.connect(2, "arm", uid=1001)
    rig.connect(3, "lidar", uid=None)  # the same user as the planner (unknown: one budget)
    for _ in range(RECORDS_PER_UID + 5):
        rig.hold()
        rig.release(request=Request.HOLD)
    rig.hold(2)
    released = rig.release(2, Request.HOLD)
    assert not released.refusals
    assert released.records
    rig.hold(3)
    refused = rig.release(3, Request.HOLD)
    assert [r.reason for r in refused.refusals] == [RefusalReason.RATE_LIMITED]


def test_a_step_charges_only_its_own_user(monkeypatch: pytest.MonkeyPatch) -> None:
    """SR-8.5, SR-2.9: whom a step's records are charged to is the step's own business: a step
    that fails before it has learnt its user (the record of that failure) charges nobody, and
    never the user of the step before. So a user one record short of its budget still has
    that record after the failure."""
    rig = Rig()
    rig.bring_up()
    rig.connect(2, "arm", uid=1001)
    start = len(rig.decisions)
    for _ in range(RECORDS_PER_UID // 2 - 1):
        rig.advance(0.05)
        rig.hold(2)
        rig.advance(0.05)
        rig.release(2, Request.HOLD)
    rig.advance(0.05)
    rig.hold(2)
    assert _records(rig, start) == RECORDS_PER_UID - 1
    real = Clients.uid
    calls: list[int] = []

    def fails_once(clients: Clients, event: Event) -> Uid:
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("boom")
        return real(clients, event)

    monkeypatch.setattr(Clients, "uid", fails_once)
    rig.advance(0.05)
    failed = rig.release(2, Request.HOLD)
    assert "internal" in failed.latched_names
    assert failed.records
    rig.advance(0.05)
    released = rig.release(2, Request.HOLD)
    assert not released.refusals
    assert released.records


def test_a_release_before_hello_costs_one_record() -> None:
    """SR-8.5: a release made before hello costs its user one record, as any release does:
    ten e-stops and releases from a connection that never said hello are twenty records, all
    honoured; the next release is the one past the budget."""
    rig = Rig()
    rig.bring_up()
    rig.connect(7, name=None, uid=1001)
    start = len(rig.decisions)
    for _ in range(RECORDS_PER_UID // 2):
        rig.advance(0.05)
        rig.estop(7)
        rig.advance(0.05)
        released = rig.release(7)
        assert not released.refusals
        assert "client_estop:#uid1001" not in released.active_names
    assert _records(rig, start) == RECORDS_PER_UID
    rig.advance(0.05)
    rig.estop(7)
    rig.advance(0.05)
    refused = rig.release(7)
    assert [r.reason for r in refused.refusals] == [RefusalReason.RATE_LIMITED]


def test_a_reset_flood_makes_a_bounded_number_of_records() -> None:
    """A non-admin caller flooding ``reset`` (each refusal would be a ``rearm_refused``
    record) causes at most ``RECORDS_PER_UID`` records; the rest are refused as
    ``RATE_LIMITED`` without a record."""
    rig = Rig()
    rig.bring_up()
    rig.estop()
    start = len(rig.decisions)
    for _ in range(500):
        rig.advance(0.1)
        rig.reset(NOBODY)
    assert _records(rig, start) <= RECORDS_PER_UID
    assert _limited(rig, start) >= 500 - RECORDS_PER_UID


UID = 1000


def _cycle(rig: Rig, connection: int, uid: int | None = UID) -> None:
    """A process that connects, holds without a hello and disconnects."""
    rig.connect(connection, None, uid)
    rig.hold(connection)
    rig.disconnect(connection)


def _alive(rig: Rig, ms: int) -> None:
    """The VSC's heartbeat every 50 ms and the required client's beat: nothing but the
    flood changes."""
    if ms % 50 == 0:
        rig.vsc(OPERATIONAL)
    rig.beat()


def _worst_second(rig: Rig, since: int) -> int:
    """The most records in any window of ``BUDGET_WINDOW_NS`` from ``since`` on."""
    times = [d.now for d in rig.decisions[since:] for _ in d.records]
    return max(
        (sum(1 for u in times[i:] if u - t < BUDGET_WINDOW_NS) for i, t in enumerate(times)),
        default=0,
    )


def test_connections_that_hold_before_hello_and_disconnect_are_bounded_per_user() -> None:
    """SR-8.5: three processes of one user connecting, holding without a hello and
    disconnecting, each on a new connection, 3000 times a second for 3 s (which wrote 2,219
    records a second when every connection before hello was a new client and holds and
    disconnects were never limited): at most ``RECORDS_PER_UID`` + 1 records in any second
    (the one is a hold, never refused, raised after the last end the budget allowed), and the
    robot is held throughout once the budget is spent, the safe side."""
    rig = Rig()
    rig.bring_up()
    start = len(rig.decisions)
    connection = 100
    for ms in range(3000):
        rig.advance(1)
        _alive(rig, ms)
        for _ in range(3):
            connection += 1
            _cycle(rig, connection)
    assert _worst_second(rig, start) <= RECORDS_PER_UID + 1
    assert sum(d.state is State.RUN for d in rig.decisions[-100:]) == 0
    assert "client_hold:#uid1000" in rig.last.active_names


def test_a_deferred_end_comes_exactly_when_the_budget_allows() -> None:
    """SR-8.5: a hold before hello whose connection closed while its user was past the budget
    ends at the first input at or after the moment the budget has room again, not a
    nanosecond before."""
    rig = Rig()
    rig.bring_up()
    rig.advance(1)
    first, start = rig.now, len(rig.decisions)
    for i in range(RECORDS_PER_UID // 2):  # every cycle: a hold and its end, two records
        _cycle(rig, 10 + i)
    assert _records(rig, start) == RECORDS_PER_UID
    rig.advance(1)
    _cycle(rig, 99)  # the hold is raised (never refused); its end waits
    held = rig.last
    assert "client_hold:#uid1000" in held.active_names
    assert held.state is State.HOLD
    free = first + BUDGET_WINDOW_NS
    while rig.now + 50 * MS < free:  # the VSC and the client beat on, every input a chance
        rig.advance(50)
        _alive(rig, 0)
        assert rig.last.state is State.HOLD
    rig.now = free - 1
    assert rig.tick().state is State.HOLD
    rig.now = free
    ended = rig.tick()
    assert ended.state is State.RUN
    assert "client_hold:#uid1000" not in ended.active_names


def test_a_deferred_end_due_with_the_user_heartbeat_is_not_left_to_the_cheap_path() -> None:
    """SR-8.5, SR-9.4: a VSC heartbeat that comes late, after both the moment the budget has
    room again and the user heartbeat's time, ends the deferred hold (the full step): the
    cheap path, which answers an unchanged heartbeat when the user heartbeat is the only thing
    due, declines while an end waits."""
    rig = Rig()
    rig.bring_up()
    rig.advance(1)
    first = rig.now
    for i in range(RECORDS_PER_UID // 2):
        _cycle(rig, 10 + i)
    rig.advance(1)
    _cycle(rig, 99)  # the hold is raised; its end waits for the budget
    free = first + BUDGET_WINDOW_NS
    while rig.now + 50 * MS < free:
        rig.advance(50)
        _alive(rig, 0)
    assert rig.last.state is State.HOLD
    rig.now = free + 60 * MS  # the VSC heard 110 ms ago at most: not lost; a beat is due
    late = rig.vsc(OPERATIONAL)
    assert late.frames  # the user heartbeat was due
    assert late.state is State.RUN
    assert "client_hold:#uid1000" not in late.active_names


def test_deferred_ends_of_two_users_each_come_at_their_own_time() -> None:
    """SR-8.5, SR-2.11: with two users' ends deferred, the next deadline is the earlier end's
    (never a later one): a tick at it ends the first user's hold and leaves the second's."""
    rig = Rig(replace(ROBOT, transport=Transport.CAN, require_watchdog=False, clients=()))
    rig.bring_up()
    for i in range(RECORDS_PER_UID // 2 + 1):  # the last cycles' ends wait: deferred
        for uid, base in ((1000, 100), (1001, 200)):  # one user's cycle, then the other's
            rig.advance(0.05)
            _cycle(rig, base + i, uid)
    assert {"client_hold:#uid1000", "client_hold:#uid1001"} <= rig.last.active_names
    rig.advance(400)  # the VSC falls silent: only the deferred ends are due
    waiting = rig.tick()
    assert waiting.next_deadline < waiting.now + 1000 * MS
    rig.now = waiting.next_deadline
    first = rig.tick()
    assert "client_hold:#uid1000" not in first.active_names
    assert "client_hold:#uid1001" in first.active_names


def test_the_connections_of_one_user_share_one_hold_before_hello() -> None:
    """Choice 11, SR-8.5: holds before hello are filed under the user: two connections of
    uid 1000 holding raise one cause, ``client_hold:#uid1000``, which ends with the last of
    them (a release of one, then the other's disconnect); a connection whose uid is not known
    files under its number as before."""
    rig = Rig()
    rig.bring_up()
    rig.connect(5, None, UID)
    rig.connect(6, None, UID)
    rig.connect(7, None, None)
    rig.hold(5)
    second = rig.hold(6)
    assert not second.records  # the same cause, already active
    assert rig.hold(7).active_names >= {"client_hold:#uid1000", "client_hold:#7"}
    rig.disconnect(7)
    assert rig.release(5, Request.HOLD).state is State.HOLD
    other = rig.connect(8, None, UID)
    assert rig.release(8, Request.HOLD).refusals  # it asked for nothing
    ended = rig.disconnect(6)
    assert ended.state is State.RUN
    assert other.state is State.HOLD


def test_hellos_past_the_budget_are_refused_and_make_no_record() -> None:
    """SR-8.5, SR-8.6: a user flooding hellos under a name bound to another user (each
    refusal a ``hello_refused`` record) causes at most ``RECORDS_PER_UID`` records; past the
    budget every hello is refused as ``RATE_LIMITED`` without one."""
    rig = Rig(replace(ROBOT, clients=(ClientSpec("planner", uid=7),)))
    start = len(rig.decisions)
    for i in range(500):
        rig.advance(0.1)
        rig.connect(10 + i, None, UID)
        rig.feed(ClientHello(rig.now, 10 + i, "planner", replace(NOBODY, uid=UID)))
        rig.disconnect(10 + i)
    assert _records(rig, start) <= RECORDS_PER_UID
    assert _limited(rig, start) >= 500 - RECORDS_PER_UID


def test_local_estops_from_many_processes_of_one_user_are_bounded() -> None:
    """SR-8.5: ``srcsctl estop`` from 500 processes of one user (each a new caller, which
    would rewrite the cause's caller and so make a record) stops at once and causes at most
    ``RECORDS_PER_UID`` + 1 records: past the budget the active e-stop keeps its caller."""
    rig = Rig()
    rig.bring_up()
    start = len(rig.decisions)
    for pid in range(500):
        rig.advance(0.1)
        rig.feed(LocalEstop(rig.now, replace(NOBODY, pid=1000 + pid)))
    assert rig.state is State.STOPPED
    assert _records(rig, start) <= RECORDS_PER_UID + 1


def test_all_users_together_are_bounded() -> None:
    """SR-8.5: 40 users (more than the 32 whose budgets fill the total) each cycling connect,
    hold and disconnect as fast as they can: at most ``RECORDS_OF_ALL_CLIENTS`` records in any
    second, plus one hold each user raises after the budget is spent, whatever the number of
    connections and users."""
    rig = Rig()
    rig.bring_up()
    start = len(rig.decisions)
    connection = 100
    for ms in range(200):
        rig.advance(1)
        _alive(rig, ms)
        for uid in range(2000, 2040):
            connection += 1
            _cycle(rig, connection, uid)
    assert _worst_second(rig, start) <= RECORDS_OF_ALL_CLIENTS + 40


def test_the_window_and_the_limits_are_exact() -> None:
    """SR-8.5: ``RECORDS_PER_UID`` records exhaust a user's budget (``>=``), one fewer does
    not; a record exactly one window old no longer counts, so the budget is free again at
    ``first + BUDGET_WINDOW_NS`` and not a nanosecond before (``free_at``, the deadline the
    core asks for a deferred end); ``RECORDS_OF_ALL_CLIENTS`` from many users exhaust every
    user's."""
    budget = RecordBudget()
    t = 10 * BUDGET_WINDOW_NS
    for _ in range(RECORDS_PER_UID - 1):
        budget.charge(UID, t)
    assert not budget.exhausted(UID, t)
    assert budget.free_at(UID, t) is None
    budget.charge(UID, t)
    assert budget.exhausted(UID, t + BUDGET_WINDOW_NS - 1)
    assert budget.free_at(UID, t) == t + BUDGET_WINDOW_NS
    assert not budget.exhausted(UID, t + BUDGET_WINDOW_NS)
    assert not budget.exhausted(UID + 1, t)
    others = RecordBudget()
    for uid in range(RECORDS_OF_ALL_CLIENTS - 1):
        others.charge(uid, t)
    assert not others.exhausted(UID, t)
    others.charge(UID + 1, t)
    assert others.exhausted(UID, t)
    assert others.free_at(UID, t) == t + BUDGET_WINDOW_NS


def test_the_limits_are_the_requirements_numbers() -> None:
    """SR-8.5 states the numbers: 20 records of one user and 640 of all users in any second.
    Counted out here, not through the constants, so that neither can drift from the rule."""
    one = RecordBudget()
    for _ in range(19):
        one.charge(UID, 0)
    assert not one.exhausted(UID, 0)
    one.charge(UID, 0)
    assert one.exhausted(UID, 999_999_999)
    assert not one.exhausted(UID, 1_000_000_000)
    every = RecordBudget()
    for uid in range(639):
        every.charge(uid, 0)
    assert not every.exhausted(UID, 0)
    every.charge(639, 0)
    assert every.exhausted(UID, 0)


def test_memory_holds_the_4096_users_charged_last() -> None:
    """The budget's memory is bounded: it remembers the 4096 users charged last and forgets
    the least recently charged first (docs/safety.md "How many records the clients may
    cause": more cannot be in one window, since all share the 640). Counted out, not read from
    the constant."""
    budget = RecordBudget()
    second = BUDGET_WINDOW_NS
    for uid in range(4096):
        budget.charge(uid, uid * second)  # one a window: the total never runs out
    assert budget.tracked == 4096
    budget.charge(0, 4096 * second)  # charged again: now the most recent
    assert budget.tracked == 4096
    later = 4096 * second + 1
    budget.charge(4096, later)  # a new user: user 1, charged least recently, goes
    assert budget.tracked == 4096
    for _ in range(19):
        budget.charge(0, later)
    assert budget.exhausted(0, later)  # user 0 was kept, with its record of 1 ns before
