"""The cause names ``srcsctl log --cause`` takes: the shared vocabulary's cause kinds (SR-2,
SR-3), ``NAME`` or, for a cause that belongs to a client, output, mode or signal, ``NAME:SUBJECT``
(``client_lost:autonomy``). A name outside it is a usage error that lists the names (exit 2,
SR-11.3): a mistyped cause would otherwise match nothing and look like a clean record."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Final

from supervisord.vocabulary import Cause, CauseKind, CauseName, read_cause

CAUSE_NAMES: Final = tuple(sorted(kind.value for kind in CauseKind))
"""Every cause kind's name, for the error and for shell completion."""
WITH_SUBJECT: Final = tuple(sorted(kind.value for kind in CauseKind if kind.has_subject))


@dataclass(frozen=True, slots=True)
class CauseFilter:
    """The causes a ``--cause`` names: every cause of its ``kind``, or with a ``subject`` only
    that one (and those under it, ``client_lost:nav`` takes ``client_lost:nav:front``)."""

    kind: CauseKind
    subject: str | None = None

    def takes(self, name: CauseName) -> bool:
        """Whether ``name`` is a cause this filter names. A cause kind this client does not
        know is no known kind's (docs/api.md "Cause kinds a client does not know")."""
        if name.kind is not self.kind:
            return False
        wanted, subject = self.subject, name.subject
        return wanted is None or subject == wanted or (subject or "").startswith(wanted + ":")

    def __str__(self) -> str:
        return self.kind.value if self.subject is None else f"{self.kind.value}:{self.subject}"


def cause_name(text: str) -> CauseFilter:
    """The causes ``text`` names (``vsc_estop``, ``client_lost``, ``client_lost:autonomy``);
    else an argparse type error listing the names."""
    try:
        name = read_cause(text)
    except ValueError:  # nothing before ':', or nothing after it
        name = None
    if isinstance(name, Cause):
        return CauseFilter(name.kind, name.subject)
    kind = _kind(text.partition(":")[0])
    if kind is not None and name is not None and name.subject is None:
        return CauseFilter(kind)  # a kind that takes a subject, named without one: all of them
    if kind is not None:
        fix = f"only {', '.join(WITH_SUBJECT)} take ':NAME'" if name else "a name after ':'"
        raise argparse.ArgumentTypeError(f"{text!r} is not a cause name: {fix}")
    raise argparse.ArgumentTypeError(
        f"{text!r} is not a cause; the causes are {', '.join(CAUSE_NAMES)} "
        f"({', '.join(WITH_SUBJECT)} also as NAME:SUBJECT, e.g. client_lost:autonomy)"
    )


def _kind(text: str) -> CauseKind | None:
    """The cause kind ``text`` names, if it names one."""
    return next((kind for kind in CauseKind if kind.value == text), None)
