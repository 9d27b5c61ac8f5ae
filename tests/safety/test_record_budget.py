"""The client-record rule (SR-8.5; docs/safety.md "How many records one client may cause"): a client
causes at most ``RECORDS_PER_CLIENT`` records in any ``BUDGET_WINDOW_NS``; past it, the
requests that take a reason to stop away (releases, resets) are refused with
``RATE_LIMITED`` and make no record, while e-stops, holds and heartbeats always count."""

from __future__ import annotations

from supervisord.safety import Request, State
from supervisord.safety.budget import BUDGET_WINDOW_NS, RECORDS_PER_CLIENT
from supervisord.safety.decision import RefusalReason
from tests.safety.rig import MS, NOBODY, OPERATIONAL, Rig


def _records(rig: Rig, since: int) -> int:
    return sum(len(d.records) for d in rig.decisions[since:])


def _limited(rig: Rig, since: int) -> int:
    return sum(
        r.reason is RefusalReason.RATE_LIMITED for d in rig.decisions[since:] for r in d.refusals
    )


def test_a_hold_release_flood_makes_a_bounded_number_of_records() -> None:
    """A named client pipelining 1000 hold/release pairs within 100 ms causes at most
    ``RECORDS_PER_CLIENT`` records; the releases past that are refused as ``RATE_LIMITED``,
    so the client stays on hold (motion off) and its further holds change nothing."""
    rig = Rig()
    rig.bring_up()
    start = len(rig.decisions)
    for _ in range(1000):
        rig.advance(0.05)
        rig.hold()
        rig.release(request=Request.HOLD)
    assert _records(rig, start) <= RECORDS_PER_CLIENT
    assert _limited(rig, start) >= 1000 - RECORDS_PER_CLIENT
    assert rig.state is State.HOLD
    assert rig.last.outputs["drive"] is False


def test_the_budget_comes_back_after_the_window() -> None:
    """Once the window has passed without records from it, the client's release is
    honoured again (a client is slowed, never locked out)."""
    rig = Rig()
    rig.bring_up()
    for _ in range(RECORDS_PER_CLIENT):
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
    for _ in range(RECORDS_PER_CLIENT):
        rig.hold()
        rig.release(request=Request.HOLD)
    stop = rig.estop()
    assert stop.state is State.STOPPED
    assert stop.records
    beat = rig.beat()
    assert not [r for r in beat.refusals if r.reason is RefusalReason.RATE_LIMITED]


def test_the_budget_is_per_client() -> None:
    """One client past its budget does not limit another: a second client's hold and
    release are honoured and recorded."""
    rig = Rig()
    rig.bring_up()
    rig.connect(2, "arm")
    for _ in range(RECORDS_PER_CLIENT + 5):
        rig.hold()
        rig.release(request=Request.HOLD)
    rig.hold(2)
    released = rig.release(2, Request.HOLD)
    assert not released.refusals
    assert released.records


def test_a_reset_flood_makes_a_bounded_number_of_records() -> None:
    """A non-admin caller flooding ``reset`` (each refusal would be a ``rearm_refused``
    record) causes at most ``RECORDS_PER_CLIENT`` records; the rest are refused as
    ``RATE_LIMITED`` without a record."""
    rig = Rig()
    rig.bring_up()
    rig.estop()
    start = len(rig.decisions)
    for _ in range(500):
        rig.advance(0.1)
        rig.reset(NOBODY)
    assert _records(rig, start) <= RECORDS_PER_CLIENT
    assert _limited(rig, start) >= 500 - RECORDS_PER_CLIENT
