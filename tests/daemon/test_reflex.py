"""The loop's reflex (SR-9.5) with real parts: a pseudo-terminal VSC, sim outputs mirrored to
files, the stop record; the loop's clock moved by the test (``tests/daemon/test_loop.py``)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from supervisord.daemon import lifecycle
from supervisord.daemon.loop import Supervisor
from supervisord.outputs.sim import SimOutput
from supervisord.protocol.codes import VscMode
from supervisord.safety.transitions import State
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import _arm, active, level, rig, run_until, state

__all__ = ["rig"]  # the fixture, shared with test_loop.py


def _estop(supervisor: Supervisor, peer: VscPeer) -> None:
    peer.mode, peer.estop = VscMode.LOCAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)


def test_a_stop_by_the_reflex_is_timed_and_read_back_as_the_full_steps(
    rig: tuple[Supervisor, VscPeer, Path],
) -> None:
    """SR-9.5, SR-12.1, SR-6: a remote e-stop in RUN, its outputs written off by the reflex,
    is timed for the field stop test for every output that was on, counted once in the
    stop-to-off histogram, and its read-backs reach the core: a power output stuck on is
    ``output_fault`` although the full step never writes it again."""
    supervisor, peer, tmp = rig
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    lamp = supervisor.outputs["lamp"]
    assert isinstance(lamp, SimOutput)
    lamp.stick(True)  # a welded relay: the off write reads back on
    observed = supervisor.timings.stop_to_off.count
    _estop(supervisor, peer)
    assert level(tmp, "drive") == "0"
    assert "output_fault:lamp" in active(supervisor)
    assert supervisor.timings.stop_to_off.count == observed + 1
    stop = supervisor.bank.stop_times._open
    assert stop is not None
    assert set(stop.off_ns) == {"drive", "lamp"}  # both were on when the stop began
    assert stop.off_ns["drive"] is not None  # its verified off write, timed
    assert stop.faulted == {"lamp"}  # its read-back did not match: never timed


def test_a_failing_reflex_leaves_the_stop_to_the_full_step(
    rig: tuple[Supervisor, VscPeer, Path],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-9.5, SR-8.7: a reflex that raises is logged and changes nothing else: the full step
    stops the robot, every output off, no internal fault and no output fault."""
    supervisor, peer, tmp = rig
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    assert supervisor.core is not None

    def broken() -> None:
        raise RuntimeError("a reflex that fails")

    monkeypatch.setattr(supervisor.core, "reflex", broken)
    with caplog.at_level(logging.ERROR, logger="srcsd"):
        _estop(supervisor, peer)
    assert (level(tmp, "drive"), level(tmp, "lamp")) == ("0", "0")
    assert "vsc_estop" in active(supervisor)
    assert not any(name.startswith("output_fault") for name in active(supervisor))
    assert supervisor.counters.internal_faults == 0
    assert "the reflex failed" in caplog.text
