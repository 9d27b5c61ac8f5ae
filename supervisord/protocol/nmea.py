"""Reading the NMEA sentence of a GPS message (manual §8.3.2) into time, position and fix.

Total: any text gives a ``GpsFix`` or ``None``, never an exception, and every number in a
fix is finite and in range. Numbers are ASCII digits only (``_DECIMAL``). A sentence whose ``*hh``
checksum is present and wrong gives ``None``: a corrupted position is worse than none.
Understood: GGA (time, position, fix quality), RMC (time, position, validity) and GLL
(position, time, validity) from any talker (GP, GN, GL, ...).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

from supervisord.protocol.text import ascii_digits


@dataclass(frozen=True, slots=True)
class GpsFix:
    """What one sentence says; each field is ``None`` where the sentence leaves it empty."""

    sentence_type: str
    utc_time: dt.time | None
    latitude: float | None  # degrees, north positive
    longitude: float | None  # degrees, east positive
    fix_quality: int | None  # GGA's quality digit: 0 invalid, 1 GPS, 2 DGPS, ...
    valid: bool  # the sentence claims a usable position


def _checksum_ok(body: str, given: str) -> bool:
    expected = 0
    for ch in body:
        expected ^= ord(ch)
    hex_digits = given[:2]
    if len(hex_digits) != 2 or not all(ch in _HEX for ch in hex_digits):
        return False  # ``int(..., 16)`` would take " f", "+f" or "_f"
    return int(hex_digits, 16) == expected


_HEX = frozenset("0123456789abcdefABCDEF")
_MAX_DIGITS = 16  # no NMEA number is longer; keeps every conversion small


def _decimal(field: str) -> tuple[str, str] | None:
    """``field`` as (integer digits, fraction digits) if it is a plain decimal of ASCII
    digits with at most one point. ``str.isdigit`` takes "²", and ``int``/``float`` take
    other scripts' digits, signs, underscores, whitespace, "nan" and "inf" (SR-8.7: "²" in a
    GGA used to raise in this parser and stop the robot)."""
    if len(field) > _MAX_DIGITS:
        return None
    whole, dot, fraction = field.partition(".")
    if not ascii_digits(whole) or (dot and fraction and not ascii_digits(fraction)):
        return None
    return whole, fraction


def _time(field: str) -> dt.time | None:
    number = _decimal(field)
    if number is None or len(number[0]) != 6:
        return None
    whole, fraction = number
    hour, minute, second = int(whole[0:2]), int(whole[2:4]), int(whole[4:6])
    micro = round(int(fraction[:7].ljust(7, "0")) / 10) if fraction else 0
    try:
        return dt.time(hour, minute, second, min(micro, 999_999), tzinfo=dt.timezone.utc)
    except ValueError:  # 25:61:61: a time that does not exist
        return None


def _angle(field: str, hemisphere: str, degree_digits: int, negative: str) -> float | None:
    """``ddmm.mmmm`` (or ``dddmm.mmmm``) and N/S/E/W into signed decimal degrees."""
    number = _decimal(field)
    if number is None or hemisphere not in ("N", "S", "E", "W"):
        return None
    whole, fraction = number
    if len(whole) != degree_digits + 2:
        return None
    degrees = int(whole[:degree_digits])
    minutes = float(f"{whole[degree_digits:]}.{fraction or '0'}")
    if not 0 <= minutes < 60:
        return None
    value = degrees + minutes / 60
    limit = 90 if degree_digits == 2 else 180
    if value > limit:
        return None
    return -value if hemisphere == negative else value


def _position(parts: list[str], at: int) -> tuple[float | None, float | None]:
    return (
        _angle(parts[at], parts[at + 1], 2, "S"),
        _angle(parts[at + 2], parts[at + 3], 3, "W"),
    )


def parse_nmea(sentence: str) -> GpsFix | None:
    """The fix in ``sentence`` (``$TTSSS,...[*hh]`` with optional CR LF), or ``None``."""
    text = sentence.strip()
    if not text.startswith("$"):
        return None
    body, star, given = text[1:].partition("*")
    if star and not _checksum_ok(body, given):
        return None
    parts = body.split(",")
    kind = parts[0][-3:] if len(parts[0]) == 5 else ""
    if kind == "GGA" and len(parts) >= 7:
        lat, lon = _position(parts, 2)
        # One ASCII digit (0 invalid, 1 GPS, 2 DGPS, ... 8 simulation); anything else: unknown.
        quality = int(parts[6]) if len(parts[6]) == 1 and ascii_digits(parts[6]) else None
        return GpsFix(kind, _time(parts[1]), lat, lon, quality, bool(quality))
    if kind == "RMC" and len(parts) >= 7:
        lat, lon = _position(parts, 3)
        return GpsFix(kind, _time(parts[1]), lat, lon, None, parts[2] == "A")
    if kind == "GLL" and len(parts) >= 7:
        lat, lon = _position(parts, 1)
        return GpsFix(kind, _time(parts[5]), lat, lon, None, parts[6] == "A")
    return None
