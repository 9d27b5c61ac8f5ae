"""The request to end the loop: whether one was made, by which signal, and what the exit says.

A signal handler (:mod:`~supervisord.daemon.signals`) or an embedding program asks; the loop
checks :attr:`StopRequest.asked` between turns, records the stop ``shutdown:REASON`` with
:meth:`StopRequest.reason` (SR-7.14) and exits with :meth:`StopRequest.exit_status` (SR-6.6).
The first signal asked for decides both: a second one during the shutdown changes nothing.
It holds two values and calls nothing back (waking the loop is the loop's own).
"""

from __future__ import annotations

import logging

from supervisord.daemon import signals

__all__ = ["StopRequest"]

log = logging.getLogger("srcsd")


class StopRequest:
    """Whether the loop was asked to end, and the first signal that asked (SR-6.6)."""

    __slots__ = ("asked", "signum")

    def __init__(self) -> None:
        self.asked = False
        self.signum: int | None = None  # the first signal that asked, ``None``: none did

    def ask(self, signum: int | None = None) -> None:
        """Asked to end, by signal ``signum`` or (``None``) without one. Only sets values: it
        runs in a signal handler. The first signal asked for stays (SR-6.6)."""
        if self.signum is None:
            self.signum = signum
        self.asked = True

    def reason(self) -> str:
        """The ``shutdown:REASON`` stop's REASON (SR-7.14): the signal that asked
        (``SIGTERM``), ``requested`` when asked without one (an embedding program), ``error``
        when not asked at all (an exception ended the run)."""
        if self.signum is not None:
            return signals.name(self.signum)
        return "requested" if self.asked else "error"

    def log(self) -> None:
        """Log a stop asked by a signal (nothing when none did): info after SIGTERM or SIGINT,
        a warning after another. Before the shutdown, so that the sink drains it with the
        records (SR-7.5)."""
        if self.signum is not None:
            level = logging.INFO if self.signum in signals.CLEAN_EXIT else logging.WARNING
            log.log(level, "%s: stopping, every output off", signals.name(self.signum))

    def exit_status(self) -> int:
        """0 after SIGTERM or SIGINT or without a signal, 128 + N after another signal N."""
        return 0 if self.signum is None else signals.exit_status(self.signum)
