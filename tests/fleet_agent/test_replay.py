"""The replay window (SR-13.14): a stop is forwarded once, and only while fresh."""

from __future__ import annotations

from supervisord.fleet_agent.message import StopMessage
from supervisord.fleet_agent.replay import ReplayGuard

T0 = 1_765_000_000.0


def _stop(nonce: str, sent: float = T0, stop_id: str = "s1") -> StopMessage:
    return StopMessage("stop", stop_id, "console-1", sent, nonce.ljust(32, "0"))


def test_a_fresh_stop_passes_once_and_its_copy_is_refused() -> None:
    guard = ReplayGuard()
    assert guard.check(_stop("a"), T0 + 0.1, 100.0) is None
    assert guard.check(_stop("a"), T0 + 0.2, 100.1) == "replayed"


def test_the_consoles_retry_of_a_stop_id_is_a_new_message() -> None:
    guard = ReplayGuard()
    assert guard.check(_stop("a"), T0, 100.0) is None
    assert guard.check(_stop("b", T0 + 1), T0 + 1, 101.0) is None


def test_older_than_the_window_is_stale_and_from_the_future_past_the_skew_is_refused() -> None:
    guard = ReplayGuard(window_s=30, skew_s=5)
    assert guard.check(_stop("a"), T0 + 30.5, 100.0) == "stale"
    assert guard.check(_stop("b"), T0 - 5.5, 100.0) == "future"
    # Within the skew either way: a console's clock a little ahead or behind.
    assert guard.check(_stop("c"), T0 - 4.5, 100.0) is None
    assert guard.check(_stop("d"), T0 + 29.5, 100.0) is None


def test_a_replay_after_the_memory_forgot_it_is_refused_by_its_age() -> None:
    guard = ReplayGuard(window_s=30, skew_s=5)
    assert guard.check(_stop("a"), T0, 100.0) is None
    assert len(guard) == 1
    # 35 s later by both clocks: forgotten, and too old.
    assert guard.check(_stop("a"), T0 + 35, 135.0) == "stale"
    assert len(guard) == 0


def test_a_wall_clock_step_back_does_not_shorten_the_memory() -> None:
    guard = ReplayGuard(window_s=30, skew_s=5)
    assert guard.check(_stop("a"), T0, 100.0) is None
    # The robot's wall clock stepped back 20 s while 20 s passed: still remembered.
    assert guard.check(_stop("a"), T0, 120.0) == "replayed"


def test_a_full_memory_never_lets_a_forgotten_nonce_back_in() -> None:
    guard = ReplayGuard(window_s=30, skew_s=5, max_seen=3)
    for i, nonce in enumerate("abcd"):
        assert guard.check(_stop(nonce, T0 + i), T0 + 4, 100.0) is None
    assert len(guard) == 3
    # "a" was forgotten to make room; its send time is now the floor.
    assert guard.check(_stop("a", T0), T0 + 4, 100.0) == "stale"
    assert guard.check(_stop("e", T0 + 4), T0 + 4, 100.0) is None
