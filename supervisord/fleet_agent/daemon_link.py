"""The agent's one request to the supervisor: ``fleet_stop`` or ``fleet_release`` over the
client API's socket (docs/api.md), and its reply (SR-13.13).

Only these two ops (and ``fleet_keepalive``) are ever sent, built here from a parsed
:class:`~.message.StopMessage`: no text from the network becomes an op, so nothing that
arrives over it can ask the daemon to re-arm, commission or switch an output on. A connection
per request, without ``hello`` (the agent is never a required client: its absence cannot stop
the robot, as the exporter's cannot, docs/fleet.md "srcs-exporter"); a deadline on the
monotonic clock; every failure is a :class:`LinkFailed` with a stable reason, never another
exception.
"""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path
from typing import Any, Final

OPS: Final = {"stop": "fleet_stop", "release": "fleet_release", "keepalive": "fleet_keepalive"}
MAX_LINE: Final = 1 << 20


class LinkFailed(Exception):
    """The request got no successful reply: ``reason`` says why in a word or two."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def request(socket_path: Path, op: str, fields: dict[str, str], timeout: float) -> dict[str, Any]:
    """Send ``op`` (one of :data:`OPS`' values) with ``fields`` and
    return the daemon's successful reply."""
    if op not in OPS.values():
        raise LinkFailed(f"op {op} is not the agent's")  # never from the network (see above)
    deadline = time.monotonic() + timeout
    line = json.dumps({"op": op, **fields, "id": 1}).encode() + b"\n"
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(timeout)
            sock.connect(str(socket_path))
            sock.sendall(line)
            return _reply(sock, deadline)
    except TimeoutError:
        raise LinkFailed("supervisor did not answer in time") from None
    except OSError as e:
        raise LinkFailed(f"supervisor unreachable: {e.strerror or e}") from None


def _reply(sock: socket.socket, deadline: float) -> dict[str, Any]:
    buffer = b""
    while True:
        newline = buffer.find(b"\n")
        if newline >= 0:
            raw, buffer = buffer[:newline], buffer[newline + 1 :]
            try:
                obj = json.loads(raw)
            except (ValueError, UnicodeDecodeError, RecursionError):
                raise LinkFailed("supervisor sent a line that is not JSON") from None
            if not isinstance(obj, dict) or "event" in obj:
                continue  # a push: not subscribed, but tolerated
            if obj.get("ok") is True:
                return obj
            code, why = obj.get("code"), obj.get("reason")
            text = code if isinstance(code, str) else "?"
            raise LinkFailed(
                f"supervisor refused: {text}" + (f" ({why})" if isinstance(why, str) else "")
            )
        if len(buffer) > MAX_LINE:
            raise LinkFailed("supervisor sent too long a line")
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError
        sock.settimeout(remaining)
        data = sock.recv(65536)
        if not data:
            raise LinkFailed("supervisor closed the connection")
        buffer += data
