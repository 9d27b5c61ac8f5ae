"""The client API served from the daemon's loop: requests in, replies and pushes out.

Every request that is a safety input goes to the core first; the reply then says "ok", or
carries the core's refusal (e.g. why a reset was not honoured). Clients dropped while being
written to (a stopped or flooding client) reach the core as disconnections on the next round.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from supervisord.api.server import ApiServer, Closed, Received, Result, core_event
from supervisord.api.wire import (
    ApiError,
    Commission,
    ErrorCode,
    Status,
    Subscribe,
    Topic,
    decision_json,
    message_push,
    message_topic,
    record_push,
    refusal_error,
    state_push,
)
from supervisord.daemon.loop import Listener
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message
from supervisord.safety.decision import Decision
from supervisord.safety.events import ClientDisconnected, Event


class ApiListener(Listener):
    def __init__(self, server: ApiServer) -> None:
        self.server = server
        self.last: Decision | None = None
        self._closed: list[Closed] = []

    def descriptors(self) -> Iterable[tuple[int, bool]]:
        return self.server.descriptors()

    def handle(
        self, fd: int, readable: bool, writable: bool, now: int, feed: Callable[[Event], Decision]
    ) -> None:
        for result in self.server.handle(fd, readable, writable):
            self._result(result, now, feed)

    def take_events(self, now: int) -> list[Event]:
        closed, self._closed = self._closed, []
        return [ClientDisconnected(now, c.client.connection) for c in closed]

    def _result(self, result: Result, now: int, feed: Callable[[Event], Decision]) -> None:
        event = core_event(result, now)
        decision = feed(event) if event is not None else None
        if not isinstance(result, Received):
            return  # Denied was answered by the server; Accepted and Closed need no reply
        request = result.request
        if isinstance(request, Status):
            assert self.last is not None
            self._closed += self.server.reply(result, **decision_json(self.last))
            return
        if isinstance(request, Commission):
            # Writing key 85 is a separate, explicit, recorded step (safety-rules.md §5);
            # until the daemon performs it, say so rather than pretend.
            error = ApiError(
                ErrorCode.UNAVAILABLE,
                "commissioning is not available yet: set key 85 with the vendor's tool",
            )
            self._closed += self.server.reply_error(result, error)
            return
        refusal = (
            next((r for r in decision.refusals if r.trigger == event), None) if decision else None
        )
        if refusal is not None:
            self._closed += self.server.reply_error(result, refusal_error(request, refusal))
        else:
            self._closed += self.server.reply(result)
        if isinstance(request, Subscribe) and Topic.STATE in request.topics and self.last:
            self._closed += self.server.send(result.client.connection, state_push(self.last))

    def decided(self, decision: Decision, records: list[dict[str, object]]) -> None:
        changed = self.last is None or (decision.state, decision.causes) != (
            self.last.state,
            self.last.causes,
        )
        self.last = decision
        if changed and self.server.subscribed(Topic.STATE):
            self._closed += self.server.broadcast(Topic.STATE, state_push(decision))
        if records and self.server.subscribed(Topic.RECORDS):
            for entry in records:
                self._closed += self.server.broadcast(Topic.RECORDS, record_push(entry))

    def received(self, message: Message | HidInput) -> None:
        if isinstance(message, HidInput):
            return
        topic = message_topic(message)
        if topic is not None and self.server.subscribed(topic):
            self._closed += self.server.broadcast(topic, message_push(message))  # type: ignore[arg-type]

    def close(self) -> None:
        self.server.close()
