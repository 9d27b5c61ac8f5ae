"""The exact edges of the timeouts and of the input vocabularies (SR-2, SR-3, SR-8).

Boundary semantics: a timeout of T expires at exactly T after the last heartbeat ("silent for
T or more is lost"); a heartbeat arriving at T is too late, because its deadline expires first.
"""

from __future__ import annotations

import dataclasses

import pytest

from supervisord.safety import State, Transport
from tests.safety.rig import LOCAL, MS, OPERATIONAL, ROBOT, SEARCHING, Rig


def test_client_heartbeat_at_499_ms_keeps_run() -> None:
    """A required client's heartbeat 499 ms after the previous one is in time."""
    rig = Rig()
    rig.bring_up()
    rig.beat()
    rig.advance(149)
    rig.vsc()
    rig.advance(150)
    rig.vsc()
    rig.advance(150)
    rig.vsc()
    rig.advance(50)
    assert rig.beat().state is State.RUN  # 499 ms after the last beat


def test_client_heartbeat_at_500_ms_is_too_late() -> None:
    """SR-2.4, SR-8.1: a required client's heartbeat exactly 500 ms after the previous one comes too
    late: the client was lost at 500 ms and the stop stays latched."""
    rig = Rig()
    rig.bring_up()
    rig.beat()
    for step in (150, 150, 150):
        rig.advance(step)
        rig.vsc()
    rig.advance(50)
    decision = rig.beat()
    assert decision.state is State.STOPPED
    lost = decision.cause("client_lost:planner")
    assert lost is not None
    assert lost.latched
    assert not lost.active
    assert lost.detail("reason") == "timeout"


def test_client_deadline_is_exactly_the_timeout() -> None:
    """With nothing else due sooner, the next deadline is the client's expiry and a tick there
    stops; a tick 1 ns earlier does not."""
    rig = Rig(dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False))
    rig.open_link()
    rig.connect()
    assert rig.take_over(600).state is State.RUN
    beat_at = rig.now
    rig.beat()
    rig.advance(250)
    expiry = beat_at + 500 * MS
    assert rig.vsc().next_deadline == expiry  # before the VSC's expiry at +300 ms
    rig.now = expiry - 1
    assert rig.tick().state is State.RUN
    rig.now = expiry
    assert rig.tick().state is State.STOPPED


@pytest.mark.parametrize(("silence_ms", "state"), [(199, State.RUN), (200, State.STOPPED)])
def test_vsc_timeout_edges(silence_ms: int, state: State) -> None:
    """SR-2.2, PR-6.1: VSC silence of 199 ms keeps RUN; 200 ms (the serial default) is
    ``vsc_link_lost``."""
    rig = Rig()
    rig.bring_up()
    rig.beat()
    rig.advance(silence_ms)
    decision = rig.tick()
    assert decision.state is state
    assert ("vsc_link_lost" in decision.latched_names) is (state is State.STOPPED)


def test_vsc_heartbeat_exactly_at_the_timeout_is_too_late() -> None:
    """A VSC heartbeat arriving exactly 200 ms after the previous one finds the link already
    lost; the heartbeat clears the condition but the stop stays latched."""
    rig = Rig()
    rig.bring_up()
    rig.advance(200)
    decision = rig.vsc()
    assert decision.state is State.STOPPED
    lost = decision.cause("vsc_link_lost")
    assert lost is not None
    assert lost.latched
    assert not lost.active


def test_vsc_timeout_on_can_defaults_to_300_ms() -> None:
    """On CAN the VSC timeout defaults to 300 ms: 299 ms of silence is fine, 300 ms is not."""
    config = dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False)
    assert config.vsc_timeout_ns == 300 * MS
    rig = Rig(config)
    rig.open_link()
    rig.connect()
    rig.run_for(600, LOCAL, step_ms=100)
    rig.advance(100)
    rig.vsc(OPERATIONAL)
    assert rig.beat().state is State.RUN
    rig.advance(299)
    assert rig.tick().state is State.RUN
    rig.advance(1)
    assert rig.tick().state is State.STOPPED


def test_vsc_never_seen_counts_as_lost() -> None:
    """With the link open but no VSC heartbeat yet, ``vsc_link_lost`` is active at once."""
    rig = Rig()
    decision = rig.open_link()
    lost = decision.cause("vsc_link_lost")
    assert lost is not None
    assert lost.active
    assert lost.detail("reason") == "no heartbeat since link open"


def test_required_client_that_never_connected_keeps_stopped() -> None:
    """SR-2.4, SR-8.1: a required client that never connected keeps the supervisor STOPPED, and a
    takeover is refused naming it."""
    rig = Rig()
    rig.open_link()
    rig.key85(1)
    decision = rig.take_over(1000, clients=())
    assert decision.state is State.STOPPED
    lost = decision.cause("client_lost:planner")
    assert lost is not None
    assert lost.active
    assert lost.detail("reason") == "never connected"
    assert "client_lost:planner" in decision.refusals[0].detail


def test_required_client_that_said_hello_but_never_beat_is_lost() -> None:
    """Hello alone is not enough: a required client is lost until its first heartbeat."""
    rig = Rig()
    rig.open_link()
    decision = rig.connect()
    lost = decision.cause("client_lost:planner")
    assert lost is not None
    assert lost.active
    assert lost.detail("reason") == "no heartbeat since hello"
    after = rig.beat().cause("client_lost:planner")
    assert after is not None
    assert not after.active


@pytest.mark.parametrize(
    ("mode", "name"),
    [
        (0x42, "vsc_mode:unknown_0x42"),
        (0x00, "vsc_mode:unknown_0x00"),
        (0xFF, "vsc_mode:unknown_0xff"),
    ],
)
def test_unknown_mode_is_a_hold(mode: int, name: str) -> None:
    """SR-1.2, SR-3.1, PR-2.7, PR-6.6: a mode with no name is a hold (SR-3) named after its value:
    motion off, power on."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.vsc(mode)
    assert decision.state is State.HOLD
    assert name in decision.active_names
    assert dict(decision.outputs) == {"drive": False, "lights": True}


def test_searching_mode_is_a_hold_named_searching() -> None:
    """Searching (0x01, older firmware) is a hold ``vsc_mode:searching``."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    assert "vsc_mode:searching" in rig.vsc(SEARCHING).active_names


def test_estop_word_with_unknown_bits_only_is_a_stop() -> None:
    """SR-2.1, PR-2.6: an e-stop word with only unnamed bits still stops, with the source
    ``unknown``."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.vsc(OPERATIONAL, estop=0x0000_0100)
    assert decision.state is State.STOPPED
    estop = decision.cause("vsc_estop")
    assert estop is not None
    assert estop.detail("sources") == "unknown"
    assert estop.detail("word") == "0x00000100"


@pytest.mark.parametrize(
    ("word", "sources"),
    [(0b11, "remote"), (0b1100, "wired"), (0b1100_0000, "user"), (0x8000_0003, "remote,unknown")],
)
def test_estop_word_sources_are_named(word: int, sources: str) -> None:
    """Each e-stop bit group is named in the cause's details (PR-2)."""
    rig = Rig()
    rig.bring_up()
    estop = rig.vsc(LOCAL, estop=word).cause("vsc_estop")
    assert estop is not None
    assert estop.detail("sources") == sources
