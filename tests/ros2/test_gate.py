"""The velocity gate with a fake clock (docs/ros2.md "cmd_vel"): time is an argument."""

from __future__ import annotations

import pytest

from supervisord.ros2.gate import VelocityGate, Verdict
from supervisord.vocabulary import State

MS = 1_000_000


def test_nothing_passes_before_run() -> None:
    """A new gate is closed: commands are dropped until the supervisor reports RUN."""
    gate = VelocityGate(200 * MS)
    assert gate.command(1000 * MS, 1000 * MS) is Verdict.NOT_RUN
    assert gate.state(State.HOLD) is False
    assert gate.command(1000 * MS, 1000 * MS) is Verdict.NOT_RUN
    assert gate.counts.not_run == 2


def test_fresh_commands_pass_in_run_and_old_ones_never() -> None:
    """In RUN a command at most max age old is forwarded; an older one, one stamped far in
    the future and one with a zero stamp are dropped."""
    gate = VelocityGate(200 * MS)
    assert gate.state(State.RUN) is False
    now = 10_000 * MS
    assert gate.command(now - 200 * MS, now) is Verdict.FORWARD
    assert gate.command(None, now) is Verdict.FORWARD
    assert gate.command(now - 201 * MS, now) is Verdict.TOO_OLD
    assert gate.command(now + 500 * MS, now) is Verdict.TOO_OLD
    assert gate.command(0, now) is Verdict.TOO_OLD
    assert (gate.counts.forwarded, gate.counts.too_old) == (2, 3)


def test_leaving_run_asks_for_one_zero_then_closes() -> None:
    """Leaving RUN asks for exactly one zero command; the same state again asks for none,
    and commands are dropped until RUN returns."""
    gate = VelocityGate(200 * MS)
    gate.state(State.RUN)
    assert gate.state(State.STOPPED) is True
    assert gate.state(State.STOPPED) is False
    assert gate.state(State.HOLD) is False
    assert gate.command(5 * MS, 5 * MS) is Verdict.NOT_RUN
    gate.state(State.RUN)
    assert gate.state(State.HOLD) is True
    assert gate.counts.zeros == 2


def test_max_age_must_be_positive() -> None:
    """A gate that would drop everything, or nothing, is a configuration error."""
    with pytest.raises(ValueError, match="positive"):
        VelocityGate(0)
