"""Key 85, the VSC's user watchdog (SR-5), and the transports without one."""

from __future__ import annotations

import dataclasses

from supervisord.protocol.messages import FeedbackGet
from supervisord.safety import LinkOpened, State, Transport
from tests.safety.rig import LOCAL, MS, ROBOT, Rig

QUERY = FeedbackGet(85)


def _queries(rig: Rig) -> list[int]:
    return [d.now for d in rig.decisions for f in d.frames if f == QUERY]


def test_key85_is_queried_at_link_open_and_every_second_until_answered() -> None:
    """The core reads key 85 at link open and again every second until it reads 1."""
    rig = Rig()
    opened = rig.open_link()
    assert QUERY in opened.frames
    for _ in range(25):
        rig.advance(100)
        rig.vsc(LOCAL)
    assert _queries(rig) == [opened.now + n * 1000 * MS for n in range(3)]
    rig.key85(1)
    rig.run_for(3000, LOCAL)
    assert len(_queries(rig)) == 3


def test_watchdog_off_until_key85_reads_1() -> None:
    """``vsc_watchdog_off`` is active with no answer, stays active on 0, and clears on 1."""
    rig = Rig()
    rig.open_link()
    state = rig.last.cause("vsc_watchdog_off")
    assert state is not None
    assert state.active
    assert state.detail("key85") == "no answer"
    zero = rig.key85(0).cause("vsc_watchdog_off")
    assert zero is not None
    assert zero.active
    assert zero.detail("key85") == "0"
    one = rig.key85(1).cause("vsc_watchdog_off")
    assert one is not None
    assert not one.active


def test_unanswered_key85_keeps_stopped() -> None:
    """SR-2.8, SR-5.3: without an answer about key 85 a takeover is refused and the state stays
    STOPPED."""
    rig = Rig()
    rig.open_link()
    rig.connect()
    decision = rig.take_over(2000)
    assert decision.state is State.STOPPED
    assert "vsc_watchdog_off" in decision.refusals[0].detail


def test_key85_is_read_again_after_a_reconnect() -> None:
    """SR-5.3, PR-6.6: a new link forgets the old answer: the watchdog cause is back and the query
    resumes."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(LinkOpened(rig.now))
    assert QUERY in decision.frames
    assert "vsc_watchdog_off" in decision.active_names


def test_watchdog_not_required_raises_no_cause() -> None:
    """With ``require_watchdog = false`` the core still reads key 85 but never stops for it."""
    rig = Rig(dataclasses.replace(ROBOT, require_watchdog=False))
    opened = rig.open_link()
    assert QUERY in opened.frames
    assert rig.key85(0).cause("vsc_watchdog_off") is None


def test_hid_never_leaves_stopped() -> None:
    """PR-4.1: HID is no safety channel: even with everything healthy and a takeover, STOPPED stays,
    with ``transport_fault`` naming the reason."""
    rig = Rig(dataclasses.replace(ROBOT, transport=Transport.HID))
    rig.open_link()
    rig.connect()
    decision = rig.take_over(1000)
    assert decision.state is State.STOPPED
    fault = decision.cause("transport_fault")
    assert fault is not None
    assert fault.active
    assert fault.detail("reason") == "hid is not a safety channel"
    assert not decision.frames
