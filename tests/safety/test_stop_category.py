"""Stop categories (SR-1.4): a ``power`` output with ``off_delay_ms`` stays on that long after
the ``motion`` outputs went off, then goes off, on the core's own clock and never later."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import HealthCheck, given, note, settings

from supervisord.errors import ConfigError
from supervisord.protocol.messages import Joystick
from supervisord.safety import (
    ClientSpec,
    Decision,
    OutputRole,
    OutputSpec,
    SafetyConfig,
    SafetyCore,
    State,
)
from tests.safety.rig import MS, PAUSE, Rig
from tests.safety.test_dispatch import _StrayTick
from tests.safety.test_properties import Maker, _bring_up, steps

BRAKES_MS, FANS_MS = 300, 800
CATEGORY_1 = SafetyConfig(
    clients=(ClientSpec("planner"),),
    outputs=(
        OutputSpec("drive", OutputRole.MOTION),
        OutputSpec("brakes", OutputRole.POWER, off_delay_ms=BRAKES_MS),
        OutputSpec("fans", OutputRole.POWER, off_delay_ms=FANS_MS),
        OutputSpec("lights", OutputRole.POWER),
    ),
)
"""A robot whose drives brake under power: two category-1 outputs and one of category 0."""


def _levels(decision: Decision) -> dict[str, bool]:
    return dict(decision.outputs)


def test_a_motion_output_with_a_delay_is_refused() -> None:
    """SR-1.4: the delay is for power outputs; the enable of the drives goes off at once."""
    with pytest.raises(ConfigError) as refused:
        OutputSpec("drive", OutputRole.MOTION, off_delay_ms=100)
    assert refused.value.key == "outputs.drive.off_delay_ms"
    assert 'role = "power"' in refused.value.fix


@pytest.mark.parametrize("delay", [-1, 5001, True, 1.5])
def test_a_delay_out_of_range_is_refused(delay: object) -> None:
    """SR-1.4: a whole number of milliseconds from 0 to 5000."""
    with pytest.raises(ConfigError) as refused:
        OutputSpec("brakes", OutputRole.POWER, off_delay_ms=delay)  # type: ignore[arg-type]
    assert refused.value.key == "outputs.brakes.off_delay_ms"


def _off_times(rig: Rig, until_ns: int) -> dict[str, int]:
    """Follow the decisions' deadlines with ticks alone (what the loop does when nothing
    arrives) until ``until_ns``: the time each output was first seen off."""
    seen = {name: rig.last.now for name, on in rig.last.outputs.items() if not on}
    while rig.last.now < until_ns:
        rig.now = rig.last.next_deadline
        for name, on in rig.tick().outputs.items():
            if not on:
                seen.setdefault(name, rig.now)
    return seen


def test_each_delayed_output_goes_off_at_its_delay_after_the_motion_outputs() -> None:
    """SR-1.4: on a stop from RUN the motion output and the category-0 power output go off in
    the stop's own step; each category-1 output stays on until exactly its delay later (on a
    nanosecond before, off at). Followed deadline by deadline, each goes off at exactly its
    time: the loop wakes for it, never later."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    assert set(_levels(rig.last).values()) == {True}
    rig.advance(10)
    stop = rig.estop()
    assert stop.state is State.STOPPED
    assert _levels(stop) == {"drive": False, "brakes": True, "fans": True, "lights": False}
    assert _off_times(rig, stop.now + 2 * FANS_MS * MS) == {
        "drive": stop.now,
        "lights": stop.now,
        "brakes": stop.now + BRAKES_MS * MS,
        "fans": stop.now + FANS_MS * MS,
    }
    assert not any(rig.last.outputs.values())  # and off for the rest of the stop

    edge = Rig(CATEGORY_1)
    edge.bring_up()
    stop = edge.estop()
    edge.now = stop.now + BRAKES_MS * MS - 1
    assert _levels(edge.tick())["brakes"] is True
    edge.now += 1
    assert _levels(edge.tick()) == {"drive": False, "brakes": False, "fans": True, "lights": False}


def test_the_delay_counts_from_the_motion_outputs_not_from_the_stop() -> None:
    """SR-1.4: RUN, a pause (HOLD: motion off, drives braking under power), then a stop 100 ms
    later: the category-1 output goes off its delay after the pause, not after the stop. A stop
    long after motion went off switches every output off at once."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(50)
    pause = rig.vsc(PAUSE)
    assert pause.state is State.HOLD
    rig.advance(100)
    rig.beat()
    stop = rig.estop()
    assert stop.state is State.STOPPED
    assert _levels(stop)["brakes"] is True
    assert _off_times(rig, pause.now + 2 * FANS_MS * MS)["brakes"] == pause.now + BRAKES_MS * MS

    late = Rig(CATEGORY_1)
    late.bring_up()
    late.advance(50)
    late.vsc(PAUSE)
    late.run_for(FANS_MS, PAUSE)
    stop = late.estop()
    assert stop.state is State.STOPPED
    assert not any(stop.outputs.values())


def test_a_stop_begun_in_stopped_leaves_nothing_on() -> None:
    """SR-1.4, SR-1.3: from startup the category-1 outputs are off like every other, and a new
    cause while STOPPED switches nothing on."""
    rig = Rig(CATEGORY_1)
    assert not any(rig.last.outputs.values())
    rig.open_link()
    rig.key85(1)
    rig.connect()
    assert not any(rig.estop().outputs.values())


def test_a_failure_of_the_core_is_a_stop_of_category_0() -> None:
    """SR-1.4, SR-2.9: when the core itself fails it cannot be trusted to time a delay: every
    output goes off in that step, and stays off."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(_StrayTick(rig.now))
    assert decision.state is State.STOPPED
    assert not any(decision.outputs.values())
    rig.advance(10)
    assert not any(rig.tick().outputs.values())


def test_once_the_last_delay_is_over_the_stop_is_steady_again() -> None:
    """SR-1.4, SR-9.4: the braking ends at the longest delay, to the nanosecond: from the step
    at that instant the core no longer follows time for it, and an inert frame from the VSC
    takes the cheap path again (while braking, every input takes the full step)."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(10)
    stop = rig.estop()
    rig.now = stop.now + FANS_MS * MS - 1
    refreshes = rig.count_refreshes()
    rig.from_vsc(Joystick())
    assert refreshes  # braking: the full step
    rig.now += 1
    assert not any(rig.tick().outputs.values())
    rig.now += 1
    refreshes.clear()
    rig.from_vsc(Joystick())
    assert refreshes == []


def test_the_last_line_of_defence_while_braking_leaves_nothing_on(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-1.4, SR-2.9: while the category-1 outputs brake after a stop, a step whose fail-safe
    fails too (the core's last line of defence) switches every output off, and the braking is
    over: the steps after it, the core working again, leave every output off, not back on
    for what was left of the delay."""
    rig = Rig(CATEGORY_1)
    rig.bring_up()
    rig.advance(10)
    stop = rig.estop()
    assert _levels(stop)["brakes"] is True

    def broken(*args: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(SafetyCore, "_apply", broken)
    monkeypatch.setattr(SafetyCore, "_finish", broken)
    rig.advance(10)
    assert not any(rig.beat().outputs.values())
    monkeypatch.undo()
    for _ in range(3):
        rig.advance(10)
        assert not any(rig.beat().outputs.values())


def test_no_delay_is_category_0() -> None:
    """SR-1.4: without ``off_delay_ms`` every output goes off in the stop's step, as before."""
    config = dataclasses.replace(
        CATEGORY_1,
        outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lights", OutputRole.POWER)),
    )
    rig = Rig(config)
    rig.bring_up()
    rig.advance(10)
    assert not any(rig.estop().outputs.values())


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(plan=steps)
def test_random_inputs_never_keep_power_past_its_delay(
    plan: list[tuple[int | None, Maker]],
) -> None:
    """SR-1.1, SR-1.4: whatever arrives, in STOPPED a category-1 output is on only if it was on
    in the decision before and less than its delay has passed since the motion outputs went
    off, and the next deadline is never later than its off time; motion outputs are on only
    in RUN and category-0 power outputs only in HOLD and RUN."""
    now = 10_000 * MS
    core = SafetyCore(CATEGORY_1, now)
    now = _bring_up(core, now)
    delays = {o.name: o.off_delay_ns for o in CATEGORY_1.outputs}
    before = core.decision
    motion_off: int | None = None
    for step, make in plan:
        now = before.next_deadline if step is None else now + step * MS
        for event in make(now):
            now = max(now, event.now)
            after = core.handle(event)
            if before.state is State.RUN and after.state is not State.RUN:
                motion_off = after.now
            for spec in CATEGORY_1.outputs:
                on = after.outputs[spec.name]
                if spec.role is OutputRole.MOTION:
                    assert not on or after.state is State.RUN
                elif after.state is not State.STOPPED:
                    assert on
                elif on:
                    assert delays[spec.name], spec.name
                    assert before.outputs[spec.name], f"{spec.name} switched on in STOPPED"
                    assert motion_off is not None
                    assert after.now - motion_off < delays[spec.name]
                    assert after.next_deadline <= motion_off + delays[spec.name]
                    note("a category-1 output on in STOPPED")
            before = after
