"""The bridge's connection to the supervisor: ``supervisord.client`` with reconnects.

No ROS here, and no thread: the rclpy edge calls it from its executor's timers, so a stalled
executor stalls the heartbeats too and the supervisor stops the robot (docs/ros2.md
"Heartbeat"). Every call returns at once or within the client's timeout; nothing raises. What
happened comes out as events (:meth:`SupervisorLink.take`): ``Connected``, ``Lost`` and the
pushes of the topics the bridge subscribes to.
"""

from __future__ import annotations

import select
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Union

from supervisord.api.framing import ApiError
from supervisord.client import ClientError, Push, StatusReply, SupervisorClient

TOPICS: Final = ("state", "joystick", "gps", "remote_status")
MAX_PUSHES_PER_CALL: Final = 256  # the executor's other callbacks get their turn
READ_SLICE_S: Final = 0.02  # how long a read may wait for the rest of a line it began


@dataclass(frozen=True, slots=True)
class Connected:
    """Connected, named, subscribed: ``status`` is the first ``status`` reply."""

    status: StatusReply


@dataclass(frozen=True, slots=True)
class Lost:
    """The connection ended (or a connect failed when it was up): ``reason`` for people."""

    reason: str


LinkEvent = Union[Connected, Lost, Push]  # noqa: UP007 -- the alias is evaluated on Python 3.10 too
"""What the bridge's link to the socket reports (the safety core's events are another thing)."""
Connect = Callable[..., SupervisorClient]


class SupervisorLink:
    """One named connection to the socket at ``path``, made again ``retry_s`` after it fails.

    ``timeout`` bounds every request (and so every call here). Requests while disconnected
    fail with a reason; they are not queued, because a stop asked for while the supervisor
    cannot be reached is already in force (the robot cannot run without ``srcsd``)."""

    def __init__(
        self,
        path: str | Path,
        name: str,
        *,
        timeout: float = 0.5,
        retry_s: float = 0.5,
        connect: Connect = SupervisorClient.connect,
    ) -> None:
        self.path = str(path)
        self.name = name
        self.timeout = timeout
        self.retry_s = retry_s
        self._connect = connect
        self._client: SupervisorClient | None = None
        self._next_try = 0.0
        self._events: deque[LinkEvent] = deque()
        self.reason = "not connected yet"

    @property
    def connected(self) -> bool:
        return self._client is not None

    def take(self) -> list[LinkEvent]:
        """The events since the last call, oldest first."""
        events = list(self._events)
        self._events.clear()
        return events

    def service(self, now: float) -> None:
        """Connect when disconnected and a retry is due (``now``: monotonic seconds); read
        the pushes that have arrived."""
        if self._client is None and now >= self._next_try:
            self._next_try = now + self.retry_s
            self._open()
        if self._client is not None:
            self._drain(self._client)

    def heartbeat(self) -> bool:
        """One heartbeat; False when disconnected or it failed (then ``Lost``)."""
        return self._call(lambda client: client.heartbeat())[0]

    def status(self) -> StatusReply | None:
        """A ``status`` reply, or None when disconnected or it failed."""
        ok, reply = self._call(lambda client: client.status())
        return reply if ok and isinstance(reply, StatusReply) else None

    def request(self, call: Callable[[SupervisorClient], object]) -> tuple[bool, str]:
        """Run one request; (True, "") or (False, why). A refusal (``ApiError``) keeps the
        connection; a broken connection is ``Lost``."""
        ok, result = self._call(call)
        return ok, "" if ok else str(result)

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    # -- inside ---------------------------------------------------------------------------

    def _open(self) -> None:
        try:
            client = self._connect(self.path, name=self.name, timeout=self.timeout)
        except (ClientError, ApiError, OSError) as e:
            self.reason = _why(e)  # e.g. name_in_use while the old connection is still seen
            return
        try:
            client.subscribe(*TOPICS)
            status = client.status()
        except (ClientError, ApiError, OSError) as e:
            client.close()
            self.reason = _why(e)
            return
        self._client = client
        self.reason = ""
        self._events.append(Connected(status))

    def _call(self, call: Callable[[SupervisorClient], object]) -> tuple[bool, object]:
        client = self._client
        if client is None:
            return False, f"supervisor unreachable: {self.reason}"
        try:
            result = call(client)
        except ApiError as e:
            return False, str(e)  # refused ("refused: ..."): the connection stays
        except (ClientError, OSError) as e:
            self._lose(_why(e))
            return False, f"supervisor unreachable: {self.reason}"
        except ValueError as e:
            return False, f"bad request: {e}"  # built wrong on our side; nothing was sent
        # The reply's read may have brought pushes along: hand them on in order.
        self._drain(client, read=False)
        return True, result

    def _drain(self, client: SupervisorClient, *, read: bool = True) -> None:
        try:
            for _ in range(MAX_PUSHES_PER_CALL):
                push = client.next_event(timeout=0)  # what was read already, no waiting
                if push is None and read and _readable(client):
                    push = client.next_event(timeout=READ_SLICE_S)
                if push is None:
                    return
                self._events.append(push)
        except (ClientError, ApiError, OSError) as e:
            self._lose(_why(e))

    def _lose(self, reason: str) -> None:
        self.close()
        self.reason = reason
        self._events.append(Lost(reason))


def _readable(client: SupervisorClient) -> bool:
    try:
        fd = client.fileno()
        return fd >= 0 and bool(select.select([fd], [], [], 0)[0])
    except (OSError, ValueError):
        return True  # let the read find out and report it


def _why(error: BaseException) -> str:
    return str(error) or type(error).__name__  # an ApiError reads "code: message"
