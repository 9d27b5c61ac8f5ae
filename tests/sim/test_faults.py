"""Each fault of the plan does what it says, checked with the protocol's own decoder."""

from __future__ import annotations

import pytest

from supervisord.protocol.codes import MessageType, VscMode
from supervisord.protocol.framing import FrameDecoder, Rejection, RejectReason, encode_frame
from supervisord.protocol.j1939 import CanFrame, CanRejection, CanRejectReason, decode_can
from supervisord.protocol.messages import Gps, Joystick, VscHeartbeat
from supervisord.sim.faults import CanErrorFrame, FaultInjector, FaultPlan, Pacer

BEAT = VscHeartbeat(VscMode.OPERATIONAL)
FRAMES = [encode_frame(VscHeartbeat(VscMode.LOCAL, 0, n)) for n in range(200)]


def run(plan: FaultPlan, frames: list[bytes] = FRAMES, seed: int = 1) -> FaultInjector:
    injector = FaultInjector(plan, seed)
    for i, frame in enumerate(frames):
        injector.push(frame, frame[2], i * 0.05)
    return injector


def sent(injector: FaultInjector, until: float = 1e9) -> bytes:
    items = injector.due(until)
    assert all(isinstance(item, bytes) for item in items)
    return b"".join(item for item in items if isinstance(item, bytes))


def decode(data: bytes) -> list[object]:
    decoder = FrameDecoder()
    return [*decoder.feed(data), *decoder.end()]


def reasons(events: list[object]) -> set[RejectReason]:
    return {e.reason for e in events if isinstance(e, Rejection)}


def words(events: list[object]) -> list[int]:
    return [e.estop for e in events if isinstance(e, VscHeartbeat)]


def test_healthy_plan_passes_everything_in_order() -> None:
    injector = run(FaultPlan())
    assert words(decode(sent(injector))) == list(range(200))
    assert not FaultPlan().active


def test_drop_loses_frames_and_keeps_the_rest_in_order() -> None:
    injector = run(FaultPlan(drop=0.3))
    got = words(decode(sent(injector)))
    assert 100 < len(got) < 180
    assert got == sorted(got)
    assert injector.counts["drop"] == 200 - len(got)


def test_corrupt_is_always_caught_by_the_checksum() -> None:
    """One corrupted byte always fails Fletcher-16: every corrupted frame is rejected as
    bad_checksum and never decodes."""
    injector = run(FaultPlan(corrupt=1.0))
    events = decode(sent(injector))
    assert words(events) == []
    assert reasons(events) <= {RejectReason.BAD_CHECKSUM, RejectReason.NOISE}
    assert (
        sum(isinstance(e, Rejection) and e.reason is RejectReason.BAD_CHECKSUM for e in events)
        >= 200
    )


def test_corrupt_some_frames_leaves_the_others_intact() -> None:
    injector = run(FaultPlan(corrupt=0.5))
    events = decode(sent(injector))
    good = words(events)
    assert len(good) + injector.counts["corrupt"] == 200
    assert RejectReason.BAD_CHECKSUM in reasons(events)


def test_duplicate_sends_a_frame_twice() -> None:
    injector = run(FaultPlan(duplicate=1.0))
    assert words(decode(sent(injector))) == [n for n in range(200) for _ in range(2)]


def test_delay_holds_frames_back_for_delay_s() -> None:
    injector = FaultInjector(FaultPlan(delay=1.0, delay_s=0.3), 0)
    injector.push(FRAMES[0], FRAMES[0][2], 10.0)
    assert injector.due(10.29) == []
    assert injector.next_deadline() == pytest.approx(10.3)
    assert injector.due(10.3) == [FRAMES[0]]


def test_reorder_swaps_a_frame_with_the_next() -> None:
    injector = FaultInjector(FaultPlan(reorder=1.0, only_types=frozenset({0x20})), 0)
    injector.push(FRAMES[0], 0x20, 0.0)  # held
    joystick = encode_frame(Joystick())
    injector.push(joystick, 0x10, 0.01)  # not subject to faults: overtakes it
    assert injector.due(0.01) == [joystick, FRAMES[0]]


def test_reorder_everything_still_delivers_everything() -> None:
    injector = run(FaultPlan(reorder=0.5))
    got = words(decode(sent(injector)))
    assert sorted(got) == list(range(200))
    assert got != list(range(200))


def test_held_frame_goes_out_after_half_a_second_alone() -> None:
    injector = FaultInjector(FaultPlan(reorder=1.0), 0)
    injector.push(FRAMES[0], 0x20, 0.0)
    assert injector.due(0.4) == []
    assert injector.due(0.5) == [FRAMES[0]]


def test_garbage_bursts_are_noise_and_frames_survive() -> None:
    injector = run(FaultPlan(garbage=1.0, garbage_max=8), seed=3)
    events = decode(sent(injector))
    assert injector.counts["garbage"] == 200
    assert RejectReason.NOISE in reasons(events)
    assert len(words(events)) >= 190  # a garbage burst may form a fake header now and then


def test_wrong_length_is_rejected_from_the_header() -> None:
    frames = [*FRAMES[:10], encode_frame(Gps(1, "$GPGGA,1*00"))]
    injector = run(FaultPlan(wrong_length=1.0), frames)
    events = decode(sent(injector))
    assert words(events) == []
    assert not any(isinstance(e, Gps) for e in events)
    # The decoder drops one byte per bad header; the rest of the frame is then noise.
    assert reasons(events) == {RejectReason.WRONG_LENGTH, RejectReason.NOISE}
    wrong = [
        e for e in events if isinstance(e, Rejection) and e.reason is RejectReason.WRONG_LENGTH
    ]
    assert len(wrong) == 11


def test_unknown_type_frames_are_counted_and_skipped() -> None:
    injector = run(FaultPlan(unknown_type=1.0))
    events = decode(sent(injector))
    assert words(events) == list(range(200))
    unknown = [e for e in events if isinstance(e, Rejection)]
    assert len(unknown) == 200
    assert all(e.reason is RejectReason.UNKNOWN_TYPE for e in unknown)


def test_only_types_limits_the_faults() -> None:
    frames = [encode_frame(Joystick()), FRAMES[5]] * 20
    injector = run(FaultPlan(drop=1.0, only_types=frozenset({MessageType.JOYSTICK})), frames)
    events = decode(sent(injector))
    assert words(events) == [5] * 20
    assert not any(isinstance(e, Joystick) for e in events)


def test_frozen_heartbeat_keeps_the_first_content() -> None:
    injector = FaultInjector(FaultPlan(freeze_heartbeat=True), 0)
    first = injector.message(VscHeartbeat(VscMode.OPERATIONAL), 0.0)
    later = injector.message(VscHeartbeat(VscMode.LOCAL, 0, 1), 1.0)
    assert first == later == VscHeartbeat(VscMode.OPERATIONAL)
    assert injector.message(Joystick(), 1.0) == Joystick()
    injector.set_plan(FaultPlan(), 2.0)
    assert injector.message(VscHeartbeat(VscMode.LOCAL, 0, 1), 2.0) == VscHeartbeat(4, 0, 1)


def test_mode_flapping_alternates_with_the_period() -> None:
    injector = FaultInjector(FaultPlan(flap_mode=VscMode.PAUSE, flap_period_s=0.1), 0)
    injector.set_plan(injector.plan, 5.0)
    beats = [injector.message(BEAT, 5.025 + t / 100) for t in range(0, 40, 5)]
    op, pause = VscMode.OPERATIONAL, VscMode.PAUSE
    modes = [beat.mode if isinstance(beat, VscHeartbeat) else None for beat in beats]
    assert modes == [op, op, pause, pause, op, op, pause, pause]


def test_same_seed_same_faults() -> None:
    plan = FaultPlan(drop=0.2, corrupt=0.2, duplicate=0.2, garbage=0.2)
    assert sent(run(plan, seed=9)) == sent(run(plan, seed=9))
    assert sent(run(plan, seed=9)) != sent(run(plan, seed=10))


def test_pacer_splits_writes_into_slow_chunks() -> None:
    pacer = Pacer(chunk_bytes=3, gap_s=0.01)
    pacer.push(FRAMES[0])  # 12 bytes
    chunks = []
    now = 0.0
    while pacer.pending:
        chunk = pacer.pop(now)
        assert pacer.pop(now) == b""  # the next chunk waits for the gap
        chunks.append(chunk)
        now += 0.01
    assert chunks == [FRAMES[0][i : i + 3] for i in range(0, 12, 3)]
    whole = Pacer()
    whole.push(FRAMES[0])
    assert whole.pop(0.0) == FRAMES[0]


def test_can_faults() -> None:
    """On CAN, corruption is what a receiver sees of a CRC failure: an error frame; a short
    frame is wrong_length; an unknown id is unknown_id."""
    frame = CanFrame(0x0CFDE801, bytes(8))
    injector = FaultInjector(FaultPlan(corrupt=1.0), 0)
    injector.push_can(frame, 0x20, 0.0)
    assert injector.due(0.0) == [CanErrorFrame()]
    injector.set_plan(FaultPlan(wrong_length=1.0, unknown_type=1.0), 0.0)
    injector.push_can(frame, 0x20, 0.0)
    results = []
    for item in injector.due(0.0):
        assert isinstance(item, CanFrame)
        results.append(decode_can(item))
    assert [r.reason for r in results if isinstance(r, CanRejection)] == [
        CanRejectReason.UNKNOWN_ID,
        CanRejectReason.WRONG_LENGTH,
    ]


@pytest.mark.parametrize(
    ("plan", "message"),
    [
        ({"drop": 2}, "probability"),
        ({"delay_s": -1}, "delay_s"),
        ({"corrupt_bytes": 0}, "corrupt_bytes"),
        ({"flap_mode": 300}, "flap_mode"),
        ({"explode": 1}, "unknown fault field"),
        ({"only_types": 16}, "only_types"),
        ({"freeze_heartbeat": 1}, "freeze_heartbeat"),
    ],
)
def test_bad_plans_are_refused_with_the_field_named(plan: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        FaultPlan.from_json(plan)


def test_plan_json_round_trip() -> None:
    plan = FaultPlan(drop=0.1, only_types=frozenset({16, 32}), flap_mode=11)
    assert FaultPlan.from_json(plan.to_json()) == plan
    assert plan.to_json() == {"drop": 0.1, "flap_mode": 11, "only_types": [16, 32]}
