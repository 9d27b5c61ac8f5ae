"""The client API (SR-8, ``docs/api.md``): the local Unix socket that serves the
robot's programs and ``srcsctl``. :mod:`.wire` is the message vocabulary (sans-IO),
:mod:`.server` the non-blocking server the daemon's loop drives, :mod:`.credentials` who is
at the other end. The robot's programs use :mod:`supervisord.client`."""

from supervisord.api.server import (
    Accepted,
    ApiServer,
    Closed,
    CloseReason,
    Denied,
    Received,
    Result,
    ServerConfig,
    ServerError,
    core_event,
)
from supervisord.api.wire import (
    ApiError,
    ClientInfo,
    ErrorCode,
    Request,
    Topic,
    decision_json,
    message_push,
    message_topic,
    record_json,
    record_push,
    refusal_error,
    state_push,
    to_core_event,
)

__all__ = [
    "Accepted",
    "ApiError",
    "ApiServer",
    "ClientInfo",
    "CloseReason",
    "Closed",
    "Denied",
    "ErrorCode",
    "Received",
    "Request",
    "Result",
    "ServerConfig",
    "ServerError",
    "Topic",
    "core_event",
    "decision_json",
    "message_push",
    "message_topic",
    "record_json",
    "record_push",
    "refusal_error",
    "state_push",
    "to_core_event",
]
