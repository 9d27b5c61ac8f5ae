"""The supervisor's words: what the daemon, its safety core and every client name alike.

The three states (SR-1), the causes (SR-2, SR-3: a kind, and a subject for the kinds that
name a client, an output, a mode or a signal), their severities and changes, the re-arm
paths (SR-4), the reactions to a lost e-stop (SR-8.12), the proof test's policy and phases
(SR-5.3) and the parts of readiness (SR-8.10). Declared once here and imported by the safety
core, the stop record, the API's typed values and the clients, so that none of them spells or
parses the words as text: the wire writes each member's value (a state: its name).

Pure and small: it imports nothing of the safety core, the daemon or the API (the client
library imports it, docs/ros2.md "The client library").
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from supervisord.compat import StrEnum


class _Word(enum.Enum):
    """A word of the vocabulary: printed as the API and the record write it (``stop``), as
    the clients printed its text before it was an enum."""

    def __str__(self) -> str:
        return str(self.value)


class State(enum.Enum):
    """The three states of SR-1, printed and written by name (``STOPPED``)."""

    def __str__(self) -> str:
        return self.name

    STOPPED = "stopped"  # a stop cause is active, or latched and not yet re-armed
    HOLD = "hold"  # no stop, but motion is not intended
    RUN = "run"  # motion is allowed


class Severity(_Word):
    """Which rule a cause falls under."""

    STOP = "stop"  # SR-2: stop category 0, outputs off at once, latches
    HOLD = "hold"  # SR-3: controlled stop, clears by itself


class CauseKind(_Word):
    """Every cause the supervisor can name (SR-1 to SR-3). Values are the record names."""

    STARTUP = "startup"  # SR-1: the supervisor starts STOPPED with this cause
    VSC_ESTOP = "vsc_estop"
    VSC_LINK_LOST = "vsc_link_lost"
    TRANSPORT_FAULT = "transport_fault"
    CLIENT_LOST = "client_lost"
    CLIENT_ESTOP = "client_estop"
    LOCAL_ESTOP = "local_estop"
    OUTPUT_FAULT = "output_fault"
    VSC_WATCHDOG_OFF = "vsc_watchdog_off"
    VSC_WATCHDOG_UNTESTED = "vsc_watchdog_untested"  # SR-5.3: key 85 not proven to act
    INTERNAL = "internal"
    SHUTDOWN = "shutdown"  # SR-7.14: the daemon exits (``shutdown:SIGTERM``)
    ESTOP_UNAVAILABLE = "estop_unavailable"  # SR-8.12, vsc.on_estop_unavailable = "stop"
    FLEET_STOP = "fleet_stop"  # SR-8.19: a fleet console's stop, named by its sender
    FLEET_CONSOLE_LOST = "fleet_console_lost"  # SR-8.21: a required console's keepalive lost
    VSC_MODE = "vsc_mode"  # SR-3 hold
    CLIENT_HOLD = "client_hold"  # SR-3 hold
    ESTOP_UNAVAILABLE_HOLD = "estop_unavailable_hold"  # SR-8.12, on_estop_unavailable = "hold"

    @property
    def severity(self) -> Severity:
        return Severity.HOLD if self in _HOLD_KINDS else Severity.STOP

    @property
    def has_subject(self) -> bool:
        """Whether the cause name carries ``:NAME`` (a client, an output, a mode, or the
        signal that ended the daemon)."""
        return self in _SUBJECT_KINDS

    @property
    def momentary(self) -> bool:
        """A cause whose condition is an instant, not a lasting state: it fires and is clear
        at once, and only its latch remains (``startup``, ``internal``, ``shutdown``)."""
        return self in _MOMENTARY_KINDS

    @property
    def sets_user_estop(self) -> bool:
        """Whether an active condition of this kind sets the user heartbeat's e-stop byte.

        SR-5: every supervisor-side stop condition does. ``vsc_estop`` does not:
        our own byte makes the VSC raise its user e-stop bits, which would then hold the byte
        at 1 for ever. ``startup`` is never an active condition. ``vsc_watchdog_untested``
        does not either: the proof test needs the byte at 0 to see the VSC's own bits 6-7
        come and go (PR-2.6, docs/safety.md "The proof test"); the outputs are off meanwhile.
        """
        return self.severity is Severity.STOP and self not in _NOT_USER_ESTOP_KINDS


_HOLD_KINDS = frozenset(
    {CauseKind.VSC_MODE, CauseKind.CLIENT_HOLD, CauseKind.ESTOP_UNAVAILABLE_HOLD}
)
_SUBJECT_KINDS = frozenset(
    {
        CauseKind.CLIENT_LOST,
        CauseKind.CLIENT_ESTOP,
        CauseKind.FLEET_STOP,
        CauseKind.OUTPUT_FAULT,
        CauseKind.VSC_MODE,
        CauseKind.CLIENT_HOLD,
        CauseKind.SHUTDOWN,
    }
)
_MOMENTARY_KINDS = frozenset({CauseKind.STARTUP, CauseKind.INTERNAL, CauseKind.SHUTDOWN})
_NOT_USER_ESTOP_KINDS = frozenset(
    {CauseKind.VSC_ESTOP, CauseKind.STARTUP, CauseKind.VSC_WATCHDOG_UNTESTED}
)


class _Named:
    """What a cause name of either kind shares: its text, written ``KIND`` or
    ``KIND:SUBJECT``, by which it prints and sorts."""

    __slots__ = ()
    kind: CauseKind | UnknownCauseKind
    subject: str | None

    @property
    def name(self) -> str:
        """The name used in records and by ``srcsctl``, as in SR-2/SR-3."""
        if self.subject is None:
            return self.kind.value
        return f"{self.kind.value}:{self.subject}"

    def to_text(self) -> str:
        return self.name

    def __lt__(self, other: object) -> bool:
        if not isinstance(other, _Named):
            return NotImplemented
        return self.name < other.name

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class Cause(_Named):
    """One named cause, e.g. ``client_lost:planner`` or ``vsc_estop``.

    Raises ``ValueError`` when a kind that needs a subject has none, or the reverse.
    """

    kind: CauseKind
    subject: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.kind, CauseKind):
            raise ValueError("cause kind must be a CauseKind")
        if self.kind.has_subject != (self.subject is not None):
            raise ValueError(f"cause {self.kind.value} subject mismatch: {self.subject!r}")
        if self.subject is not None and (not isinstance(self.subject, str) or not self.subject):
            raise ValueError("cause subject must be non-empty text")

    @classmethod
    def from_text(cls, text: str) -> Cause:
        """The cause a name says (``client_lost:planner``, ``vsc_estop``): its kind, and its
        subject after the first ``:``. Raises ``ValueError`` for a name that is none."""
        kind, colon, subject = text.partition(":")
        return cls(CauseKind(kind), subject if colon else None)

    @property
    def severity(self) -> Severity:
        return self.kind.severity


@dataclass(frozen=True, slots=True)
class UnknownCauseKind:
    """A cause kind this client does not know: one a newer daemon added, read from its API or
    its record file (docs/api.md "Cause kinds a client does not know"). It keeps the text it
    was written as (:attr:`value`, as a :class:`CauseKind` member's) and equals no member, so
    no rule of a known kind applies to it. The daemon never makes one."""

    value: str

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True, slots=True)
class UnknownCause(_Named):
    """A cause name whose kind this client does not know (:class:`UnknownCauseKind`), or a
    known kind written with a subject where this client knows none (or none where it knows
    one): kept as written, so that it is shown and counted under the text it came as, never
    refused (a newer daemon's record must stay readable)."""

    kind: UnknownCauseKind
    subject: str | None = None


CauseName = Cause | UnknownCause
"""A cause's name as a client reads it: a :class:`Cause` of a known kind, or an
:class:`UnknownCause` kept as written (:func:`read_cause`)."""


def read_cause(text: str) -> Cause | UnknownCause:
    """The cause a name says, as a client reads it from the daemon: a :class:`Cause` when this
    client knows its kind (and its subject fits the kind), else an :class:`UnknownCause` that
    keeps the text. Raises ``ValueError`` only for text that names nothing (an empty kind or
    an empty subject). The daemon parses nothing with it: it makes only known kinds."""
    kind, colon, subject = text.partition(":")
    if not kind or (colon and not subject):
        raise ValueError(f"not a cause name: {text!r}")
    try:
        return Cause.from_text(text)
    except ValueError:
        return UnknownCause(UnknownCauseKind(kind), subject if colon else None)


class ChangeKind(_Word):
    """How a cause changed in one step (SR-7: every raise and clear is recorded)."""

    RAISED = "raised"  # its condition became active (a momentary cause fired)
    CLEARED = "cleared"  # its condition became clear; a stop cause stays latched
    RELEASED = "released"  # a re-arm released the latch of a clear stop cause (SR-4)
    UPDATED = "updated"  # an active cause's details changed (e.g. more e-stop sources)


class RearmKind(_Word):
    """The two re-arm paths of SR-4."""

    TAKEOVER = "takeover"  # the operator's takeover on the remote: not Operational -> Operational
    LOCAL_RESET = "local_reset"  # ``srcsctl reset`` by an admin, when the config allows it


class Counted(_Word):
    """What a record counts as for a fleet (SR-13.9, docs/record.md "What counts as a
    stop"): one meaning for ``srcsctl fleet --summary``, ``srcsctl log --summary``, the
    exporter's counters and the alert rules, decided by
    :func:`supervisord.record.counted.counted`. A record that is none of these (a cause
    raised or cleared while STOPPED, a follow-up the supervisor raised itself) counts as
    nothing."""

    STOP = "stop"  # RUN or HOLD -> STOPPED by a stop cause; its trigger: the causes raised
    STARTUP = "startup"  # the daemon started (the record that raised ``startup``)
    PROOFTEST_PASSED = "prooftest_passed"  # the VSC's watchdog proven (SR-5.3)
    PROOFTEST_FAILED = "prooftest_failed"  # not proven: the robot has one stop path left
    REARM = "rearm"  # STOPPED -> RUN or HOLD, by a takeover or a local reset (SR-4)


class Reaction(StrEnum):
    """``vsc.on_estop_unavailable``: what the supervisor does while the remote's battery is low
    or not reported (SR-8.12)."""

    WARN = "warn"  # say so in status, the exporter and the bridge; nothing else
    HOLD = "hold"  # the cause estop_unavailable_hold: HOLD, RUN again once it is back
    STOP = "stop"  # the cause estop_unavailable: STOPPED, latched, a takeover after it is back


class ProofTestPolicy(_Word):
    """What a failed or impossible proof test does (config ``vsc.prooftest``)."""

    BLOCK = "block"  # vsc_watchdog_untested stays active until a proof test passes
    RECORD = "record"  # the failure is a momentary stop: recorded, latched, re-armed as usual
    OFF = "off"  # no proof test (the only choice on CAN and HID: nothing to prove)


class Phase(_Word):
    """Where the proof test is."""

    WAITING = "waiting"  # not proven; waiting for the conditions to start
    WITHHOLDING = "withholding"  # the user heartbeat is withheld; waiting for the trip
    RESUMED = "resumed"  # the heartbeat goes out again; waiting for the bits to clear
    PASSED = "passed"
    FAILED = "failed"
    OFF = "off"


class ProofTestFailure(enum.Enum):
    """Why a proof test failed: written by its name in lower case in the record's
    ``prooftest.failure`` (``late``); the value is the text in the record's words and the
    cause's details."""

    KEY85_OFF = "key 85 does not read 1: the VSC's watchdog is off, nothing to prove"
    NO_TRIP = "the VSC did not report the user-timeout e-stop while the heartbeat was withheld"
    LATE = "the VSC reported the user-timeout e-stop late"
    STAYED_OPERATIONAL = "the VSC reported the user-timeout e-stop but stayed Operational"
    NOT_CLEARED = "the VSC did not clear the user-timeout e-stop after the heartbeat resumed"


_NS_PER_MS: Final = 1_000_000  # as supervisord.timebase says; not imported: the client set is fixed
WATCHDOG_NS: Final = 500 * _NS_PER_MS
"""The VSC's user watchdog: an e-stop after 500 ms without a user heartbeat (manual §8.3.5)."""
READING_MARGIN_NS: Final = 200 * _NS_PER_MS
"""What the proof test allows beyond the watchdog's 500 ms for seeing the trip: one VSC
heartbeat interval at the manual's 20 Hz (50 ms, table 5), the heartbeat that carries the bits,
and 150 ms for reading it on a busy vehicle computer."""
TRIP_LATE_NS: Final = WATCHDOG_NS + READING_MARGIN_NS
"""A trip seen later than this (700 ms) after the last heartbeat sent is late (SR-5.7). Absolute:
it judges the VSC's watchdog, whose promise is the manual's 500 ms, so it does not grow with
``vsc.timeout_ms`` (how long the supervisor tolerates the VSC's silence is another question; a
timeout of 1000 ms once let a watchdog tripping at 1.2 s pass). A VSC set to send its heartbeat
less often than every 50 ms (manual §8.3.6) can show a healthy trip late: it fails, the safe
side, and ``vsc.prooftest = "record"`` is the integrator's choice there (docs/safety.md).
Here, with the failures' words, so that a client prints a proof test's verdict without the
safety core (SR-8.8)."""


class ReadinessPart(_Word):
    """A part of readiness (SR-8.10, docs/srcsctl.md "Starting behind the supervisor"): what
    ``status`` must show for the stop path to work."""

    LINK = "link"  # the link to the VSC is open
    STOP_PATH = "stop_path"  # no cause of STOP_PATH_CAUSES is active
    PROOFTEST = "prooftest"  # the VSC's key-85 watchdog is proven (or nothing to prove)
    OUTPUTS = "outputs"  # every output is held by the supervisor


STOP_PATH_CAUSES: Final[Mapping[CauseKind, str]] = {
    CauseKind.VSC_LINK_LOST: "the VSC is not heard",
    CauseKind.TRANSPORT_FAULT: "the link to the VSC has failed",
    CauseKind.VSC_WATCHDOG_OFF: "the VSC's key-85 watchdog is off",
    CauseKind.OUTPUT_FAULT: "an output does not read back what it was told",
    CauseKind.INTERNAL: "the supervisor has an internal fault",
}
"""Active causes that mean the stop path does not work (:attr:`ReadinessPart.STOP_PATH`),
and how each is said."""

PROOFTEST_BLOCKERS: Final = frozenset(
    kind for kind in CauseKind if kind.sets_user_estop and kind is not CauseKind.CLIENT_LOST
)
"""The stop causes that keep a proof test from starting: those that set the user heartbeat's
byte, ``client_lost`` aside (SR-8.15; docs/safety.md "The proof test")."""
