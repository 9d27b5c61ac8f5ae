"""The fleet's stops and its console's keepalive as the safety core sees them (SR-8.19 to
SR-8.21; docs/safety.md "The fleet stop").

Internal to the core, one of the machines :class:`~supervisord.safety.clients.Clients` holds
(the fleet's agent is a client of the API): its handlers apply one fleet input each and
return what they refuse as a value, :meth:`Fleet.stops` and :meth:`Fleet.console_lost` give
the conditions at ``now``, :meth:`Fleet.next_deadline` its deadline and :meth:`Fleet.canonical`
its canonical form (docs/verification.md).

What arrives here can only add a reason to stop (SR-8.19): a stop raises ``fleet_stop:SENDER``;
a release ends only that condition, and the stop stays latched until the operator's takeover
on the remote (SR-4); a keepalive ends only the condition of ``fleet_console_lost``, latched
the same way. Nothing here re-arms or asks for an output.
"""

from __future__ import annotations

import re
from typing import Final

from supervisord.safety.canonical import Clock, clock
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import FleetSpec
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.safety.events import Caller, FleetKeepalive, FleetRelease, FleetStop

FLEET_TEXT: Final = re.compile(r"[A-Za-z0-9_.:-]{1,64}")
"""A stop's id and a console's name: 1 to 64 characters, none that a record or a cause name
would have to quote. The API's parser holds requests to the same rule."""
SEEN_MAX: Final = 64
"""Stop ids kept for idempotency (SR-8.19): a repeat among the last 64 changes nothing. A
console sends a new id for every stop; a repeat older than these is taken as a new stop,
which can only stop."""
CONSOLE_LOST: Final = Cause(CauseKind.FLEET_CONSOLE_LOST)


class Fleet:
    """The fleet's active stops by id, the ids already taken and the console's keepalive."""

    def __init__(self, spec: FleetSpec) -> None:
        self._agents = spec.agent_uids
        self._required = spec.console_required
        self._timeout_ns = spec.console_timeout_ns
        self._timeout_ms = str(spec.console_timeout_ms)
        self._stops: dict[str, str] = {}  # active stop id -> its sender
        self._seen: tuple[str, ...] = ()  # the last SEEN_MAX stop ids taken, oldest first
        self._keepalive_ns: int | None = None  # the console's last keepalive (None: never)

    # ----------------------------------------------------------------- handlers

    def stop(self, event: FleetStop) -> Refusal | None:
        refusal = self._refused(event, event.caller, event.sender, event.stop_id)
        if refusal is not None:
            return refusal
        if event.stop_id in self._seen:
            return None  # SR-8.19: the same stop again: already taken, nothing changes
        self._seen = (*self._seen, event.stop_id)[-SEEN_MAX:]
        self._stops[event.stop_id] = event.sender
        return None

    def release(self, event: FleetRelease) -> Refusal | None:
        refusal = self._refused(event, event.caller, event.sender, event.stop_id)
        if refusal is not None:
            return refusal
        if self._stops.get(event.stop_id) != event.sender:
            return Refusal(RefusalReason.NOTHING_TO_RELEASE, f"fleet stop {event.stop_id}", event)
        del self._stops[event.stop_id]
        return None

    def keepalive(self, event: FleetKeepalive, now: int) -> Refusal | None:
        refusal = self._refused(event, event.caller, event.sender, None)
        if refusal is not None:
            return refusal  # SR-8.21: a keepalive from anyone else keeps no deadline
        self._keepalive_ns = now
        return None

    def seen(self, stop_id: str) -> bool:
        """Whether the stop ``stop_id`` was taken already (the daemon's acknowledgement of a
        repeat is the first one's, SR-8.20)."""
        return stop_id in self._seen

    # ----------------------------------------------------------------- conditions at now

    def stops(self) -> dict[Cause, Details]:
        """``fleet_stop:SENDER`` for each console with a stop not released, with its ids."""
        ids: dict[str, list[str]] = {}
        for stop_id, sender in self._stops.items():
            ids.setdefault(sender, []).append(stop_id)
        return {
            Cause(CauseKind.FLEET_STOP, sender): make_details(
                [("sender", sender), ("stop_id", " ".join(sorted(stop_ids)))]
            )
            for sender, stop_ids in ids.items()
        }

    def console_lost(self, now: int) -> Details | None:
        """The details of ``fleet_console_lost`` when the console is required and was not
        heard for its timeout (or not since the start), else ``None`` (SR-8.21)."""
        if not self._required:
            return None
        last = self._keepalive_ns
        if last is None:
            reason = "never heard"
        elif now - last >= self._timeout_ns:  # ">=": as a client's heartbeat (SR-8.1)
            reason = "timeout"
        else:
            return None
        return make_details([("reason", reason), ("timeout_ms", self._timeout_ms)])

    def expired(self, now: int) -> bool:
        """Whether the console's deadline falls due at ``now`` or has (the full step raises
        ``fleet_console_lost`` then; the cheap path must not answer for it)."""
        last = self._keepalive_ns
        return self._required and last is not None and now - last >= self._timeout_ns

    def next_deadline(self, now: int) -> int | None:
        """When the required console's keepalive falls due, if after ``now``."""
        last = self._keepalive_ns
        if not self._required or last is None:
            return None
        due = last + self._timeout_ns
        return due if now < due else None

    def canonical(self, now: int) -> tuple[tuple[object, ...], tuple[Clock, ...]]:
        """The facts and clocks of the fleet (docs/verification.md)."""
        clocks: tuple[Clock, ...] = ()
        if self._required and self._keepalive_ns is not None:
            clocks = (clock("fleet:console", self._keepalive_ns, now, self._timeout_ns),)
        facts = (
            ("fleet_stops", tuple(sorted(self._stops.items()))),
            ("fleet_seen", self._seen),
            ("fleet_heard", self._keepalive_ns is not None),
        )
        return facts, clocks

    NOT_CANONICAL = frozenset({"_agents", "_required", "_timeout_ns", "_timeout_ms"})
    """Attributes ``canonical`` leaves out: the config, and what is computed from it once."""

    # ----------------------------------------------------------------- helpers

    def _refused(
        self,
        event: FleetStop | FleetRelease | FleetKeepalive,
        caller: Caller | None,
        sender: object,
        stop_id: object,
    ) -> Refusal | None:
        """SR-8.19: only a connection of a user ``[fleet] agent_users`` names is heard, and
        only with a well-formed sender and stop id (the API checked them; the core does not
        trust it)."""
        if caller is None or caller.uid not in self._agents:
            who = "an unknown caller" if caller is None else f"uid {caller.uid}"
            return Refusal(RefusalReason.NOT_FLEET_AGENT, who, event)
        for text in (sender,) if stop_id is None else (sender, stop_id):
            if not isinstance(text, str) or FLEET_TEXT.fullmatch(text) is None:
                return Refusal(RefusalReason.BAD_FLEET_TEXT, repr(text)[:70], event)
        return None
