"""The one rule for the numbers ``srcsctl`` reads from its command line (SR-11.3,
docs/srcsctl.md "Exit status"): argparse types, so that a bad number is a usage error of
its own command (exit 2, that command's usage) before anything runs.

A duration or a rate (``wait-ready --timeout``, ``stoptest --timeout``, ``demo --speed``) is
a finite number above 0: ``nan`` compares false with everything, so a deadline ``now + nan``
is never reached and ``wait-ready`` waited without end (SR-8.10); ``inf`` never ends either,
and 0 or less is no wait at all. A duration may also be written as systemd writes a time span
(``2s``, ``500ms``, ``1min``, ``1m30s``): what a unit file's author types in
``ExecStartPre=srcsctl wait-ready --timeout 2min``. A count (``log -n``) is a whole number, 0
or more; a key or row of the remote's screen a whole number in its range.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable
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


DURATION_UNITS: Final = {
    **dict.fromkeys(("us", "usec"), 1e-6),
    **dict.fromkeys(("ms", "msec"), 1e-3),
    **dict.fromkeys(("s", "sec", "second", "seconds"), 1.0),
    **dict.fromkeys(("m", "min", "minute", "minutes"), 60.0),
    **dict.fromkeys(("h", "hr", "hour", "hours"), 3600.0),
    **dict.fromkeys(("d", "day", "days"), 86400.0),
}
"""systemd.time(7)'s units of a time span, up to days: a timeout in weeks is a typing error."""

_SPAN_PART: Final = re.compile(r"\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*([a-z]*)")


def duration(text: str) -> float:
    """``text`` as seconds above 0: a plain number is seconds (``2``, ``0.5``), else a time
    span as systemd writes one (systemd.time(7)): ``2s``, ``500ms``, ``1min``, ``1m30s``,
    ``1min 30s``; in ASCII (SR-8.7). The sum must be finite and above 0; else an argparse type
    error naming the rule (SR-11.3)."""
    try:
        return positive(text)
    except argparse.ArgumentTypeError:
        pass
    total, at, span = 0.0, 0, text.strip()
    while span and at < len(span) and span.isascii():
        part = _SPAN_PART.match(span, at)
        if part is None or part.group(2) not in DURATION_UNITS:
            break
        total += float(part.group(1)) * DURATION_UNITS[part.group(2)]
        at = part.end()
    else:
        if span and math.isfinite(total) and total > 0:
            return total
    raise argparse.ArgumentTypeError(
        f"{text!r} is not a duration above 0: seconds (2, 0.5) or a time span such as 2s, "
        "500ms, 1min, 1m30s"
    )


def whole_in(low: int, high: int) -> Callable[[str], int]:
    """An argparse type: a whole number from ``low`` to ``high`` (a sign allowed), in ASCII
    digits (SR-8.7); else a type error naming the range."""

    def parse(text: str) -> int:
        digits = text.strip()
        unsigned = digits[1:] if digits[:1] in "+-" else digits
        if unsigned.isascii() and unsigned.isdigit() and len(unsigned) <= MAX_COUNT_DIGITS:
            number = int(digits)
            if low <= number <= high:
                return number
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number from {low} to {high}")

    parse.__name__ = f"whole number from {low} to {high}"
    return parse
