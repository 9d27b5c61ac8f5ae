"""A minimal VSC for the daemon's tests: heartbeats in a chosen mode, key 85 answered with 1.

(The full simulated VSC with its remote is ``srcs-sim``.)"""

from __future__ import annotations

import time

from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import FeedbackGet, FeedbackSet, VscHeartbeat
from supervisord.testkit.pty_port import PtyPort


class VscPeer:
    """The VSC end of the pty: heartbeats every 50 ms in the current mode, key 85 = 1."""

    def __init__(self, port: PtyPort) -> None:
        self.port = port
        self.mode = VscMode.LOCAL
        self.estop = 0
        self.silent = False
        self.received: list[object] = []
        self._decoder = FrameDecoder()
        self._next = 0.0

    def serve(self) -> None:
        now = time.monotonic()
        if not self.port.plugged:
            return
        for message in self._decoder.feed(self.port.read()):
            self.received.append(message)
            if message == FeedbackGet(85):
                self.port.write(encode_frame(FeedbackSet(85, 1)))
        if not self.silent and now >= self._next:
            self._next = now + 0.05
            self.port.write(encode_frame(VscHeartbeat(self.mode, 0, self.estop)))
