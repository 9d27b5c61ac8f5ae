"""Commissioning a VSC: switch its key-85 watchdog on and its remote-status messages on.

Both settings are stored permanently by the VSC (manual §8.3.6 and table 13), so this is a
separate, explicit step that an admin asks for (``srcsctl commission``, SR-5),
never something the daemon does on its own. The procedure writes, then reads back:

1. Feedback Set key 85 = 1 and Message Control 0x22 enabled every 1000 ms (the manual's
   default rate for remote status);
2. Feedback Get key 85 every 250 ms until the VSC answers 1 (it answers a Get with a Set of the
   same key, manual §8.3.8), and waits for a remote-status message to prove the second write;
3. ends when both are confirmed or after :data:`TIMEOUT_NS`, with what it saw.

Pure: the caller passes the time and the VSC's messages in and sends the frames it returns.
"""

from __future__ import annotations

from typing import Final

from supervisord.protocol.codes import FeedbackKey, MessageType
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    Message,
    MessageControl,
    RemoteStatus,
)
from supervisord.safety.events import Caller, Commissioned
from supervisord.timebase import NS_PER_MS

TIMEOUT_NS: Final = 3_000 * NS_PER_MS  # remote status comes once a second: room for two
ASK_EVERY_NS: Final = 250 * NS_PER_MS  # the manual allows Feedback Get at up to 20 Hz
REMOTE_STATUS_INTERVAL_MS: Final = 1_000


class Commissioning:
    """One run of the procedure for ``caller``, started at ``now``."""

    def __init__(self, caller: Caller, now: int) -> None:
        self.caller = caller
        self.deadline = now + TIMEOUT_NS
        self.key85: int | None = None
        self.remote_status = False
        self._writes: list[Message] = [
            FeedbackSet(FeedbackKey.USER_ESTOP_TIMEOUT, 1),
            MessageControl(MessageType.REMOTE_STATUS, 1, REMOTE_STATUS_INTERVAL_MS),
        ]
        self._next_ask = now

    def received(self, message: Message) -> None:
        """A valid message from the VSC: a key-85 answer or a remote status counts."""
        if isinstance(message, FeedbackSet) and message.key == FeedbackKey.USER_ESTOP_TIMEOUT:
            if not self._writes:  # only answers to our own Get, after the write went out
                self.key85 = message.value
        elif isinstance(message, RemoteStatus):
            self.remote_status = True

    def confirmed(self) -> bool:
        return self.key85 == 1 and self.remote_status

    def finished(self, now: int) -> bool:
        return self.confirmed() or now >= self.deadline

    def due(self, now: int) -> list[Message]:
        """The frames to send now: the writes once, then a Get of key 85 until it reads 1."""
        frames, self._writes = self._writes, []
        if self.key85 != 1 and now >= self._next_ask:
            frames.append(FeedbackGet(FeedbackKey.USER_ESTOP_TIMEOUT))
            self._next_ask = now + ASK_EVERY_NS
        return frames

    def next_deadline(self) -> int:
        """When ``due`` has work: at once when confirmed (to answer), else the next Get."""
        if self.confirmed():
            return 0
        return self.deadline if self.key85 == 1 else min(self._next_ask, self.deadline)

    def outcome(self, now: int) -> Commissioned:
        """The event for the safety core, which records it."""
        return Commissioned(now, self.caller, self.key85, self.remote_status)
