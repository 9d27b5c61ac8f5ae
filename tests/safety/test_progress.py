"""Fresh heartbeats (SR-8.16): only a heartbeat whose progress value moves on keeps a required
client alive; the core is driven with its own time."""

from __future__ import annotations

from dataclasses import replace

from supervisord.safety import ClientHeartbeat, ClientSpec, Decision, RefusalReason, State
from supervisord.safety.progress import PROGRESS_MODULUS, is_new
from tests.safety.rig import OPERATIONAL, ROBOT, Rig

TIMEOUT_MS = 500  # the planner's timeout_ms in the rig's config (the default)
DEMANDING = replace(ROBOT, clients=(ClientSpec("planner", progress=True),))


def _beat(rig: Rig, progress: object) -> Decision:
    return rig.feed(ClientHeartbeat(rig.now, 1, progress))  # type: ignore[arg-type]


def _vsc_for(rig: Rig, ms: int, step_ms: int = 50) -> Decision:
    """Let ``ms`` pass with a healthy VSC in Operational and no client heartbeat."""
    for _ in range(ms // step_ms):
        rig.advance(step_ms)
        rig.vsc(OPERATIONAL)
    return rig.last


def _lost_reason(decision: Decision) -> str | None:
    for cause in decision.causes:
        if cause.cause.name == "client_lost:planner" and cause.active:
            return dict(cause.details)["reason"]
    return None


def test_a_repeated_progress_value_extends_no_deadline() -> None:
    """SR-8.16: a heartbeat with the same progress value as the last is refused and the client
    is lost at its timeout from the last heartbeat that moved on, naming stale progress."""
    rig = Rig()
    rig.bring_up()
    assert _beat(rig, 7).refusals == ()
    _vsc_for(rig, 250)
    refused = _beat(rig, 7)
    assert [r.reason for r in refused.refusals] == [RefusalReason.STALE_PROGRESS]
    _vsc_for(rig, 200)
    assert _beat(rig, 7).state is State.RUN  # 450 ms: within the timeout still
    rig.advance(TIMEOUT_MS - 450 - 1)
    assert rig.tick().state is State.RUN
    rig.advance(1)
    lost = rig.tick()
    assert lost.state is State.STOPPED
    assert _lost_reason(lost) == "stale progress"


def test_an_increasing_progress_value_keeps_the_client_alive() -> None:
    """SR-8.16: heartbeats whose progress goes up by one each keep the client alive, each
    extending its deadline to its own timeout."""
    rig = Rig()
    rig.bring_up()
    for progress in range(1, 20):
        _vsc_for(rig, 100)
        decision = _beat(rig, progress)
        assert decision.refusals == ()
        assert decision.state is State.RUN
    assert _vsc_for(rig, 450).state is State.RUN
    silent = _vsc_for(rig, 50)
    assert silent.state is State.STOPPED
    assert _lost_reason(silent) == "timeout"  # the beats all counted: plain silence


def test_progress_wraps_around_and_replays_do_not_count() -> None:
    """SR-8.16: 2**32 - 1 is followed by 0; an older value replayed, a duplicate and a value half
    the circle away are not new."""
    assert is_new(0, PROGRESS_MODULUS - 1)
    assert is_new(5, None)
    assert is_new(PROGRESS_MODULUS // 2 - 1, 0)
    assert not is_new(PROGRESS_MODULUS // 2, 0)
    assert not is_new(3, 3)
    assert not is_new(2, 3)
    assert not is_new(PROGRESS_MODULUS - 1, 0)
    rig = Rig()
    rig.bring_up()
    assert _beat(rig, PROGRESS_MODULUS - 1).refusals == ()
    assert _beat(rig, 0).refusals == ()
    assert _beat(rig, 1).refusals == ()
    replay = _beat(rig, PROGRESS_MODULUS - 1)
    assert [r.reason for r in replay.refusals] == [RefusalReason.STALE_PROGRESS]


def test_a_replayed_older_value_does_not_extend_the_deadline() -> None:
    """SR-8.16: after 1, 2, a replay of 1 is refused and the deadline stays that of 2."""
    rig = Rig()
    rig.bring_up()
    _beat(rig, 1)
    _vsc_for(rig, 100)
    _beat(rig, 2)
    _vsc_for(rig, 300)
    _beat(rig, 1)
    _vsc_for(rig, 150)
    assert rig.last.state is State.RUN  # 450 ms after 2
    rig.advance(TIMEOUT_MS - 450)
    assert rig.tick().state is State.STOPPED
    assert _lost_reason(rig.last) == "stale progress"


def test_a_value_once_given_is_demanded_until_the_connection_ends() -> None:
    """SR-8.16: a client that sent a progress value binds itself: a later heartbeat without one
    is refused; a new connection starts without the bond and with a new counter."""
    rig = Rig()
    rig.bring_up()
    assert rig.beat(1).refusals == ()  # no value yet: a plain heartbeat counts
    assert _beat(rig, 9).refusals == ()
    plain = rig.beat(1)
    assert [r.reason for r in plain.refusals] == [RefusalReason.NO_PROGRESS]
    rig.disconnect(1)
    rig.connect(1)
    assert rig.beat(1).refusals == ()
    assert _beat(rig, 3).refusals == ()  # lower than 9: the counter started again


def test_the_config_demands_progress_from_the_first_heartbeat() -> None:
    """SR-8.16: with ``progress = true`` in its ``[[clients]]`` entry, a heartbeat without a
    value is refused and the client stays lost, the reason naming it; one with a value counts."""
    rig = Rig(DEMANDING)
    rig.open_link()
    rig.key85(1)
    rig.connect(1)
    plain = rig.beat(1)
    assert [r.reason for r in plain.refusals] == [RefusalReason.NO_PROGRESS]
    assert _lost_reason(plain) == "heartbeat without progress"
    counted = _beat(rig, 0)
    assert counted.refusals == ()
    assert _lost_reason(counted) is None


def test_a_value_out_of_range_is_refused_never_raised() -> None:
    """SR-8.16, SR-8.7: a progress value that is no 32-bit counter (negative, too large, a bool,
    text) is refused as stale in the core and extends no deadline; the core never fails."""
    rig = Rig()
    rig.bring_up()
    for bad in (-1, PROGRESS_MODULUS, True, "1"):
        decision = _beat(rig, bad)
        assert [r.reason for r in decision.refusals] == [RefusalReason.STALE_PROGRESS]
        assert "internal" not in decision.active_names


def test_a_fresh_heartbeat_after_a_stale_one_ends_the_stale_reason() -> None:
    """SR-8.16: once a new value comes after a stale one, the client is alive again from it and
    a later silence is named ``timeout``, not ``stale progress``."""
    rig = Rig()
    rig.bring_up()
    _beat(rig, 4)
    _beat(rig, 4)
    _vsc_for(rig, 100)
    assert _beat(rig, 5).refusals == ()
    _vsc_for(rig, 450)
    assert rig.last.state is State.RUN
    rig.advance(50)
    silent = rig.tick()
    assert silent.state is State.STOPPED
    assert _lost_reason(silent) == "timeout"
