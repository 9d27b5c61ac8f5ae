"""Time is an argument (SR-2): integer monotonic nanoseconds, never read."""

from __future__ import annotations

import pytest

from supervisord.safety import State, Tick
from tests.safety.rig import LOCAL, MS, Rig


def test_time_going_back_is_treated_as_not_moving() -> None:
    """SR-2.11, PR-6.3: an input stamped earlier than the latest ``now`` is handled at the latest
    ``now``: an expired timeout stays expired and the deadline is not moved into the past."""
    rig = Rig()
    rig.bring_up()
    rig.advance(250)
    lost = rig.tick()
    assert lost.state is State.STOPPED
    back = rig.feed(Tick(rig.now - 1000 * MS))
    assert back.now == lost.now
    assert back.next_deadline > lost.now
    assert "vsc_link_lost" in back.latched_names


def test_a_heartbeat_stamped_in_the_past_does_not_extend_liveness_backwards() -> None:
    """A VSC heartbeat with an old stamp counts as arriving at the latest ``now``."""
    rig = Rig()
    rig.bring_up()
    rig.advance(150)
    rig.tick()
    rig.now -= 100 * MS
    rig.vsc()  # stamped 100 ms in the past
    rig.now += 100 * MS
    rig.advance(199)
    assert rig.tick().state is State.RUN


def test_deadline_is_never_now_or_earlier() -> None:
    """After any input the next deadline is strictly later than ``now``."""
    rig = Rig()
    rig.bring_up()
    rig.run_for(1000, LOCAL)
    assert all(d.next_deadline > d.now for d in rig.decisions)


@pytest.mark.parametrize("now", [True, 1.5, "1"])
def test_a_time_that_is_not_an_integer_is_refused(now: object) -> None:
    """SR-2.11, PR-6.3: every input's time is integer nanoseconds of the monotonic clock, in
    one unit: a float, a text or a bool (an int to Python, never a time) is refused."""
    with pytest.raises(ValueError, match="now must be an integer"):
        Tick(now)  # type: ignore[arg-type]


def test_an_integer_time_of_an_int_subclass_is_accepted() -> None:
    """SR-2.11: an integer of a type derived from int (not bool) is a time like any other."""

    class Ns(int):
        pass

    assert Tick(Ns(5)).now == 5
