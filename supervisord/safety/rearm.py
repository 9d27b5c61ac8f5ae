"""The re-arm check (SR-4): whether a takeover or a local reset may leave STOPPED.

One of the parts :class:`~supervisord.safety.core.SafetyCore` composes: step 4 of its step
hands :func:`check_rearm` the re-arm its event asked for, with the machines it reads, and takes
back the re-arm granted or its refusal as a value (docs/safety.md "Re-arming").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from supervisord.safety.book import CauseBook
from supervisord.safety.clients import Clients
from supervisord.safety.config import SafetyConfig
from supervisord.safety.decision import Rearm, RearmKind, Refusal, RefusalReason
from supervisord.safety.display import DisplayStore, Notice
from supervisord.safety.events import Caller, Event
from supervisord.safety.transitions import State
from supervisord.safety.vsc import Run, VscLink
from supervisord.timebase import NS_PER_MS

NOTICE_WIDTH: Final = 20  # characters in a row of the remote's text page (manual table 18)


@dataclass(frozen=True, slots=True)
class RearmRequest:
    """A re-arm an event asks for: a local reset by its caller, or a takeover with its run."""

    kind: RearmKind
    caller: Caller | None
    run: Run | None = None  # a takeover's evidence: the run before the Operational heartbeat


def check_rearm(
    request: RearmRequest,
    event: Event,
    now: int,
    *,
    state: State,
    config: SafetyConfig,
    book: CauseBook,
    vsc: VscLink,
    clients: Clients,
    display: DisplayStore,
) -> Rearm | Refusal | None:
    """The re-arm granted (the latches released), the refusal to report, or ``None``: nothing
    to report (a takeover outside STOPPED, or a takeover refused again within the quiet)."""
    takeover = request.kind is RearmKind.TAKEOVER
    if takeover and state is not State.STOPPED:
        return None  # a takeover outside STOPPED is just the remote leaving pause (SR-3)
    refusal = rearm_refusal(
        request, now, state=state, config=config, book=book, vsc=vsc, clients=clients
    )
    if refusal is None:
        vsc.rearmed()
        book.release_latches()
        return Rearm(request.kind, request.caller)
    reason, detail = refusal
    if reason is RefusalReason.COMMAND_NONZERO:
        display.notice(notice_rows(clients.commanding()))  # tell the operator (SR-4.6)
    # The same takeover refusal again within a second is not reported (a flapping VSC,
    # docs/safety.md "Re-arming"); a new reason always is. A local reset always gets its
    # answer: a person asked.
    if takeover and vsc.refusal_quiet(reason, now):
        return None
    return Refusal(reason, detail, event)


def rearm_refusal(
    request: RearmRequest,
    now: int,
    *,
    state: State,
    config: SafetyConfig,
    book: CauseBook,
    vsc: VscLink,
    clients: Clients,
) -> tuple[RefusalReason, str] | None:
    """Why the re-arm is refused, or ``None`` when every rule of SR-4 holds."""
    takeover = request.kind is RearmKind.TAKEOVER
    if not takeover:
        caller = request.caller
        if not config.local_reset:
            return RefusalReason.LOCAL_RESET_DISABLED, ""
        if caller is None or not caller.admin:
            return RefusalReason.NOT_ADMIN, caller.name if caller else ""
        if state is not State.STOPPED:
            return RefusalReason.NOT_STOPPED, state.name
    active = book.active_stops()
    if active:
        # Safe choice: a re-arm while a stop condition is active does not count, even
        # later; it must be given after the conditions clear.
        return RefusalReason.CONDITIONS_ACTIVE, ", ".join(c.name for c in active)
    if takeover:
        last_stop = book.last_stop_raised_ns
        refusal = vsc.takeover_refusal(request.run, last_stop, now)
        if refusal is not None:
            return refusal
    clear_since = book.stops_clear_since()
    hold = config.rearm_hold_ns
    if clear_since is None or now - clear_since < hold:
        clear_ms = 0 if clear_since is None else (now - clear_since) // NS_PER_MS
        return (
            RefusalReason.HOLD_TIME_NOT_ELAPSED,
            f"clear for {clear_ms} ms of {hold // NS_PER_MS} ms",
        )
    commanding = clients.commanding()
    if commanding:
        # SR-4.6, checked last: the re-arm breaks no other rule, and the operator is told
        # the one thing left to do.
        return RefusalReason.COMMAND_NONZERO, ", ".join(commanding)
    return None


def notice_rows(names: list[str]) -> Notice:
    """The remote's text page while a re-arm is refused for a non-zero command (SR-4.6):
    what happened, who commands motion (``names``), what to do (20 characters a row)."""
    more = f" +{len(names) - 1}" if len(names) > 1 else ""
    who = names[0][: NOTICE_WIDTH - len(more)] + more
    return ("NOT RE-ARMED", "COMMAND NOT ZERO:", who, "ZERO IT, TAKE OVER")
