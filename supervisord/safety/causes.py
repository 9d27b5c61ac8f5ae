"""The closed vocabulary of causes: why the supervisor is not in RUN (SR-2, SR-3).

A *stop* cause (SR-2) forces STOPPED and latches: once raised it stays in the record of active
causes until a valid re-arm (SR-4), even after its condition has cleared. A *hold* cause (SR-3)
forces HOLD and clears by itself. Each cause kind is an enum member; a cause that belongs to a
client, an output or a VSC mode carries that name as its ``subject``.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass

Details = tuple[tuple[str, str], ...]
"""What the record says about a cause: sorted ``(key, value)`` text pairs."""


def make_details(pairs: Iterable[tuple[str, str]]) -> Details:
    """Details in a canonical (sorted) order, so equal details compare equal."""
    return tuple(sorted(pairs))


class Severity(enum.Enum):
    """Which rule a cause falls under."""

    STOP = "stop"  # SR-2: stop category 0, outputs off at once, latches
    HOLD = "hold"  # SR-3: controlled stop, clears by itself


class CauseKind(enum.Enum):
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


@dataclass(frozen=True, slots=True)
class Cause:
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

    def __lt__(self, other: object) -> bool:
        if not isinstance(other, Cause):
            return NotImplemented
        return self.name < other.name

    @property
    def name(self) -> str:
        """The name used in records and by ``srcsctl``, as in SR-2/SR-3."""
        if self.subject is None:
            return self.kind.value
        return f"{self.kind.value}:{self.subject}"

    @property
    def severity(self) -> Severity:
        return self.kind.severity

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class CauseState:
    """A cause as the core sees it at one moment.

    ``active``: its condition holds now. ``latched``: a stop cause raised since the last
    re-arm (always false for holds). ``raised_ns``/``cleared_ns``: monotonic times of the
    latest raise and of the clearing that followed it (``None`` while active).
    """

    cause: Cause
    active: bool
    latched: bool
    raised_ns: int
    cleared_ns: int | None
    details: Details = ()

    @property
    def name(self) -> str:
        return self.cause.name

    @property
    def severity(self) -> Severity:
        return self.cause.severity

    def detail(self, key: str) -> str | None:
        """The value of one detail, or ``None``."""
        for k, v in self.details:
            if k == key:
                return v
        return None
