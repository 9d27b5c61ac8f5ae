"""The acknowledgement: what the robot's supervisor says happened, not an echo (SR-13.15).

The agent builds it from the daemon's ``fleet_stop`` reply (docs/api.md "fleet_stop") and
publishes it to ``srcs/<fleet>/ack/<robot>``:

    {"v": 1, "robot": "robot-a", "stop_id": "...", "kind": "stop", "result": "stopped",
     "state": "STOPPED", "outputs": [{"name": "drive", "level": false, "readback": false}],
     "record_seq": 42, "arrival_to_off_ms": 0.41, "agent_ms": 1.9, "reason": null}

``result`` is the agent's judgement of the daemon's facts: ``stopped`` only when the state is
STOPPED and every output reads back off (its ``readback``; its commanded ``level`` where it has
no read-back); ``not_stopped`` otherwise, with ``reason`` saying why (an output that reads back
on, the state, the daemon's refusal, a daemon the agent cannot reach, a refused message:
``stale``, ``replayed``, ...). A release's acknowledgement is ``released`` with the state as
it is (still STOPPED: only the operator's takeover re-arms). The console reads
acknowledgements with :func:`parse`, which never raises: another robot's (or a broken
agent's) payload is typed or refused.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Final

from supervisord.fleet_agent.topics import valid_name

VERSION: Final = 1
RESULTS: Final = frozenset({"stopped", "not_stopped", "released", "refused"})
MAX_OUTPUTS: Final = 64
MAX_TEXT: Final = 200


@dataclass(frozen=True, slots=True)
class OutputState:
    name: str
    level: bool | None
    readback: bool | None

    @property
    def off(self) -> bool:
        """Off by its read-back, or by its commanded level where it reads nothing back."""
        seen = self.readback if self.readback is not None else self.level
        return seen is False


@dataclass(frozen=True, slots=True)
class Ack:
    robot: str
    stop_id: str | None
    kind: str
    result: str
    state: str | None = None
    outputs: tuple[OutputState, ...] = field(default_factory=tuple)
    record_seq: int | None = None
    arrival_to_off_ms: float | None = None
    agent_ms: float | None = None
    reason: str | None = None

    def encode(self) -> bytes:
        return json.dumps(
            {
                "v": VERSION,
                "robot": self.robot,
                "stop_id": self.stop_id,
                "kind": self.kind,
                "result": self.result,
                "state": self.state,
                "outputs": [
                    {"name": o.name, "level": o.level, "readback": o.readback} for o in self.outputs
                ],
                "record_seq": self.record_seq,
                "arrival_to_off_ms": self.arrival_to_off_ms,
                "agent_ms": self.agent_ms,
                "reason": self.reason,
            },
            separators=(",", ":"),
        ).encode()


def judge(state: str | None, outputs: tuple[OutputState, ...]) -> str | None:
    """``None`` when these facts are a stop, else why not (SR-13.15)."""
    if state != "STOPPED":
        return f"state {state or 'unknown'}"
    read_on = [o.name for o in outputs if o.readback is True]
    if read_on:
        return "output reads back on: " + ", ".join(read_on)
    # Not read back (not acquired, or a category-1 power output still braking): its level.
    still_on = [o.name for o in outputs if not o.off]
    if still_on:
        return "output still on, not read back: " + ", ".join(still_on)
    return None


def from_reply(robot: str, kind: str, stop_id: str, reply: dict[str, Any], agent_ms: float) -> Ack:
    """The acknowledgement of the daemon's successful reply to ``fleet_stop`` or
    ``fleet_release`` (fields it lacks or mistypes are left out, and judged so)."""
    state = _text(reply.get("state"))
    outputs = _outputs(reply.get("outputs"))
    if kind == "release":
        result, reason = "released", None
    else:
        reason = judge(state, outputs)
        result = "stopped" if reason is None else "not_stopped"
    return Ack(
        robot,
        stop_id,
        kind,
        result,
        state,
        outputs,
        _int(reply.get("record_seq")),
        _number(reply.get("arrival_to_off_ms")),
        round(agent_ms, 3),
        reason,
    )


def failed(
    robot: str, kind: str, stop_id: str | None, reason: str, agent_ms: float, *, refused: bool
) -> Ack:
    """The acknowledgement of a stop that did not reach the outputs: the agent refused the
    message (``refused``: ``replayed``, ``stale``, a malformed payload), or the daemon refused
    it or could not be reached (``not_stopped``)."""
    result = "refused" if refused else "not_stopped"
    return Ack(robot, stop_id, kind, result, reason=reason[:MAX_TEXT], agent_ms=round(agent_ms, 3))


def parse(payload: bytes) -> Ack | None:
    """An acknowledgement, or ``None`` for anything that is not one."""
    try:
        obj = json.loads(payload)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return None
    if not isinstance(obj, dict) or obj.get("v") != VERSION:
        return None
    robot, result = obj.get("robot"), obj.get("result")
    if not isinstance(robot, str) or not valid_name(robot) or result not in RESULTS:
        return None
    return Ack(
        robot,
        _text(obj.get("stop_id")),
        _text(obj.get("kind")) or "?",
        str(result),
        _text(obj.get("state")),
        _outputs(obj.get("outputs")),
        _int(obj.get("record_seq")),
        _number(obj.get("arrival_to_off_ms")),
        _number(obj.get("agent_ms")),
        _text(obj.get("reason")),
    )


def _outputs(value: object) -> tuple[OutputState, ...]:
    if not isinstance(value, list):
        return ()
    found = []
    for item in value[:MAX_OUTPUTS]:
        if isinstance(item, dict) and isinstance(name := item.get("name"), str):
            found.append(
                OutputState(name[:MAX_TEXT], _flag(item.get("level")), _flag(item.get("readback")))
            )
    return tuple(found)


def _flag(value: object) -> bool | None:
    return value if isinstance(value, bool) else None


def _text(value: object) -> str | None:
    return value[:MAX_TEXT] if isinstance(value, str) else None


def _int(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _number(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None
