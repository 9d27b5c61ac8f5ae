"""The agent's loop: a stop from the broker becomes the daemon's ``fleet_stop``, and its reply
the robot's acknowledgement (SR-13.13, SR-13.14, SR-13.15).

:class:`Agent` is the pure decision for one message (route, parse, replay window) plus the
request and the acknowledgement; the caller (:mod:`supervisord.cli.fleet_agent`) feeds it the
messages of :mod:`.mqtt_edge` and publishes what it returns. Nothing here raises on input: a
message for another robot is ignored (the broker's ACL should never deliver one), anything else
refused is acknowledged with its reason so the console can name it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from supervisord.fleet_agent import ack as acks
from supervisord.fleet_agent import daemon_link, message
from supervisord.fleet_agent.replay import ReplayGuard
from supervisord.fleet_agent.topics import parse_stop_topic

Requester = Callable[[str, dict[str, str]], dict[str, Any]]
"""``(op, fields) -> reply``: the daemon's successful reply, or :class:`LinkFailed`."""


@dataclass
class Agent:
    fleet: str
    robot: str
    groups: frozenset[str]
    request: Requester
    guard: ReplayGuard

    def handle(
        self,
        topic: str,
        payload: bytes,
        *,
        retained: bool,
        arrived: float,
        now_utc: Callable[[], float] = time.time,
        now_mono: Callable[[], float] = time.monotonic,
    ) -> acks.Ack | None:
        """The acknowledgement to publish for one message, or ``None`` when it is not for
        this robot (``arrived``: the monotonic time it was received)."""
        target = parse_stop_topic(self.fleet, topic)
        if target is None or not target.covers(self.robot, self.groups):
            return None
        parsed = message.parse(payload)
        if isinstance(parsed, message.Refused):
            ms = (now_mono() - arrived) * 1000
            return acks.failed(self.robot, "?", parsed.stop_id, parsed.reason, ms, refused=True)
        why = "retained" if retained else self.guard.check(parsed, now_utc(), now_mono())
        if why is not None:
            ms = (now_mono() - arrived) * 1000
            return acks.failed(self.robot, parsed.kind, parsed.stop_id, why, ms, refused=True)
        fields = {"stop_id": parsed.stop_id, "sender": parsed.sender}
        try:
            reply = self.request(daemon_link.OPS[parsed.kind], fields)
        except daemon_link.LinkFailed as e:
            ms = (now_mono() - arrived) * 1000
            return acks.failed(self.robot, parsed.kind, parsed.stop_id, e.reason, ms, refused=False)
        ms = (now_mono() - arrived) * 1000
        return acks.from_reply(self.robot, parsed.kind, parsed.stop_id, reply, ms)


def socket_requester(socket_path: Path, timeout: float) -> Requester:
    def request(op: str, fields: dict[str, str]) -> dict[str, Any]:
        return daemon_link.request(socket_path, op, fields, timeout)

    return request
