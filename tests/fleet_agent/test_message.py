"""A stop's payload is read without ever raising (SR-13.14): anything else is a typed refusal."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.fleet_agent.message import (
    Refused,
    StopMessage,
    new_message,
    new_stop_id,
    parse,
)

T0 = 1_765_000_000.25


def test_a_message_reads_back_as_sent() -> None:
    sent = new_message("stop", new_stop_id("console-1", T0), "console-1", T0)
    assert parse(sent.encode()) == sent
    assert len(sent.nonce) == 32


def _with(**fields: object) -> bytes:
    good = json.loads(new_message("stop", "s1", "console-1", T0).encode())
    good.update(fields)
    return json.dumps(good).encode()


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"", "not_json"),
        (b"\xff\xfe", "not_json"),
        (b"[1]", "not_an_object"),
        (b"{" * 600 + b"}" * 600, "too_long"),
        (_with(v=2), "version"),
        (_with(kind="rearm"), "kind"),
        (_with(kind="reset"), "kind"),
        (_with(stop_id=""), "stop_id"),
        (_with(stop_id="a/b"), "stop_id"),
        (_with(sender="a/+"), "sender"),
        (_with(sent_utc=True), "sent_utc"),
        (_with(sent_utc="now"), "sent_utc"),
        (
            b'{"v":1,"kind":"stop","stop_id":"s","sender":"c","sent_utc":1e999,"nonce":"00000000000000000000000000000000"}',
            "sent_utc",
        ),
        (_with(nonce="short"), "nonce"),
    ],
)
def test_what_is_no_stop_is_refused_by_name(payload: bytes, reason: str) -> None:
    refused = parse(payload)
    assert isinstance(refused, Refused)
    assert refused.reason == reason


def test_a_refusal_names_the_stop_id_when_it_could_be_read() -> None:
    assert parse(_with(kind="rearm")) == Refused("kind", "s1")


@settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300))
def test_no_bytes_raise(payload: bytes) -> None:
    assert isinstance(parse(payload), StopMessage | Refused)


@settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.dictionaries(
        st.sampled_from(["v", "kind", "stop_id", "sender", "sent_utc", "nonce"]),
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=70),
    )
)
def test_no_object_raises(obj: dict[str, object]) -> None:
    assert isinstance(parse(json.dumps(obj).encode()), StopMessage | Refused)
