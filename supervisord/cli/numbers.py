"""The one rule for the numbers ``srcsctl`` reads from its command line (SR-11.3,
docs/srcsctl.md "Exit status"): argparse types, so that a bad number is a usage error of
its own command (exit 2, that command's usage) before anything runs.

A duration or a rate (``wait-ready --timeout``, ``stoptest --timeout``, ``demo --speed``) is
a finite number above 0: ``nan`` compares false with everything, so a deadline ``now + nan``
is never reached and ``wait-ready`` waited without end (SR-8.10); ``inf`` never ends either,
and 0 or less is no wait at all. A count (``log -n``) is a whole number, 0 or more.
"""

from __future__ import annotations

import argparse
import math
from typing import Final

MAX_COUNT_DIGITS: Final = 18
"""More records than any file holds, and far below the text-to-int conversion's own limit,
which raises where this refuses."""


def positive(text: str) -> float:
    """``text`` as a finite number above 0 (seconds, or a rate), in ASCII (SR-8.7); else an
    argparse type error naming the rule."""
    try:
        number = float(text) if text.isascii() else math.nan
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or number <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number above 0")
    return number


def count(text: str) -> int:
    """``text`` as a whole number, 0 or more, in ASCII digits (SR-8.7); else an argparse type
    error naming the rule."""
    digits = text.strip()
    if not (digits.isascii() and digits.isdigit()) or len(digits) > MAX_COUNT_DIGITS:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number, 0 or more")
    return int(digits)
