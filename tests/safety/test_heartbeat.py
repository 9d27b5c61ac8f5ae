"""The user heartbeat to the VSC (SR-5): rate, e-stop byte, transports."""

from __future__ import annotations

import dataclasses

import pytest

from supervisord.protocol.messages import FeedbackGet, UserHeartbeat
from supervisord.safety import InternalFault, LinkBroken, State, Transport
from tests.safety.rig import LOCAL, ROBOT, Rig


def _tick_through(rig: Rig, ms: int) -> None:
    """Call the core at every deadline it asks for, for ``ms`` milliseconds, feeding healthy
    VSC and client heartbeats at the same time (as the daemon's loop would)."""
    end = rig.now + ms * 1_000_000
    while rig.last.next_deadline <= end:
        rig.now = rig.last.next_deadline
        rig.tick()


@pytest.mark.parametrize("hz", [20, 33, 50])
def test_heartbeat_goes_out_at_the_configured_rate(hz: int) -> None:
    """SR-5.1, PR-6.2: driven only by its own deadlines, the core asks for ``heartbeat_hz`` frames a
    second."""
    rig = Rig(dataclasses.replace(ROBOT, heartbeat_hz=hz))
    rig.open_link()
    before = len(rig.heartbeats())
    _tick_through(rig, 1000)
    assert len(rig.heartbeats()) - before == hz


def test_heartbeat_byte_follows_active_conditions_not_the_latch() -> None:
    """The e-stop byte is 1 while a client's e-stop is active and back to 0 once released,
    although the stop stays latched: the operator can then take over again."""
    rig = Rig()
    rig.bring_up()
    assert rig.last.heartbeat_estop == 0
    rig.advance(10)
    stopped = rig.estop()
    assert stopped.heartbeat_estop == 1
    assert stopped.frames[0] == UserHeartbeat(1)  # a new stop goes out at once
    rig.advance(10)
    released = rig.release()
    assert released.state is State.STOPPED
    assert released.heartbeat_estop == 0
    rig.advance(50)
    assert UserHeartbeat(0) in rig.tick().frames


def test_vsc_estop_does_not_set_the_heartbeat_byte() -> None:
    """A VSC e-stop is not echoed back: our byte would raise the VSC's user e-stop bits and
    hold the e-stop for ever."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.vsc(LOCAL, estop=0b1100_0011)
    assert decision.state is State.STOPPED
    assert decision.heartbeat_estop == 0
    assert UserHeartbeat(1) not in decision.frames


def test_internal_fault_reaches_the_vsc_once() -> None:
    """A momentary cause sends one heartbeat with the e-stop byte set, at once."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(InternalFault(rig.now, "overrun"))
    assert decision.frames[0] == UserHeartbeat(1)
    rig.advance(50)
    assert rig.tick().heartbeat_estop == 0


def test_link_loss_sets_the_heartbeat_byte() -> None:
    """Documented choice: ``vsc_link_lost`` sets the byte, so a half-broken link still asks the
    VSC to stop."""
    rig = Rig()
    rig.bring_up()
    rig.advance(200)
    decision = rig.tick()
    assert decision.heartbeat_estop == 1
    assert UserHeartbeat(1) in decision.frames


def test_no_frames_while_the_link_is_down() -> None:
    """With the link broken the core asks for no frames at all."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    rig.feed(LinkBroken(rig.now, "EIO"))
    count = len(rig.frames())
    _tick_through(rig, 2000)
    assert len(rig.frames()) == count


def test_can_has_no_user_heartbeat_and_no_key85() -> None:
    """SR-5.5, PR-3.3: on CAN the core never asks for a user heartbeat or a key 85 query (PR-3)."""
    rig = Rig(dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False))
    rig.open_link()
    rig.connect()
    rig.run_for(600, LOCAL)
    _tick_through(rig, 1000)
    assert not any(isinstance(f, UserHeartbeat | FeedbackGet) for f in rig.frames())
