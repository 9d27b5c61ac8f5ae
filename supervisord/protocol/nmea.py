"""Reading the NMEA sentence of a GPS message (manual §8.3.2) into time, position and fix.

Total: any text gives a ``GpsFix`` or ``None``, never an exception. A sentence whose ``*hh``
checksum is present and wrong gives ``None``: a corrupted position is worse than none.
Understood: GGA (time, position, fix quality), RMC (time, position, validity) and GLL
(position, time, validity) from any talker (GP, GN, GL, ...).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass


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
    try:
        return int(given[:2], 16) == expected
    except ValueError:
        return False


def _time(field: str) -> dt.time | None:
    if len(field) < 6 or not field[:6].isdigit():
        return None
    hour, minute, second = int(field[0:2]), int(field[2:4]), int(field[4:6])
    micro = 0
    if len(field) > 7 and field[6] == "." and field[7:].isdigit():
        micro = round(float("0" + field[6:]) * 1_000_000)
    try:
        return dt.time(hour, minute, second, min(micro, 999_999), tzinfo=dt.UTC)
    except ValueError:
        return None


def _angle(field: str, hemisphere: str, degree_digits: int, negative: str) -> float | None:
    """``ddmm.mmmm`` (or ``dddmm.mmmm``) and N/S/E/W into signed decimal degrees."""
    if len(field) < degree_digits + 2 or hemisphere not in ("N", "S", "E", "W"):
        return None
    try:
        degrees = int(field[:degree_digits])
        minutes = float(field[degree_digits:])
    except ValueError:
        return None
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
        quality = int(parts[6]) if parts[6].isdigit() else None
        return GpsFix(kind, _time(parts[1]), lat, lon, quality, bool(quality))
    if kind == "RMC" and len(parts) >= 7:
        lat, lon = _position(parts, 3)
        return GpsFix(kind, _time(parts[1]), lat, lon, None, parts[2] == "A")
    if kind == "GLL" and len(parts) >= 7:
        lat, lon = _position(parts, 1)
        return GpsFix(kind, _time(parts[5]), lat, lon, None, parts[6] == "A")
    return None
