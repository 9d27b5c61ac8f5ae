"""The acknowledgement is the daemon's facts, judged (SR-13.15)."""

from __future__ import annotations

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.fleet_agent.ack import Ack, OutputState, failed, from_reply, parse

REPLY = {
    "ok": True,
    "op": "fleet_stop",
    "id": 1,
    "stop_id": "s1",
    "state": "STOPPED",
    "outputs": [
        {"name": "drive", "level": False, "readback": False},
        {"name": "brake", "level": False, "readback": None},
    ],
    "record_seq": 42,
    "arrival_to_off_ms": 0.41,
}


def test_stopped_when_stopped_and_every_output_reads_back_off() -> None:
    ack = from_reply("robot-a", "stop", "s1", REPLY, 1.23456)
    assert ack.result == "stopped"
    assert ack.reason is None
    assert ack.record_seq == 42
    assert ack.arrival_to_off_ms == 0.41
    assert ack.agent_ms == 1.235
    assert ack.outputs == (
        OutputState("drive", False, False),
        OutputState("brake", False, None),
    )
    assert parse(ack.encode()) == ack


def test_an_output_that_reads_back_on_is_not_stopped_whatever_the_state() -> None:
    reply = {**REPLY, "outputs": [{"name": "drive", "level": False, "readback": True}]}
    ack = from_reply("robot-a", "stop", "s1", reply, 1.0)
    assert ack.result == "not_stopped"
    assert ack.reason == "output reads back on: drive"


def test_a_state_other_than_stopped_or_a_missing_state_is_not_stopped() -> None:
    assert from_reply("r", "stop", "s1", {**REPLY, "state": "RUN"}, 1.0).reason == "state RUN"
    no_state = {k: v for k, v in REPLY.items() if k != "state"}
    assert from_reply("r", "stop", "s1", no_state, 1.0).result == "not_stopped"


def test_a_release_is_acknowledged_as_released_with_the_state_it_left() -> None:
    ack = from_reply("robot-a", "release", "s1", REPLY, 1.0)
    assert (ack.result, ack.state) == ("released", "STOPPED")


def test_a_failure_carries_its_reason() -> None:
    ack = failed("robot-a", "stop", "s1", "supervisor unreachable: x", 2.0, refused=False)
    assert (ack.result, ack.reason) == ("not_stopped", "supervisor unreachable: x")
    assert parse(ack.encode()) == ack
    ack = failed("robot-a", "stop", "s1", "replayed", 0.1, refused=True)
    assert ack.result == "refused"


def test_what_is_no_ack_is_none() -> None:
    good = json.loads(from_reply("robot-a", "stop", "s1", REPLY, 1.0).encode())
    assert parse(b"nope") is None
    assert parse(json.dumps({**good, "v": 2}).encode()) is None
    assert parse(json.dumps({**good, "robot": "a/#"}).encode()) is None
    assert parse(json.dumps({**good, "result": "rearmed"}).encode()) is None


@settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300))
def test_no_bytes_raise(payload: bytes) -> None:
    assert isinstance(parse(payload), Ack | None)


@settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.dictionaries(
        st.sampled_from(["state", "outputs", "record_seq", "arrival_to_off_ms"]),
        st.none()
        | st.booleans()
        | st.integers()
        | st.floats()
        | st.text(max_size=10)
        | st.lists(
            st.dictionaries(st.text(max_size=8), st.none() | st.booleans() | st.text(max_size=4)),
            max_size=3,
        ),
    )
)
def test_no_reply_raises(reply: dict[str, object]) -> None:
    assert isinstance(from_reply("r", "stop", "s1", reply, 1.0), Ack)


def test_an_output_on_that_reads_nothing_back_is_named_apart() -> None:
    reply = {**REPLY, "outputs": [{"name": "wheels", "level": True, "readback": None}]}
    ack = from_reply("robot-a", "stop", "s1", reply, 1.0)
    assert ack.result == "not_stopped"
    assert ack.reason == "output still on, not read back: wheels"
