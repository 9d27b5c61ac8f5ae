"""What the safety core answers: a frozen :class:`Decision` for every input.

The daemon acts on a decision in this order (SR-6): set the outputs, send the
frames, then write the records and report the refusals.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from supervisord.protocol.messages import Message
from supervisord.safety.causes import Cause, CauseState, Severity
from supervisord.safety.events import Caller, Event
from supervisord.safety.prooftest import Outcome, ProofStatus
from supervisord.vocabulary import ChangeKind, RearmKind, State


@dataclass(frozen=True, slots=True)
class CauseChange:
    cause: Cause
    kind: ChangeKind


class RecordNote(enum.Enum):
    """A record made for something other than a change of state or cause (docs/record.md)."""

    REARM_REFUSED = "rearm_refused"  # a reset or takeover was asked for and refused (SR-4)
    COMMISSIONED = "commissioned"  # key 85 was written to the VSC (SR-5): permanent, so recorded
    HELLO_REFUSED = "hello_refused"  # a hello as a client bound to another user (SR-8)
    PROOFTEST = "prooftest"  # a proof test of the VSC's watchdog finished (SR-5.3)
    STOPTEST = "stoptest"  # a field stop test finished (SR-12.1)


@dataclass(frozen=True, slots=True)
class Rearm:
    """A re-arm that ended STOPPED, and who gave it (``None`` for a takeover)."""

    kind: RearmKind
    caller: Caller | None = None


class RefusalReason(enum.Enum):
    """Why the core did not do what an input asked. The value is the text ``srcsctl`` prints."""

    # Re-arm refusals (SR-4).
    LOCAL_RESET_DISABLED = "local reset is not allowed by the config (local_reset = false)"
    NOT_ADMIN = "the caller is not in the admin group"
    NOT_STOPPED = "nothing to re-arm: the supervisor is not STOPPED"
    CONDITIONS_ACTIVE = "stop conditions are still active"
    NEW_CAUSE_DURING_REARM = "a new stop cause arrived during the takeover"
    HOLD_TIME_NOT_ELAPSED = "stop conditions have not been clear for the whole re-arm hold time"
    TAKEOVER_TOO_SHORT = "the VSC did not report a non-Operational mode long enough for a takeover"
    VSC_TOO_FAST = "VSC heartbeats came faster than a VSC sends them: no takeover"
    COMMAND_NONZERO = "re-arm only at zero command: a client declares a non-zero command"
    # Inputs that make no sense; each is ignored, never an exception.
    UNKNOWN_CONNECTION = "no such client connection"
    DUPLICATE_CONNECTION = "the connection number is already in use"
    ALREADY_NAMED = "this connection has already said hello"
    NAME_IN_USE = "another connection already uses this name"
    BAD_NAME = "client names are 1-32 letters, digits, '_', '.' or '-'"
    NO_HELLO = "the client has not said hello"
    NOTHING_TO_RELEASE = "this client has no such request active"
    LINK_NOT_OPEN = "a VSC message arrived while the link is not open"
    UNKNOWN_OUTPUT = "no output of that name is configured"
    DISPLAY_KEY_NOT_ALLOWED = "clients may only set display keys 1-12 and 99, names 1-9, 90-93"
    DISPLAY_VALUE_OUT_OF_RANGE = "the display value is out of range for its key"
    NOT_AN_EVENT = "the input is not a safety event"
    WRONG_USER = "this client name is bound to another user"
    STALE_PROGRESS = "the heartbeat's progress is not ahead of the last one: it keeps no deadline"
    NO_PROGRESS = "this client's heartbeats must carry a new progress value (SR-8.16)"
    RATE_LIMITED = (
        "this user's clients caused too many records in the last second; try again shortly"
    )
    # srcsctl prooftest (docs/safety.md "The proof test").
    PROOFTEST_NOT_POSSIBLE = "no proof test here: the link has no user heartbeat, or it is off"
    PROOFTEST_NOT_STOPPED = "the proof test runs only while STOPPED, never in RUN or HOLD"
    PROOFTEST_RUNNING = "a proof test is already running"
    INTERNAL_ERROR = "the core failed on this input and stopped"
    # The fleet's ops (SR-8.19).
    NOT_FLEET_AGENT = "only the fleet agent's user ([fleet] agent_user) may send fleet ops"
    BAD_FLEET_TEXT = "a stop id and a sender are 1-64 letters, digits, '_', '.', ':' or '-'"


@dataclass(frozen=True, slots=True)
class Refusal:
    """An input the core ignored or declined, and why (``detail`` adds the specifics)."""

    reason: RefusalReason
    detail: str
    trigger: object

    @property
    def message(self) -> str:
        return f"{self.reason.value}: {self.detail}" if self.detail else self.reason.value


@dataclass(frozen=True, slots=True, kw_only=True)
class Record:
    """One entry of the stop record (SR-7) for a step that changed the state or a cause, or
    that has a note (:class:`RecordNote`). UTC time is stamped later by the daemon: the core
    has no wall clock. Built by keyword only: eleven fields, several of one type."""

    sequence: int
    monotonic_ns: int
    previous: State
    state: State
    causes: tuple[CauseState, ...]
    changes: tuple[CauseChange, ...]
    trigger: Event
    rearm: Rearm | None = None
    note: RecordNote | None = None
    reason: str = ""  # what the note is about: the refusal's text, the commissioning result
    prooftest: Outcome | None = None  # a proof test that finished with this input


@dataclass(frozen=True, slots=True, kw_only=True)
class Decision:
    """Everything the daemon must do after one input (built by keyword only).

    - ``state`` and ``causes`` (every active or latched cause, sorted by name).
    - ``outputs``: the level each configured output must have now (name -> on).
    - ``heartbeat_estop``: the e-stop byte for user heartbeats (SR-5).
    - ``next_deadline``: call ``tick`` at this monotonic time at the latest (always later
      than ``now``).
    - ``frames``: messages to send to the VSC now, in order.
    - ``records``: stop-record entries, in order: none, one, or two when a proof test finished
      in a step whose input has a note of its own (a commissioning): each record is about one
      thing (SR-7.1).
    - ``refusals``: inputs declined, with the reason (e.g. for ``srcsctl reset``).
    """

    now: int
    state: State
    causes: tuple[CauseState, ...]
    outputs: Mapping[str, bool]
    heartbeat_estop: int
    next_deadline: int
    frames: tuple[Message, ...] = ()
    records: tuple[Record, ...] = ()
    refusals: tuple[Refusal, ...] = ()
    rearm: Rearm | None = None
    prooftest: ProofStatus | None = None  # the proof test of the VSC's watchdog, for status

    def cause(self, name: str) -> CauseState | None:
        """The cause of that name (e.g. ``"client_lost:planner"``), or ``None``."""
        for state in self.causes:
            if state.name == name:
                return state
        return None

    @property
    def active_names(self) -> frozenset[str]:
        """Names of the causes whose condition holds now."""
        return frozenset(c.name for c in self.causes if c.active)

    @property
    def latched_names(self) -> frozenset[str]:
        """Names of the stop causes waiting for a re-arm."""
        return frozenset(c.name for c in self.causes if c.latched)

    @property
    def stop_active(self) -> bool:
        return any(c.active and c.severity is Severity.STOP for c in self.causes)


(
    _SET_NOW,
    _SET_STATE,
    _SET_CAUSES,
    _SET_OUTPUTS,
    _SET_HEARTBEAT_ESTOP,
    _SET_NEXT_DEADLINE,
    _SET_FRAMES,
    _SET_RECORDS,
    _SET_REFUSALS,
    _SET_REARM,
    _SET_PROOFTEST,
) = (Decision.__dict__[field.name].__set__ for field in dataclasses.fields(Decision))
"""The slots of a decision, in the order of its fields, for :func:`again`: a field added to
:class:`Decision` makes this unpacking fail at import until :func:`again` sets it too."""
_NEW: Final = object.__new__
_NOTHING: Final[tuple[()]] = ()


def again(
    previous: Decision,
    now: int,
    heartbeat_estop: int,
    next_deadline: int,
    frames: tuple[Message, ...],
) -> Decision:
    """``previous`` at a new time: the same state, causes, outputs and proof test, with this
    user heartbeat byte, next deadline and frames, and no records, refusals or re-arm. The
    cheap path's decision (SR-9.4): equal to the one ``Decision(...)`` builds, set slot by slot
    without the frozen class's ``__init__``, which costs two and a half times as much
    (``tests/safety/test_cheap_heartbeat.py`` compares both)."""
    decision = _NEW(Decision)
    _SET_NOW(decision, now)
    _SET_STATE(decision, previous.state)
    _SET_CAUSES(decision, previous.causes)
    _SET_OUTPUTS(decision, previous.outputs)
    _SET_HEARTBEAT_ESTOP(decision, heartbeat_estop)
    _SET_NEXT_DEADLINE(decision, next_deadline)
    _SET_FRAMES(decision, frames)
    _SET_RECORDS(decision, _NOTHING)
    _SET_REFUSALS(decision, _NOTHING)
    _SET_REARM(decision, None)
    _SET_PROOFTEST(decision, previous.prooftest)
    return decision


__all__ = [
    "CauseChange",
    "ChangeKind",
    "Decision",
    "Rearm",
    "RearmKind",
    "Record",
    "RecordNote",
    "Refusal",
    "RefusalReason",
    "State",
    "again",
]
