"""The loop's side of the reflex (SR-9.5; docs/performance.md "The reflex"): a stopping VSC
heartbeat's outputs written off before the core's full step, and those writes handed to the
decision that follows.

The safety core gives, from the state it is in, the outputs a VSC heartbeat switches off at
once (:mod:`supervisord.safety.reflex`). For a heartbeat whose mode or e-stop word differ from
the last one's, read when time decides nothing else (``SafetyCore.reflex``),
:meth:`EarlyOff.heard` writes those outputs off; the loop then feeds the heartbeat to the core
as always, and applies the decision with :meth:`EarlyOff.take`: the early writes count as that
decision's writes (their read-backs go back to the core after it, as every write's do; the
stop's times to off are theirs), and the decision's own write of an output already off is
skipped, as for any output already at its level. Records, frames, pushes follow the decision,
as before.

Only ever off, never on. A failure here is logged and changes nothing else: the full step
follows and decides the stop, as it would without the reflex.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping

from supervisord.daemon.stoptimes import StopTimes
from supervisord.outputs.base import Output, ReadBack
from supervisord.protocol.messages import VscHeartbeat
from supervisord.safety.core import SafetyCore

log = logging.getLogger("srcsd")


class EarlyOff:
    """The outputs the reflex wrote off ahead of the full step, until its decision takes them."""

    def __init__(self, outputs: Mapping[str, Output], clock: Callable[[], int]) -> None:
        self._outputs = outputs
        self._clock = clock
        self._word: tuple[int, int] | None = None  # the last heartbeat's mode and e-stop word
        self.written: list[tuple[ReadBack, int]] = []  # each write, and when it returned

    def heard(self, message: VscHeartbeat, now: int, core: SafetyCore) -> None:
        """A VSC heartbeat read at ``now``, before the core is fed it: switch off at once what
        the core's reflex names for it (SR-9.5)."""
        word = (message.mode, message.estop)
        if word == self._word:
            return  # the state already answers this word: nothing goes off (the usual case)
        self._word = word
        try:
            reflex = core.reflex(now)
            if reflex is None:
                return  # time decides too (a timeout is due): the full step alone
            for name in reflex.off(message.mode, message.estop, now):
                output = self._outputs.get(name)
                if output is not None and output.is_open and output.requested:
                    readback = output.set(False, now)
                    self.written.append((readback, self._clock()))
        except Exception:  # the full step follows and stops anyway (SR-9.5)
            log.exception("the reflex failed; the core's full step decides the stop")

    def wrote(self, name: str) -> bool:
        """Whether ``name`` was written off ahead of the decision being applied."""
        return any(readback.name == name for readback, _ in self.written)

    def take(self, readbacks: list[ReadBack], times: StopTimes) -> int:
        """Hand the early writes to the decision being applied: their read-backs onto
        ``readbacks`` (the core is fed them after the decision, as every write's), their times
        to off to ``times`` (SR-12.1). Returns when the last write returned."""
        written, self.written = self.written, []
        for readback, returned in written:
            readbacks.append(readback)
            if times.waiting(readback.name):
                times.off(readback, returned)
        return written[-1][1]
