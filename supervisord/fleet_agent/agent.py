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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from supervisord.fleet_agent import ack as acks
from supervisord.fleet_agent import daemon_link, message
from supervisord.fleet_agent.replay import SKEW_S, ReplayGuard
from supervisord.fleet_agent.topics import parse_robot_topic, parse_stop_topic

KEEPALIVE_WINDOW_S = 2.0
"""How old a console's keepalive may be (by the robot's wall clock) and still count: a
keepalive held back or sent again must not keep a robot going whose console is gone
(SR-8.21), so its window is short; a robot whose clock is off by more than this from the
console's hears none and stops, which is the safe side."""

Requester = Callable[[str, dict[str, str]], dict[str, Any]]
"""``(op, fields) -> reply``: the daemon's successful reply, or :class:`LinkFailed`."""


@dataclass
class Agent:
    fleet: str
    robot: str
    groups: frozenset[str]
    request: Requester
    guard: ReplayGuard
    keepalives: ReplayGuard = field(
        default_factory=lambda: ReplayGuard(KEEPALIVE_WINDOW_S, min(SKEW_S, KEEPALIVE_WINDOW_S))
    )
    keepalive_error: str = ""
    """Why the last keepalive was not passed on ("" when it was): the caller logs changes."""

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
        console = parse_robot_topic(self.fleet, topic, "keepalive")
        if console is not None:
            self._keepalive(console, payload, retained, now_utc(), now_mono())
            return None
        target = parse_stop_topic(self.fleet, topic)
        if target is None or not target.covers(self.robot, self.groups):
            return None
        parsed = message.parse(payload)
        if not isinstance(parsed, message.Refused) and parsed.kind == "keepalive":
            parsed = message.Refused("kind", parsed.stop_id)  # only on a keepalive topic
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

    def _keepalive(
        self, console: str, payload: bytes, retained: bool, now_utc: float, now_mono: float
    ) -> None:
        """Pass a console's fresh keepalive on as ``fleet_keepalive`` (no acknowledgement:
        the robot's own timeout judges the console, SR-8.21)."""
        parsed = message.parse(payload)
        if isinstance(parsed, message.Refused):
            self.keepalive_error = f"keepalive refused: {parsed.reason}"
        elif parsed.kind != "keepalive" or parsed.sender != console:
            self.keepalive_error = "keepalive refused: not the topic's console"
        elif retained:
            self.keepalive_error = "keepalive refused: retained"
        elif why := self.keepalives.check(parsed, now_utc, now_mono):
            self.keepalive_error = f"keepalive refused: {why}"
        else:
            try:
                self.request(daemon_link.OPS["keepalive"], {"sender": parsed.sender})
                self.keepalive_error = ""
            except daemon_link.LinkFailed as e:
                self.keepalive_error = f"keepalive not passed on: {e.reason}"


def socket_requester(socket_path: Path, timeout: float) -> Requester:
    def request(op: str, fields: dict[str, str]) -> dict[str, Any]:
        return daemon_link.request(socket_path, op, fields, timeout)

    return request
