"""A minimal VSC for the daemon's tests: heartbeats in a chosen mode, key 85 kept and answered
as the manual says (manual §8.3.7-8.3.8), remote status once enabled by Message Control (§8.3.6),
and the key-85 watchdog: bit 7 of the e-stop word while key 85 is 1 and no user heartbeat
came for 500 ms (manual §8.3.5), which the supervisor's proof test looks for (SR-5.3).

(The full simulated VSC with its remote is ``srcs-sim``.)"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator

from supervisord.protocol.codes import FeedbackKey, MessageType, VscMode
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    MessageControl,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.sim.pty import PtyPort

KEY85 = FeedbackKey.USER_ESTOP_TIMEOUT


class VscPeer:
    """The VSC end of the pty: heartbeats every 50 ms in the current mode, by ``clock``
    (monotonic seconds; a test that drives the daemon's clock gives the peer the same one)."""

    def __init__(
        self, port: PtyPort, key85: int = 1, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.port = port
        self.clock = clock
        self.mode = VscMode.LOCAL
        self.estop = 0
        self.silent = False
        self.key85 = key85
        self.answers_feedback = True
        self.remote_status_ms: int | None = None  # off, as the VSC ships (manual table 5)
        self.battery = 80  # the remote's battery percent in each remote status
        self.burst = 1  # heartbeats sent back to back in one write (a VSC's queue after a stall)
        self.written = 0  # bytes sent so far (a test waits until the daemon's side has them)
        self.received: list[object] = []
        self._decoder = FrameDecoder()
        self._next = 0.0
        self._next_status = 0.0
        self._last_user = clock()  # the watchdog counts from power-on

    @property
    def next_due(self) -> float:
        """When (by ``clock``) the next heartbeat is due."""
        return self._next

    def serve(self) -> bool:
        """Read what the daemon sent, answer it, send what is due; whether anything was sent."""
        now = self.clock()
        if not self.port.plugged:
            return False
        sent = False
        for message in self._decoder.feed(self.port.read()):
            self.received.append(message)
            sent = self._handle(message) or sent
        if self.silent:
            return sent
        if now >= self._next:
            self._next = now + 0.05
            timed_out = self.key85 == 1 and now - self._last_user >= 0.5
            word = self.estop | (0x80 if timed_out else 0)
            self._send(encode_frame(VscHeartbeat(self.mode, 0, word)) * self.burst)
            sent = True
        if self.remote_status_ms is not None and now >= self._next_status:
            self._next_status = now + self.remote_status_ms / 1000
            self._send(encode_frame(RemoteStatus(self.battery)))
            sent = True
        return sent

    def _send(self, data: bytes) -> None:
        self.port.write(data)
        self.written += len(data)

    def _handle(self, message: object) -> bool:
        """Act on one message from the daemon; whether an answer was sent."""
        if isinstance(message, UserHeartbeat):
            self._last_user = self.clock()
        elif isinstance(message, FeedbackSet) and message.key == KEY85:
            self.key85 = message.value
        elif message == FeedbackGet(KEY85) and self.answers_feedback:
            self._send(encode_frame(FeedbackSet(KEY85, self.key85)))
            return True
        elif (
            isinstance(message, MessageControl)
            and message.message_type == MessageType.REMOTE_STATUS
        ):
            self.remote_status_ms = message.interval if message.enabled else None
        return False

    @contextlib.contextmanager
    def serving(self) -> Iterator[None]:
        """Serve from a thread while the test blocks on a client call."""
        done = threading.Event()

        def loop() -> None:
            while not done.is_set():
                self.serve()
                time.sleep(0.005)

        thread = threading.Thread(target=loop, daemon=True)
        thread.start()
        try:
            yield
        finally:
            done.set()
            thread.join()
