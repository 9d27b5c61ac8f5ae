"""The flight recorder's encoding of the core's inputs and configuration (SR-7.10;
``supervisord/record/flight_codec.py``, docs/record.md "The flight recorder"): every input type
has an encoding that names each of its fields, and every input comes back equal from its JSON
(through text, as the file holds it)."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from supervisord.protocol.messages import FeedbackName, FeedbackSet, VscHeartbeat
from supervisord.record import flight_codec
from supervisord.record.flight_codec import (
    CLASSES,
    FIELDS,
    FlightFormatError,
    config_from_json,
    config_to_json,
    event_from_json,
    event_to_json,
)
from supervisord.record.format import TRIGGER_EVENTS
from supervisord.safety.config import ClientSpec, OutputRole, OutputSpec, SafetyConfig, Transport
from supervisord.safety.events import EVENT_TYPES, Caller, Event, Request, Tick, _Event
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.safety.stoptest import OutputOff, Source, StopStep, StopTestResult
from tests.protocol.strategies import i32, messages, text, u8

words = st.one_of(st.text(), st.sampled_from(["", "EIO", "nav", "\udcff-not-utf8", "a\nb"]))
callers = st.builds(Caller, st.integers(0, 2**32), st.integers(0, 2**22), words, st.booleans())
display = st.one_of(st.builds(FeedbackSet, u8, i32), st.builds(FeedbackName, u8, text(20)))

stoptest_results = st.builds(
    StopTestResult,
    st.lists(
        st.builds(
            StopStep,
            st.sampled_from(Source),
            st.integers(1, 2**62),
            st.integers(0, 2**62),
            st.lists(
                st.builds(
                    OutputOff, words, st.none() | st.integers(-(2**40), 2**40), st.integers(0, 5000)
                ),
                max_size=4,
            ).map(tuple),
        ),
        max_size=2,
    ).map(tuple),
    st.integers(1, 10_000),
)

KINDS = (
    flight_codec.INT,
    flight_codec.OPTIONAL_INT,
    flight_codec.FLAG,
    flight_codec.OPTIONAL_FLAG,
    flight_codec.TEXT,
    flight_codec.CALLER,
    flight_codec.OPTIONAL_CALLER,
    flight_codec.MESSAGE,
    flight_codec.DISPLAY,
    flight_codec.REQUEST,
    flight_codec.STOPTEST,
)
VALUES: dict[str, st.SearchStrategy[Any]] = {
    "connection": st.integers(-(2**40), 2**40),
    "uid": st.integers(0, 2**32),
    "name": words,
    "caller": callers,
    "request": st.sampled_from(Request),
    "output": words,
    "requested": st.booleans(),
    "read_back": st.booleans(),
    "reason": words,
    "key85": st.integers(-(2**31), 2**31),
    "remote_status": st.booleans(),
    "nonzero": st.booleans(),
    "result": stoptest_results,
    "progress": st.integers(0, 2**32 - 1),
    "stop_id": words,  # SR-8.19
    "sender": words,
}
"""Values for each field of the events, by its name, from what the field holds (its type in
the code), not from the encoding's kind: a field given the wrong kind fails to round-trip."""


def _events(cls: type) -> st.SearchStrategy[Event]:
    fields: dict[str, st.SearchStrategy[Any]] = {}
    for field in dataclasses.fields(cls):
        if field.name == "now":
            continue
        if field.name == "message":
            values = display if "Feedback" in str(field.type) else messages
        else:
            values = VALUES[field.name]
        fields[field.name] = st.none() | values if "None" in str(field.type) else values
    return st.builds(cls, now=st.integers(0, 2**63 - 1), **fields)


every_event = st.one_of([_events(cls) for cls in EVENT_TYPES])


def test_every_input_type_has_an_encoding_of_every_field() -> None:
    """SR-7.10: each event type of the core has a name in the file and an entry for each of
    its fields (``now`` is every input's own): a new event type, or a new field, fails here
    until it is given its encoding."""
    assert set(CLASSES.values()) == set(EVENT_TYPES)
    for cls in EVENT_TYPES:
        name = TRIGGER_EVENTS[cls]
        fields = {f.name for f in dataclasses.fields(cls)} - {"now"}
        assert {key for key, _ in FIELDS.get(name, ())} == fields, name
        assert all(kind in KINDS for _, kind in FIELDS[name])


def test_an_event_type_without_an_encoding_is_refused() -> None:
    """SR-7.10: an input of a type the encoding does not know is refused by name, never
    written as something else."""

    @dataclasses.dataclass(frozen=True, slots=True)
    class Novel(_Event):
        what: str

    with pytest.raises(FlightFormatError, match="Novel"):
        event_to_json(Novel(1, "x"))  # type: ignore[arg-type]


@given(every_event)
def test_every_input_round_trips_through_its_line(event: Event) -> None:
    """SR-7.10: every input of every type comes back equal from its line of text."""
    line = json.dumps(event_to_json(event))
    assert event_from_json(json.loads(line)) == event


@pytest.mark.parametrize("cls", EVENT_TYPES, ids=[TRIGGER_EVENTS[c] for c in EVENT_TYPES])
def test_each_input_type_round_trips(cls: type) -> None:
    """SR-7.10: each type on its own (so that none is left to chance)."""

    @given(_events(cls))
    def round_trip(event: Event) -> None:
        assert event_from_json(json.loads(json.dumps(event_to_json(event)))) == event

    round_trip()


def test_a_vsc_message_is_written_as_its_packet() -> None:
    """SR-7.10: a VSC message is its HRI packet's type and payload (PR-2), the wire's own
    encoding, not the code's field names."""
    line = event_to_json(flight_codec.CLASSES["vsc_received"](5, VscHeartbeat(9, 0, 1)))
    assert line == {
        "event": "vsc_received",
        "now": 5,
        "message": {"type": 0x20, "payload": "090001000000"},
    }


@pytest.mark.parametrize(
    "line",
    [
        {"event": "unknown", "now": 1},
        {"event": "tick"},
        {"event": "tick", "now": True},
        {"event": "client_estop", "now": 1},
        {"event": "client_estop", "now": 1, "connection": "3"},
        {"event": "vsc_received", "now": 1, "message": {"type": 0x20, "payload": "09"}},
        {"event": "vsc_received", "now": 1, "message": {"type": 0x77, "payload": ""}},
        {"event": "vsc_received", "now": 1, "message": {"type": 0x20, "payload": "zz"}},
        {"event": "display_update", "now": 1, "message": {"type": 0x20, "payload": "090001000000"}},
        {"event": "client_release", "now": 1, "connection": 1, "request": "both"},
        {"event": "local_estop", "now": 1, "caller": {"uid": 0}},
        ["tick", 1],
    ],
)
def test_a_line_that_is_no_input_is_refused(line: object) -> None:
    """SR-7.10: whatever a damaged or edited file holds is refused with a reason, never read
    as some other input."""
    with pytest.raises(FlightFormatError):
        event_from_json(line)


CONFIGS = [
    SafetyConfig(),
    SafetyConfig(
        vsc_timeout_ms=150,
        heartbeat_hz=50,
        rearm_hold_ms=100,
        local_reset=True,
        clients=(ClientSpec("nav"), ClientSpec("arm", 300, uid=1000)),
        outputs=(
            OutputSpec("drive"),
            OutputSpec("lamp", OutputRole.POWER),
            OutputSpec("brakes", OutputRole.POWER, off_delay_ms=400),
        ),
        prooftest=ProofTestPolicy.BLOCK,
        prooftest_clear_ms=5000,
    ),
    SafetyConfig(transport=Transport.CAN, require_watchdog=False),
]


@pytest.mark.parametrize("config", CONFIGS, ids=["defaults", "everything", "can"])
def test_the_configuration_round_trips(config: SafetyConfig) -> None:
    """SR-7.10: the core's configuration comes back equal, validated as any other."""
    assert config_from_json(json.loads(json.dumps(config_to_json(config)))) == config


def test_the_configuration_encoding_names_every_field() -> None:
    """SR-7.10: a field added to the core's configuration fails here until it is written."""
    assert set(config_to_json(SafetyConfig())) == {f.name for f in dataclasses.fields(SafetyConfig)}


def test_the_encoding_of_an_output_names_every_field_the_core_reads() -> None:
    """SR-7.10, SR-1.4: an output's name, role and stop category; a field added to the core's
    output fails here until it is written."""
    (output,) = config_to_json(SafetyConfig(outputs=(OutputSpec("drive"),)))["outputs"]
    assert set(output) == {f.name for f in dataclasses.fields(OutputSpec)}


def test_a_configuration_the_core_would_refuse_is_refused() -> None:
    """SR-7.10: an edited configuration goes through the same checks as the robot's file."""
    data = config_to_json(SafetyConfig()) | {"heartbeat_hz": 5}
    with pytest.raises(FlightFormatError, match="heartbeat_hz"):
        config_from_json(data)
    with pytest.raises(FlightFormatError):
        config_from_json(config_to_json(SafetyConfig()) | {"outputs": [{"role": "motion"}]})


def test_tick_has_no_fields() -> None:
    """SR-7.10: the most frequent input is the smallest line."""
    assert event_to_json(Tick(7)) == {"event": "tick", "now": 7}
