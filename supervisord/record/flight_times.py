"""The moments of a flight recorder window: what a time in it may be, and how it maps to the wall
clock (SR-7.13, SR-7.15; ``docs/record.md`` "Replay").

A moment is a reading of the daemon's monotonic clock (:mod:`supervisord.clock`): an integer of
nanoseconds from 0 to 2**63 - 1, what a signed 64-bit counter holds. The stop record's ``utc``
maps each moment to the wall clock (the stop's ``mono_ns`` is its ``utc``); every mapped moment
must again lie from 0 to 2**63 - 1 ns after 1970 (the years 1970 to 2262), which both an
unsigned (MCAP's ``log_time``) and a signed 64-bit reader take. A window with any other time
is damaged: :func:`check_moments` refuses it when it is read, so that the replay and every
export (``--mcap``, ``--plot``) see only windows whose times they can write. Pure: no I/O.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping, Sequence
from typing import Any, Final

from supervisord.record.flight_codec import MOMENT_LIMIT, FlightFormatError, moment, preview

EPOCH: Final = dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)

Json = Any


def parse_utc(text: object) -> dt.datetime | None:
    """A record's ``utc`` (ISO 8601 with a zone), or ``None``."""
    if not isinstance(text, str):
        return None
    try:
        value = dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    return value if value.tzinfo is not None else None


def epoch_ns(when: dt.datetime) -> int:
    """``when`` (aware) in integer nanoseconds since 1970 (negative before it)."""
    delta = when - EPOCH
    return (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1000


def utc_ns(stop_utc: dt.datetime | None, stop_ns: int, mono_ns: int) -> int:
    """The wall-clock time (ns since 1970) of the moment ``mono_ns``: as far from the stop's
    ``utc`` as from its ``stop_ns``; with no ``utc``, the moment itself."""
    if stop_utc is None:
        return mono_ns
    return epoch_ns(stop_utc) + (mono_ns - stop_ns)


def check_moments(
    stop: Mapping[str, Json], base: Mapping[str, Json], inputs: Sequence[int]
) -> None:
    """Refuse (:class:`FlightFormatError`) a window with a time that is no moment, or a moment
    that the stop's ``utc`` maps out of the range. ``inputs`` are the inputs' times, each
    already read as a moment (``flight_codec``); the base's ``now_ns`` and the stop's
    ``mono_ns`` are checked here when the window has them. The stop's moment is its
    ``mono_ns``, else the last input's, as the export takes it (``timeline``)."""
    times = list(inputs)
    if "now_ns" in base:
        times.append(moment(base["now_ns"], "the base's now_ns"))
    stop_ns = stop.get("mono_ns")
    if stop_ns is not None:
        times.append(moment(stop_ns, "the stop record's mono_ns"))
    elif inputs:
        stop_ns = inputs[-1]
    stop_utc = parse_utc(stop.get("utc"))
    if not times or stop_utc is None or not isinstance(stop_ns, int):
        return
    for when in (min(times), max(times)):
        mapped = utc_ns(stop_utc, stop_ns, when)
        if not 0 <= mapped < MOMENT_LIMIT:
            raise FlightFormatError(
                f"the stop record's utc {preview(stop.get('utc'))} maps the moment {when} ns "
                "outside 1970 to 2262 (0 to 2**63 - 1 ns)"
            )
