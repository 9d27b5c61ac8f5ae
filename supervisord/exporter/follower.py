"""The socket edge: follow srcsd's API and feed the model, reconnecting for ever.

One thread, one connection, no ``hello``: the exporter is an anonymous client, never a
required one, so its absence, a hang or a crash can never stop the robot (SR-8;
docs/api.md "hello"). It subscribes to ``state``, ``records`` and ``remote_status`` (not
``joystick``: 20-50 messages a second that no metric needs) and asks for ``status`` every
``poll`` seconds, because the loop's counters (messages, rejections, link, record errors) come
only in the ``status`` reply. It keeps reading its pushes, so the daemon never has to drop it
for a full buffer (docs/api.md "Limits").

Whatever goes wrong with the connection (no socket, no permission, the daemon stops or closes
it, a reply that does not come) ends the connection: the model forgets the daemon's values
(``srcs_up`` 0) and the follower tries again after a backoff of ``retry_min`` doubling to
``retry_max`` seconds.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

from supervisord.api.framing import ApiError
from supervisord.client import ClientError, SupervisorClient
from supervisord.exporter.model import ExporterModel

log = logging.getLogger("srcs-exporter")

TOPICS = ("state", "records", "remote_status")


class Follower:
    """Feeds ``model`` (under ``lock``) from the socket at ``path`` until ``stop`` is set."""

    def __init__(
        self,
        path: Path,
        model: ExporterModel,
        lock: threading.Lock,
        *,
        poll: float = 1.0,
        timeout: float = 2.0,
        retry_min: float = 0.2,
        retry_max: float = 5.0,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.path, self.model, self.lock = path, model, lock
        self.poll, self.timeout = poll, timeout
        self.retry_min, self.retry_max = retry_min, retry_max
        self.clock = clock
        self._last_problem: str | None = None

    def run(self, stop: threading.Event) -> None:
        """Connect, follow, reconnect, until ``stop`` is set."""
        retry = self.retry_min
        while not stop.is_set():
            try:
                client = SupervisorClient.connect(self.path, timeout=self.timeout)
            except ClientError as e:
                self._problem(str(e))
                stop.wait(retry)
                retry = min(self.retry_max, retry * 2)
                continue
            retry = self.retry_min
            try:
                self._follow(client, stop)
            except (ClientError, ApiError) as e:
                self._problem(str(e))
            except Exception:
                # The last net: the model takes any reply without raising, but if a defect
                # ever made it raise, the exporter says srcs_up 0 and starts over rather than
                # serve values it no longer follows.
                log.exception("the follower failed; reconnecting")
            finally:
                client.close()
                with self.lock:
                    self.model.disconnected()
            stop.wait(self.retry_min)

    def _follow(self, client: SupervisorClient, stop: threading.Event) -> None:
        with self.lock:
            self.model.connected()
        # Subscribe first: a record written between the two requests is then pushed, not lost.
        client.subscribe(*TOPICS)
        self._status(client)
        if self._last_problem is not None:
            log.info("connected to %s", self.path)
            self._last_problem = None
        next_poll = time.monotonic() + self.poll
        while not stop.is_set():
            push = client.next_event(timeout=max(0.0, min(0.5, next_poll - time.monotonic())))
            if push is not None:
                with self.lock:
                    self.model.push(push, self.clock())
            if time.monotonic() >= next_poll:
                self._status(client)
                next_poll = max(next_poll + self.poll, time.monotonic())

    def _status(self, client: SupervisorClient) -> None:
        reply = client.status()
        with self.lock:
            self.model.status(reply)

    def _problem(self, text: str) -> None:
        """Log a connection problem once, not at every retry."""
        if text != self._last_problem:
            log.warning("srcsd not reachable: %s", text)
            self._last_problem = text
