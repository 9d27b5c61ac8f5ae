"""The loop's face to the service manager (systemd's sd_notify(3), through
:class:`~supervisord.daemon.notify.Notifier`): READY, STATUS, WATCHDOG and STOPPING.

The loop tells it what happened and when; it answers with values (``next_watchdog``, the
status line) and never calls back into the loop:

- ``ready(now, decision)``: READY=1 once the startup decision is applied, its outputs off
  (SR-0.2, SR-6.5), with that decision's status line; the watchdog is due at once.
- ``decided(decision)``: the status line follows the decisions, sent only when its text
  changes, and worked out only when the state or the causes change (the loop checks the two
  by identity, so a decision of the core's cheap path costs nothing here, SR-9.4). A VSC whose
  key-85 watchdog answered off is said once, with its fix (SR-8.18).
- ``next_watchdog`` and ``watchdog(now)``: WATCHDOG=1 at half of WatchdogSec, as
  sd_watchdog_enabled(3) advises; the loop wakes for it like for any deadline, so a loop that
  hangs stops the keep-alives and systemd restarts it (SR-5).
- ``stopping()``: STOPPING=1 as the shutdown begins.
"""

from __future__ import annotations

import logging

from supervisord.api.readiness import DEFAULT_SRCSCTL, NO_ANSWER, commission_fix
from supervisord.daemon.notify import Notifier
from supervisord.safety.causes import CauseState
from supervisord.safety.decision import Decision
from supervisord.safety.transitions import State
from supervisord.vocabulary import STOP_PATH_CAUSES, CauseKind

log = logging.getLogger("srcsd")

OFF_KIND = CauseKind.VSC_WATCHDOG_OFF


def status_text(decision: Decision) -> str:
    """systemd's status line for a decision: its state, then its active and latched causes."""
    causes = sorted(decision.active_names | decision.latched_names)
    state = decision.state.value.upper()
    return f"{state}: {', '.join(causes)}" if causes else state


def watchdog_said_off(decision: Decision) -> bool:
    """Whether the VSC answered key 85 with another value than 1 (not: not answered yet)."""
    return any(
        state.active
        and state.cause.kind is OFF_KIND
        and state.detail("key85") not in (None, NO_ANSWER)
        for state in decision.causes
    )


class ServiceManager:
    """What the service manager is told, and when its watchdog is due (``next_watchdog``, on
    the loop's monotonic clock; ``None`` without a watchdog or before ``ready``)."""

    def __init__(self, notifier: Notifier, srcsctl: str = DEFAULT_SRCSCTL) -> None:
        self.notifier = notifier
        # How a fix names the command that reaches this daemon (SR-8.18): set by srcsd from
        # its config's path (``srcsctl -R robot-a``).
        self.srcsctl = srcsctl
        self.status = ""  # the status line last sent
        # What ``status`` is of: the loop compares a decision's two with these by identity.
        self.causes: tuple[CauseState, ...] | None = None
        self.state: State | None = None
        self.next_watchdog: int | None = None
        self._interval: int | None = None  # the notifier's, read once at ``ready``
        self._said_watchdog_off = False

    def ready(self, now: int, decision: Decision) -> None:
        """The startup decision is applied (its outputs off): READY=1, and the watchdog is due
        from ``now``."""
        self._interval = self.notifier.watchdog_interval_ns
        self.next_watchdog = now if self._interval else None
        self.notifier.send(READY="1", STATUS=status_text(decision))

    def decided(self, decision: Decision) -> None:
        """A decision with other causes or another state than the last one told: the status
        line, sent if its text changed; the VSC's watchdog said off once."""
        self.causes, self.state = decision.causes, decision.state
        status = status_text(decision)
        if status != self.status:
            self.status = status
            self.notifier.send(STATUS=status)
        off = watchdog_said_off(decision)
        if off and not self._said_watchdog_off:
            # Said each time the VSC answers key 85 with another value than 1, with its fix
            # (SR-8.18): a VSC fresh from the box has key 85 off, and the gate (SR-8.10) waits
            # for it at every start. Not before it answered: a commissioned VSC is not read yet.
            log.warning("%s: %s", STOP_PATH_CAUSES[OFF_KIND], commission_fix(self.srcsctl))
        self._said_watchdog_off = off

    def watchdog(self, now: int) -> None:
        """WATCHDOG=1 if it is due at ``now``; the next one is due an interval later."""
        due, interval = self.next_watchdog, self._interval
        if due is not None and interval and now >= due:
            self.notifier.send(WATCHDOG="1")
            self.next_watchdog = now + interval

    def stopping(self) -> None:
        """The shutdown begins: the outputs go off next (SR-6.5)."""
        self.notifier.send(STOPPING="1", STATUS="stopping: outputs off")

    def close(self) -> None:
        self.notifier.close()
