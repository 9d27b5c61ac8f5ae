"""The simulator's chattering VSC (``flap_heartbeats``): each change of the flapping mode is a
heartbeat of its own, faster than any heartbeat schedule the manual allows (manual §8.3.6: 20 ms at
the fastest). The fault suite uses it against the takeover rule (docs/safety.md rule 4)."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import VscHeartbeat
from supervisord.sim.faults import FaultInjector, FaultPlan
from supervisord.sim.process import SimProcess
from tests.sim.test_process import Host

LOCAL, OPERATIONAL = VscMode.LOCAL.value, VscMode.OPERATIONAL.value


def test_a_flap_heartbeat_is_due_once_at_every_change() -> None:
    """``flap_due`` answers yes once per change of the flapping mode, ``next_deadline`` names
    the next change, and the heartbeat sent then carries the mode of its half period."""
    plan = FaultPlan(flap_mode=LOCAL, flap_period_s=0.01, flap_heartbeats=True)
    injector = FaultInjector(plan, 0)
    injector.set_plan(plan, 2.0)
    assert injector.next_deadline() == 2.0
    assert injector.flap_due(2.0)
    assert not injector.flap_due(2.005)  # still the same half period
    assert injector.next_deadline() == pytest.approx(2.01)
    modes = []
    for step in range(1, 7):
        now = 2.0 + step * 0.01 + 0.001
        assert injector.flap_due(now)
        assert not injector.flap_due(now)
        beat = injector.message(VscHeartbeat(OPERATIONAL), now)
        assert isinstance(beat, VscHeartbeat)
        modes.append(beat.mode)
    assert modes == [LOCAL, OPERATIONAL] * 3


def test_without_flap_heartbeats_nothing_extra_is_due() -> None:
    """The plain flap (``flap_heartbeats`` false) only changes the scheduled heartbeats' mode,
    as before; a plan asking for flap heartbeats without a flap mode is refused."""
    injector = FaultInjector(FaultPlan(flap_mode=LOCAL, flap_period_s=0.01), 0)
    assert not injector.flap_due(0.0)
    assert injector.next_deadline() is None
    with pytest.raises(ValueError, match="flap_heartbeats needs flap_mode"):
        FaultPlan(flap_heartbeats=True)
    with pytest.raises(ValueError, match="flap_heartbeats must be true or false"):
        FaultPlan.from_json({"flap_mode": 4, "flap_heartbeats": 1})


def test_srcs_sim_chatters_every_10_ms(tmp_path: Path) -> None:
    """The real ``srcs-sim`` with a chattering VSC's fault (Local/Operational every 10 ms, a
    heartbeat at each change) sends far more heartbeats than its 20 Hz schedule, alternating
    Local and Operational; clearing the plan ends it."""
    with SimProcess(tmp_path) as sim:
        assert sim.serial_path is not None
        sim.control.wait_for(lambda s: s["linked"])
        sim.control.takeover()
        host = Host(sim.serial_path)
        try:
            host.read(0.2)
            sim.control.fault(flap_mode=LOCAL, flap_period_s=0.01, flap_heartbeats=True)
            host.read(0.1)
            beats = [e for e in host.read(1.0) if isinstance(e, VscHeartbeat)]
            assert len(beats) >= 40, len(beats)  # about 100 a second; 20 is the schedule
            changes = sum(a.mode != b.mode for a, b in itertools.pairwise(beats))
            assert changes >= 30, [b.mode for b in beats]
            assert {b.mode for b in beats} == {LOCAL, OPERATIONAL}
            sim.control.fault()
            host.read(0.2)
            calm = [e for e in host.read(1.0) if isinstance(e, VscHeartbeat)]
            assert 10 <= len(calm) <= 26
            assert {b.mode for b in calm} == {OPERATIONAL}
        finally:
            host.close()
