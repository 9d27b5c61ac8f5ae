"""The closed vocabulary of causes: why the supervisor is not in RUN (SR-2, SR-3).

A *stop* cause (SR-2) forces STOPPED and latches: once raised it stays in the record of active
causes until a valid re-arm (SR-4), even after its condition has cleared. A *hold* cause (SR-3)
forces HOLD and clears by itself. Each cause kind is an enum member; a cause that belongs to a
client, an output or a VSC mode carries that name as its ``subject``. The words themselves
(:class:`Severity`, :class:`CauseKind`, :class:`Cause`) are the shared vocabulary's
(:mod:`supervisord.vocabulary`), which clients import without the core.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from supervisord.vocabulary import Cause, CauseKind, Severity

if TYPE_CHECKING:
    from supervisord.safety.events import Caller

Details = tuple[tuple[str, str], ...]
"""What the record says about a cause: sorted ``(key, value)`` text pairs."""


def make_details(pairs: Iterable[tuple[str, str]]) -> Details:
    """Details in a canonical (sorted) order, so equal details compare equal."""
    return tuple(sorted(pairs))


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


__all__ = ["Cause", "CauseKind", "CauseState", "Details", "Severity", "make_details"]


def caller_details(caller: Caller | None) -> Details:
    """The details naming who asked for a cause (a local e-stop's caller), or none."""
    if caller is None:
        return ()
    return make_details(
        [("caller", caller.name[:60]), ("uid", str(caller.uid)), ("pid", str(caller.pid))]
    )
