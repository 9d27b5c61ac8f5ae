"""The fake monotonic clock the kit ships to integrators (``supervisord.testkit.clock``):
it moves only when told, never backwards (SR-2.11), and drives the pure parts' time and a
client's timing without sleeping."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from supervisord.links.base import Backoff
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.testkit.clock import START_NS, ClockWentBackwardsError, FakeClock
from supervisord.timebase import NS_PER_MS, NS_PER_S, next_due
from supervisord.vocabulary import CauseKind, State


def test_it_moves_only_when_told_and_by_what_it_is_told() -> None:
    clock = FakeClock()
    assert clock.now_ns == START_NS
    assert clock.now_ns == START_NS  # reading it moves nothing
    assert clock.advance(5) == START_NS + 5
    assert clock.advance(ms=2) == START_NS + 5 + 2 * NS_PER_MS
    assert clock.advance(s=0.5) == START_NS + 5 + 2 * NS_PER_MS + NS_PER_S // 2
    assert clock.advance() == clock.now_ns  # zero: two inputs at one instant
    assert clock.advance_to(clock.now_ns + 7) == clock.now_ns
    assert clock.monotonic() == clock.now_ns / NS_PER_S
    assert clock() == clock.now_ns  # the clock a loop takes as a function


@pytest.mark.parametrize(
    "move",
    [
        lambda c: c.advance(-1),
        lambda c: c.advance(ms=-1),
        lambda c: c.advance(s=-0.001),
        lambda c: c.advance_to(c.now_ns - 1),
        lambda c: c.sleep(-1.0),
    ],
    ids=["ns", "ms", "s", "to", "sleep"],
)
def test_it_refuses_to_run_backwards_and_moves_nothing(move: Callable[[FakeClock], object]) -> None:
    """SR-2.11: a monotonic clock never goes back; asked to, the clock raises its typed error
    and stays where it was."""
    clock = FakeClock()
    clock.advance(ms=10)
    before = clock.now_ns
    with pytest.raises(ClockWentBackwardsError) as refused:
        move(clock)
    assert refused.value.now_ns == before
    assert refused.value.asked_ns < before
    assert clock.now_ns == before


def test_a_negative_start_is_refused() -> None:
    with pytest.raises(ClockWentBackwardsError):
        FakeClock(-1)


def _pace(monotonic: Callable[[], float], sleep: Callable[[float], None], seconds: float) -> int:
    """An integrator's client loop as it would be written against ``time``: a 10 Hz beat
    for ``seconds``, on the one rule for periodic duties; the number of beats sent."""
    period = NS_PER_S // 10
    start = round(monotonic() * NS_PER_S)
    due, beats = start, 0
    while due < start + round(seconds * NS_PER_S):
        now = round(monotonic() * NS_PER_S)
        if now >= due:
            beats += 1
            due = next_due(due, now, period)
        sleep(max(0, due - now) / NS_PER_S)
    return beats


def test_it_drives_a_clients_timing_without_sleeping() -> None:
    """A minute of a 10 Hz client beat runs in fake time: 600 beats, each on its period."""
    clock = FakeClock()
    assert _pace(clock.monotonic, clock.sleep, 60.0) == 600
    assert clock.now_ns == START_NS + 60 * NS_PER_S


def test_it_drives_the_pure_core_to_its_deadlines() -> None:
    """The safety core asked to tick at each deadline it names: the deadline is always
    ahead (Decision's promise), time passes without sleeping, and a robot with no VSC link
    stays STOPPED with the link's causes active (SR-1, SR-2)."""
    clock = FakeClock()
    core = SafetyCore(SafetyConfig(), clock.now_ns)
    decision = core.decision
    for _ in range(20):
        assert decision.next_deadline > clock.now_ns
        decision = core.tick(clock.advance_to(decision.next_deadline))
    assert clock.now_ns > START_NS + 10 * NS_PER_S
    assert decision.state is State.STOPPED
    kinds = {state.cause.kind for state in decision.causes}
    assert CauseKind.VSC_LINK_LOST in kinds
    assert not any(decision.outputs.values())
    with pytest.raises(ClockWentBackwardsError):
        clock.advance_to(decision.now - 1)  # a tick at a time already passed


def test_it_drives_the_links_backoff() -> None:
    """The links' reopen backoff (pure, time passed in) doubles to its cap on fake time."""
    clock = FakeClock()
    backoff = Backoff(first_ms=100, max_ms=400)
    delays = []
    for _ in range(4):
        backoff.failed(clock.now_ns)
        delays.append((backoff.next_attempt - clock.now_ns) // NS_PER_MS)
        clock.advance_to(backoff.next_attempt)
    assert delays == [100, 200, 400, 400]
