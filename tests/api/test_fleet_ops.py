"""The fleet's ops as the API reads them (SR-8.19, docs/api.md "fleet_stop"): strict, each
back from its own JSON, every malformed one refused with ``bad_request``."""

from __future__ import annotations

import json

import pytest

from supervisord.api.framing import ApiError, ErrorCode
from supervisord.api.requests import (
    FleetKeepaliveRequest,
    FleetReleaseRequest,
    FleetStopRequest,
    parse_request,
    request_json,
)
from supervisord.api.translate import ClientInfo, to_core_event
from supervisord.api.views import refusal_error
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.safety.events import Caller, FleetKeepalive, FleetRelease, FleetStop

CALLER = Caller(uid=998, pid=5, name="srcs-fleet", admin=False)


@pytest.mark.parametrize(
    "request_",
    [
        FleetStopRequest("2026-12-06T14:00:00Z:17", "console-a", id=7),
        FleetReleaseRequest("s-1", "console.b"),
        FleetKeepaliveRequest("console-a", id="k"),
    ],
)
def test_each_fleet_op_reads_back_from_its_json(
    request_: FleetStopRequest | FleetReleaseRequest | FleetKeepaliveRequest,
) -> None:
    """What a client sends (``request_json``) the daemon reads back as the same request."""
    line = json.dumps(request_json(request_)).encode()
    assert parse_request(line) == request_


@pytest.mark.parametrize(
    "line",
    [
        b'{"op": "fleet_stop", "sender": "c"}',
        b'{"op": "fleet_stop", "stop_id": "", "sender": "c"}',
        b'{"op": "fleet_stop", "stop_id": "a b", "sender": "c"}',
        b'{"op": "fleet_stop", "stop_id": "a", "sender": "' + b"c" * 65 + b'"}',
        b'{"op": "fleet_stop", "stop_id": 3, "sender": "c"}',
        b'{"op": "fleet_stop", "stop_id": "a", "sender": "c", "arm": true}',
        b'{"op": "fleet_release", "stop_id": "a"}',
        b'{"op": "fleet_keepalive"}',
        b'{"op": "fleet_keepalive", "sender": "c\\n"}',
    ],
)
def test_a_malformed_fleet_op_is_a_bad_request(line: bytes) -> None:
    """A missing, empty, too long or unknown field, or text outside the rule: ``bad_request``."""
    with pytest.raises(ApiError) as error:
        parse_request(line)
    assert error.value.code == ErrorCode.BAD_REQUEST


def test_each_fleet_op_is_its_core_event_with_the_caller() -> None:
    """Each op reaches the core with the caller's credentials, which the core judges."""
    client = ClientInfo(4, CALLER)
    assert to_core_event(FleetStopRequest("s", "c"), client, 9) == FleetStop(9, 4, CALLER, "s", "c")
    release = to_core_event(FleetReleaseRequest("s", "c"), client, 9)
    assert release == FleetRelease(9, 4, CALLER, "s", "c")
    keepalive = to_core_event(FleetKeepaliveRequest("c"), client, 9)
    assert keepalive == FleetKeepalive(9, 4, CALLER, "c")


def test_a_fleet_op_from_another_user_is_not_allowed() -> None:
    """SR-8.19: the core's refusal of a connection that is not the agent's user has the code
    a hello bound to another user has."""
    request = FleetStopRequest("s", "c", id=3)
    refusal = Refusal(RefusalReason.NOT_FLEET_AGENT, "uid 1000", None)
    error = refusal_error(request, refusal)
    assert error.code == ErrorCode.NOT_ALLOWED
    assert error.op == "fleet_stop"
