"""The cause names ``srcsctl log --cause`` takes: the safety core's vocabulary (SR-2, SR-3),
``NAME`` or, for a cause that belongs to a client, output, mode or signal, ``NAME:SUBJECT``
(``client_lost:autonomy``). A name outside it is a usage error that lists the names (exit 2,
SR-11.3): a mistyped cause would otherwise match nothing and look like a clean record."""

from __future__ import annotations

import argparse
from typing import Final

from supervisord.safety.causes import CauseKind

CAUSE_NAMES: Final = tuple(sorted(kind.value for kind in CauseKind))
"""Every cause kind's name, for the error and for shell completion."""
WITH_SUBJECT: Final = tuple(sorted(kind.value for kind in CauseKind if kind.has_subject))


def cause_name(text: str) -> str:
    """``text`` if it names a cause (``vsc_estop``, ``client_lost``, ``client_lost:autonomy``);
    else an argparse type error listing the names."""
    kind, colon, subject = text.partition(":")
    if kind in CAUSE_NAMES and (not colon or (subject and kind in WITH_SUBJECT)):
        return text
    if kind in CAUSE_NAMES:
        fix = f"only {', '.join(WITH_SUBJECT)} take ':NAME'" if subject else "a name after ':'"
        raise argparse.ArgumentTypeError(f"{text!r} is not a cause name: {fix}")
    raise argparse.ArgumentTypeError(
        f"{text!r} is not a cause; the causes are {', '.join(CAUSE_NAMES)} "
        f"({', '.join(WITH_SUBJECT)} also as NAME:SUBJECT, e.g. client_lost:autonomy)"
    )
