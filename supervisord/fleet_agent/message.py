"""A fleet stop's payload, as the console sends it and the agent reads it (SR-13.14).

    {"v": 1, "kind": "stop", "stop_id": "...", "sender": "console-1",
     "sent_utc": 1765000000.123, "nonce": "32 hex digits"}

``kind`` is ``stop``, ``release`` (the console withdraws its request; the robot stays STOPPED
until the operator's takeover, docs/fleet.md) or ``keepalive`` (the console is there, for a
robot whose config requires it, SR-8.21; its ``stop_id`` is the word ``keepalive``): no other
kind exists, so nothing read here can ask for anything else (SR-13.13). ``sent_utc``: the
console's wall clock at the send, seconds since the epoch, for the replay window
(:mod:`.replay`); ``nonce``: fresh for each send, so a console's retry of the same ``stop_id``
is a new message and a captured one sent again is not. Every payload is another machine's:
:func:`parse` returns a typed :class:`Refused` for anything else and never raises.
"""

from __future__ import annotations

import json
import math
import re
import secrets
from dataclasses import dataclass
from typing import Final

from supervisord.fleet_agent.topics import valid_name

VERSION: Final = 1
KINDS: Final = frozenset({"stop", "release", "keepalive"})
MAX_PAYLOAD: Final = 1024
_STOP_ID: Final = re.compile(r"[A-Za-z0-9._:-]{1,64}")
_NONCE: Final = re.compile(r"[0-9a-f]{16,64}")


@dataclass(frozen=True, slots=True)
class StopMessage:
    kind: str
    stop_id: str
    sender: str
    sent_utc: float
    nonce: str

    def encode(self) -> bytes:
        return json.dumps(
            {
                "v": VERSION,
                "kind": self.kind,
                "stop_id": self.stop_id,
                "sender": self.sender,
                "sent_utc": self.sent_utc,
                "nonce": self.nonce,
            },
            separators=(",", ":"),
        ).encode()


@dataclass(frozen=True, slots=True)
class Refused:
    """Why a payload is no stop: a stable ``reason`` word, and the ``stop_id`` when one was
    readable (so the console can name its refused stop)."""

    reason: str
    stop_id: str | None = None


def new_message(kind: str, stop_id: str, sender: str, sent_utc: float) -> StopMessage:
    """A console's message with a fresh nonce (16 random bytes)."""
    return StopMessage(kind, stop_id, sender, sent_utc, secrets.token_hex(16))


def new_stop_id(sender: str, sent_utc: float) -> str:
    """A stop's id: the console's name, its send time and 4 random bytes; readable in a
    record (the daemon records it with the sender) and unique without coordination."""
    return f"{sender}-{int(sent_utc)}-{secrets.token_hex(4)}"[-64:]


def parse(payload: bytes) -> StopMessage | Refused:
    """The message ``payload`` carries, or why it is none."""
    if len(payload) > MAX_PAYLOAD:
        return Refused("too_long")
    try:
        obj = json.loads(payload)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return Refused("not_json")
    if not isinstance(obj, dict):
        return Refused("not_an_object")
    stop_id = obj.get("stop_id")
    sid = stop_id if isinstance(stop_id, str) and _STOP_ID.fullmatch(stop_id) else None
    if obj.get("v") != VERSION:
        return Refused("version", sid)
    kind, sender, sent, nonce = (obj.get(k) for k in ("kind", "sender", "sent_utc", "nonce"))
    if kind not in KINDS:
        return Refused("kind", sid)
    if sid is None:
        return Refused("stop_id")
    if not isinstance(sender, str) or not valid_name(sender):
        return Refused("sender", sid)
    # bool is an int: true is no time.
    if isinstance(sent, bool) or not isinstance(sent, int | float) or not math.isfinite(sent):
        return Refused("sent_utc", sid)
    if not isinstance(nonce, str) or not _NONCE.fullmatch(nonce):
        return Refused("nonce", sid)
    return StopMessage(str(kind), sid, sender, float(sent), nonce)
