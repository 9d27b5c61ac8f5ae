"""The simulated VSC's key-85 watchdog behaviours for the proof test (SR-5.3;
docs/simulator.md ``watchdog``), on made-up monotonic times."""

from __future__ import annotations

import pytest

from supervisord.protocol.messages import UserHeartbeat
from supervisord.sim.faults import FaultPlan
from supervisord.sim.model import LINK_DELAY_S, EstopBit, SimRefused, VscModel

T0 = 1000.0
LINKED = T0 + LINK_DELAY_S
TIMEOUT = int(EstopBit.USER_TIMEOUT)


def watched(behaviour: str, late_s: float = 1.0) -> VscModel:
    """A linked VSC with key 85 on, fed a user heartbeat at ``LINKED``."""
    model = VscModel(T0)
    model.set_key(85, 1, T0)
    model.set_watchdog(behaviour, late_s, T0)
    model.handle(UserHeartbeat(0), LINKED)
    assert model.estop_word(LINKED) & TIMEOUT == 0
    return model


def test_healthy_trips_at_500_ms_and_clears_with_the_next_heartbeat() -> None:
    """Manual §8.3.5: the bit at 500 ms without a heartbeat; gone with the next one."""
    model = watched("healthy")
    assert model.estop_word(LINKED + 0.499) & TIMEOUT == 0
    assert model.estop_word(LINKED + 0.5) & TIMEOUT
    model.handle(UserHeartbeat(0), LINKED + 0.6)
    assert model.estop_word(LINKED + 0.6) & TIMEOUT == 0


def test_ignores_never_trips_and_late_trips_late() -> None:
    """The faults ``ignores`` (never) and ``late`` (at ``watchdog_late_s``)."""
    assert watched("ignores").estop_word(LINKED + 5.0) & TIMEOUT == 0
    late = watched("late", late_s=1.0)
    assert late.estop_word(LINKED + 0.9) & TIMEOUT == 0
    assert late.estop_word(LINKED + 1.0) & TIMEOUT


def test_held_keeps_the_bit_until_a_takeover_which_leaves_local() -> None:
    """``held``: the bit stays after heartbeats resume; the takeover gesture clears it and
    the remote stays in Local, so a second takeover enters Operational."""
    model = watched("held")
    model.estop_word(LINKED + 0.6)
    model.handle(UserHeartbeat(0), LINKED + 0.7)
    assert model.estop_word(LINKED + 0.8) & TIMEOUT
    model.takeover(LINKED + 0.8)
    assert model.estop_word(LINKED + 0.8) == 0
    assert model.mode(LINKED + 0.8) == model.idle_mode
    model.takeover(LINKED + 0.9)
    assert model.mode(LINKED + 0.9) != model.idle_mode


def test_never_clears_keeps_the_bit_and_refuses_the_takeover() -> None:
    """``never_clears``: the bit stays after heartbeats resume and a takeover is refused."""
    model = watched("never_clears")
    model.estop_word(LINKED + 0.6)
    model.handle(UserHeartbeat(0), LINKED + 0.7)
    with pytest.raises(SimRefused, match="e-stop active"):
        model.takeover(LINKED + 0.8)
    assert model.estop_word(LINKED + 5.0) & TIMEOUT


def test_the_fault_plan_checks_the_watchdog_fields() -> None:
    """An unknown behaviour or a late time out of range is refused with its name."""
    with pytest.raises(ValueError, match="watchdog must be one of"):
        FaultPlan(watchdog="sometimes")
    with pytest.raises(ValueError, match="watchdog_late_s"):
        FaultPlan(watchdog="late", watchdog_late_s=0.1)
    assert FaultPlan.from_json({"watchdog": "held"}).to_json() == {"watchdog": "held"}
