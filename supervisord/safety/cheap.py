"""The cheap path of the safety core (docs/performance.md "The cheap path"; SR-9.4).

An input that cannot change a decision is answered without the full step: :func:`cheap`
decides it from the core's parts and the previous decision, or returns ``None`` for the full
step. :class:`~supervisord.safety.core.SafetyCore` calls it once per input, before anything
else, while its last step ended normally; the full step is the reference
(``tests/safety/test_cheap_path.py`` checks that both give the same decisions, property P17 of
docs/verification.md that both leave the same state).
"""

from __future__ import annotations

from typing import Final

from supervisord.protocol.messages import (
    Gps,
    Joystick,
    Message,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.safety.book import CauseBook
from supervisord.safety.deadline import IDLE_NS, next_deadline
from supervisord.safety.decision import Decision, again
from supervisord.safety.events import ClientHeartbeat, Event, Tick, VscReceived
from supervisord.safety.prooftest import SETTLED
from supervisord.safety.transitions import IllegalTransition, Situation, State, next_state
from supervisord.safety.view import View
from supervisord.safety.vscmessage import take_vsc_heartbeat

INERT_VSC_MESSAGES = (Joystick, Gps, RemoteStatus)
"""VSC messages that change no fact the core keeps (``SafetyCore._on_vsc`` ignores them): in a
steady state they take the cheap path. A whitelist, so that a message type added later takes
the full path until someone decides otherwise. Remote status is inert only while the core does
not react to the remote's battery (SR-8.12)."""
SETTLED_PROOF: Final = SETTLED
"""Proof-test phases in which neither time nor an unchanged heartbeat moves the proof test
(docs/safety.md "The proof test"); in any other the cheap path declines, and the full step
recomputes the conditions before its event."""
_CHEAP_EVENTS = frozenset({Tick, VscReceived, ClientHeartbeat})
_INERT_TYPES = frozenset(INERT_VSC_MESSAGES)
"""The only VSC message types :func:`cheap` considers; every other takes the full step."""


def cheap(  # noqa: PLR0912 -- inline: called for every input (SR-9.4)
    event: Event, previous: Decision, last: int, estop: int, view: View
) -> Decision | None:
    """The decision for an input that cannot change one, or ``None`` for the full step.

    ``previous`` is the core's last decision, ``last`` the time of its last input and ``estop`` the
    user heartbeat's byte from the conditions alone (no urgent raise); ``view`` the core's view of
    its machines (``face.View``, built once: its ``now`` is set here).
    The core asks only after a step that ended normally on a fixed point of the table
    (:func:`fixed_point`). Cheap are a :class:`Tick`, an inert VSC message
    (:data:`INERT_VSC_MESSAGES`), a VSC heartbeat with the same mode and e-stop word as the last and
    a client's heartbeat that changes no condition (``Clients.beat_unchanged``: named, in time, no
    progress value), while no machine moves with time (``Machine.moving``), either before the
    previous decision's ``next_deadline`` or when the user heartbeat is the only thing due
    (:func:`_only_heartbeat_due`: no machine ``due_by``). Then no timeout expires and no other frame
    is due (:func:`~supervisord.safety.deadline.next_deadline` takes every machine's), so step 1
    of the full path changes nothing; such an input changes no condition (a heartbeat after an
    expired timeout clears ``vsc_link_lost`` and is not cheap, and so is one while the mode's hold
    names another mode, which it renames after the dwell) (step 3), asks no re-arm (the mode did
    not change, step 4), so the state is the previous step's fixed point (step 5) and no record
    follows (step 6); the one frame is the user heartbeat at its cadence, with the byte of the
    conditions (SR-5.1, SR-5.2). What can differ is ``now``, the facts the input moves (applied by
    the full step's own handler: the heartbeat's time, the takeover run; a client's time) and so
    ``next_deadline``, computed as the full path does (SR-2.2, SR-2.11: the heartbeat still
    restarts the link deadline). An input that moves no fact and sends nothing keeps the previous
    ``next_deadline`` (:func:`_kept_deadline`). The decision's ``now`` is the core's new time of
    its last input.
    """
    kind = type(event)
    if kind not in _CHEAP_EVENTS:
        return None
    for machine in view.movers:  # a plain loop over the few that can move (SR-9.4)
        if machine.moving():
            return None  # a proof test running, a deferred end, an output braking
    now = event.now if event.now > last else last
    view.now = now
    beat_due = now >= previous.next_deadline
    if beat_due and not _only_heartbeat_due(view):
        return None
    vsc = view.vsc
    moved = False  # whether the input moved a fact that a deadline is counted from
    if type(event) is VscReceived:
        message = event.message
        if not vsc.open:
            return None  # the full path refuses it (LINK_NOT_OPEN)
        if type(message) is VscHeartbeat:
            if not vsc.unchanged_by(message, now):
                return None
            # Applied by the full step's own handler of a VSC heartbeat (SR-2.2, SR-5.3).
            if take_vsc_heartbeat(message, now, vsc, view.proof, view.display) is not None:
                raise AssertionError("a heartbeat of an unchanged mode asked a takeover")
            moved = True  # the link's timeout restarts (SR-2.2)
        # SR-8.12: a remote status is inert only while the battery is not watched
        elif type(message) not in _INERT_TYPES or (
            view.battery.cause is not None and type(message) is RemoteStatus
        ):
            return None
    elif type(event) is ClientHeartbeat:
        if not view.clients.beat_unchanged(event, now):
            return None
        moved = True  # the client's timeout restarts (SR-8.2)
    frames: tuple[Message, ...] = ()
    if beat_due:
        # What the full step's link frames are for a heartbeat that is not urgent (SR-5.1).
        frames = (UserHeartbeat(estop),)
        view.proof.sent(now)
        vsc.beat_sent(now)
    deadline = (
        previous.next_deadline
        if not (beat_due or moved) and _kept_deadline(previous)
        else next_deadline(view)
    )
    # Every other field as the previous decision has it, as the full step would compute it
    # again (``again``).
    return again(previous, now, estop, deadline, frames)


def _kept_deadline(previous: Decision) -> bool:
    """Whether an input that moved no fact and sent nothing, before ``previous``'s deadline,
    may keep that deadline: :func:`~supervisord.safety.deadline.next_deadline` would give
    it again (SR-9.4). Every deadline it weighs is a time kept by a machine, not reckoned
    from ``now`` (the clients' deferred ends, which are, decline the cheap path), and no
    such time lies between the previous input and this one (this one comes before the
    earliest); so the earliest is the same, unless it was the idle bound ``now + IDLE_NS``,
    which moves with ``now``: kept only when the earliest fell before that bound."""
    return previous.next_deadline - previous.now < IDLE_NS


def only_the_beat_moves(view: View) -> bool:
    """Whether at ``view.now`` time moves nothing but the user heartbeat: no machine moving
    (the proof test settled, no client's end deferred, no category-1 output braking), and of
    everything due only the beat. The cheap path's own test of time; the reflex holds at such
    a time too (SR-9.5)."""
    for machine in view.movers:
        if machine.moving():
            return False
    return _only_heartbeat_due(view)


def _only_heartbeat_due(view: View) -> bool:
    """Whether the user heartbeat is due at ``view.now`` and nothing else any machine keeps
    is (nor does the proof test withhold it): the time at which the full step's only work is
    to send it. One comparison over the machines' face (``Machine.due_by``)."""
    if not view.vsc.beat_due(view.now):
        return False
    for machine in view.machines:  # noqa: SIM110 -- every machine's due times, no generator
        if machine.due_by(view):
            return False
    return True


def fixed_point(state: State, book: CauseBook) -> bool:
    """Whether the table keeps the state where it is when nothing changes (SR-1): true for
    every legal row a step can end on; checked anyway, so that a table that ever says
    otherwise is met by the full step, which turns its refusal into ``internal``. Asked
    once at the end of each full step (only a full step changes the state or the book), not
    for each cheap input (SR-9.4)."""
    if book.any_latched():
        situation = Situation.STOP
    else:
        situation = Situation.HOLD if book.any_hold() else Situation.CLEAR
    try:
        return next_state(state, situation) is state
    except IllegalTransition:
        return False
