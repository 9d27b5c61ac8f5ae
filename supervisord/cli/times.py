"""The one time rule of ``srcsctl`` (docs/srcsctl.md "Times"): how a time is shown and how a
typed one is read.

Shown: in local time with its UTC offset (``log``), or as the local time of day (``watch``,
the demo); in UTC with ``--utc``. Read: ISO 8601 (a time without a zone is read in the same
zone), a time of day (today), ``now``, ``today``, ``yesterday``, ``tomorrow``, or an age in
journalctl's forms (systemd.time(7)): ``5 min ago``, ``-5min``, ``1h 30min ago``, ``+2h``,
and the short ``10m``, ``-2h``, ``3d`` (a number with no sign is an age too).
"""

from __future__ import annotations

import datetime as dt
import re
from typing import Final

from supervisord.compat import from_iso

_UNITS: Final = {
    **dict.fromkeys(("us", "usec", "µs"), dt.timedelta(microseconds=1)),
    **dict.fromkeys(("ms", "msec"), dt.timedelta(milliseconds=1)),
    **dict.fromkeys(("s", "sec", "second", "seconds"), dt.timedelta(seconds=1)),
    **dict.fromkeys(("m", "min", "minute", "minutes"), dt.timedelta(minutes=1)),
    **dict.fromkeys(("h", "hr", "hour", "hours"), dt.timedelta(hours=1)),
    **dict.fromkeys(("d", "day", "days"), dt.timedelta(days=1)),
    **dict.fromkeys(("w", "week", "weeks"), dt.timedelta(weeks=1)),
    # systemd.time(7)'s month and year: 30.44 and 365.25 days. "M" is a month, "m" a minute.
    **dict.fromkeys(("M", "month", "months"), dt.timedelta(days=30.44)),
    **dict.fromkeys(("y", "year", "years"), dt.timedelta(days=365.25)),
}
_SPAN: Final = re.compile(r"\s*(\d+(?:\.\d+)?)\s*([a-zA-Zµ]+)", re.ASCII)  # ASCII digits (SR-8.7)
_AGE: Final = re.compile(r"([+-])?((?:\s*\d+(?:\.\d+)?\s*[a-zA-Zµ]+)+)(\s+ago)?", re.ASCII)
_TIME_OF_DAY: Final = re.compile(r"\d{1,2}:\d{2}(:\d{2}(\.\d+)?)?", re.ASCII)
FORMS: Final = (
    "ISO 8601, a time of day, now, today, yesterday, tomorrow, or an age like "
    "'5 min ago', -5min, 2h, 3d"
)


class BadTime(ValueError):
    pass


def zone(utc: bool) -> dt.tzinfo | None:
    """The zone times are shown and read in: UTC with ``--utc``, else local (``None``)."""
    return dt.timezone.utc if utc else None


def _age(text: str) -> dt.timedelta | None:
    """The signed offset from now that ``text`` names (negative: the past), or ``None``."""
    found = _AGE.fullmatch(text.strip())
    if found is None:
        return None
    sign, spans, ago = found.groups()
    if sign == "+" and ago:
        return None
    total = dt.timedelta()
    for amount, unit in _SPAN.findall(spans):
        if unit not in _UNITS:
            return None
        total += float(amount) * _UNITS[unit]
    return total if sign == "+" else -total


def parse_time(text: str, now: dt.datetime, *, utc: bool = False) -> dt.datetime:
    """The aware time ``text`` names (the forms in the module's doc); ``now`` is aware.
    Raises :class:`BadTime` naming the forms, for any text that names no time, also one
    beyond the calendar (``-99999999999y``, year 1 in a zone east of UTC): a usage error,
    never a traceback (SR-11.3)."""
    try:
        return _parse_time(text, now, utc=utc)
    except BadTime:
        raise
    except (OverflowError, ValueError) as error:  # datetime's range is years 1 to 9999
        raise BadTime(f"not a time: {text!r} (beyond years 1 to 9999)") from error


def _parse_time(text: str, now: dt.datetime, *, utc: bool) -> dt.datetime:
    word = text.strip().lower()
    midnight = now.astimezone(zone(utc)).replace(hour=0, minute=0, second=0, microsecond=0)
    days = {"today": 0, "yesterday": -1, "tomorrow": 1}
    if word == "now":
        return now
    if word in days:
        return midnight + dt.timedelta(days=days[word])
    offset = _age(text)
    if offset is not None:
        return now + offset
    if _TIME_OF_DAY.fullmatch(word):
        text = f"{midnight.date().isoformat()}T{word}"
    try:
        when = from_iso(text.strip())
    except ValueError as error:
        raise BadTime(f"not a time: {text!r} (use {FORMS})") from error
    if when.tzinfo:
        return when
    return when.replace(tzinfo=dt.timezone.utc) if utc else when.astimezone()


def aware(text: object) -> dt.datetime | None:
    """A record's ``utc`` as an aware time (a time without a zone is UTC), or ``None``."""
    try:
        when = from_iso(str(text))
    except ValueError:
        return None
    return when if when.tzinfo else when.replace(tzinfo=dt.timezone.utc)


def show_time(utc_text: object, *, utc: bool = False) -> str:
    """A record's ``utc`` in the display zone, to the millisecond, with its offset."""
    when = aware(utc_text)
    if when is None:
        return str(utc_text)
    return when.astimezone(zone(utc)).isoformat(timespec="milliseconds")


def clock(when: dt.datetime, *, utc: bool = False) -> str:
    """The time of day of ``when`` (aware) in the display zone, to the millisecond (a ``Z``
    after it in UTC): what ``watch`` and the demo show."""
    local = when.astimezone(zone(utc))
    return local.strftime("%H:%M:%S.%f")[:-3] + ("Z" if utc else "")


def clock_of(utc_text: object, *, utc: bool = False) -> str:
    """:func:`clock` of a record's ``utc`` (the text itself if it is not a time)."""
    when = aware(utc_text)
    return str(utc_text) if when is None else clock(when, utc=utc)
