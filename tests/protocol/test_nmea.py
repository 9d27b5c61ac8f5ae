"""Reading the GPS message's NMEA sentence."""

from __future__ import annotations

import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from supervisord.protocol.messages import Gps
from supervisord.protocol.nmea import parse_nmea

GGA = "$GPGGA,123519.00,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,*69"


def test_gga_gives_time_position_and_quality() -> None:
    """A GGA sentence gives UTC time, signed decimal degrees and the fix quality."""
    fix = Gps(1, GGA).fix
    assert fix is not None
    assert fix.utc_time == dt.time(12, 35, 19, tzinfo=dt.timezone.utc)
    assert fix.latitude == pytest.approx(48.1173)
    assert fix.longitude == pytest.approx(11.516667)
    assert fix.fix_quality == 1
    assert fix.valid


def test_rmc_south_west_and_validity() -> None:
    """RMC with S and W hemispheres gives negative degrees; status V is not valid."""
    fix = parse_nmea("$GNRMC,010203.5,V,3352.1200,S,15112.6000,W,0.0,0.0,010125,,,N")
    assert fix is not None
    assert fix.latitude == pytest.approx(-33.868667)
    assert fix.longitude == pytest.approx(-151.21)
    assert fix.utc_time == dt.time(1, 2, 3, 500_000, tzinfo=dt.timezone.utc)
    assert not fix.valid


def test_gll_position() -> None:
    """GLL carries position, then time and status."""
    fix = parse_nmea("$GPGLL,4916.45,N,12311.12,W,225444,A")
    assert fix is not None
    assert fix.latitude == pytest.approx(49.274167)
    assert fix.longitude == pytest.approx(-123.185333)


def test_wrong_checksum_gives_nothing() -> None:
    """A sentence whose *hh checksum does not match is not read: no position beats a wrong one."""
    assert parse_nmea(GGA.replace("*69", "*6A")) is None


def test_empty_fields_are_none() -> None:
    """A GGA without a fix yet has no time, position or quality, and is not valid."""
    fix = parse_nmea("$GPGGA,,,,,,0,00,,,M,,M,,")
    assert fix is not None
    assert (fix.utc_time, fix.latitude, fix.longitude, fix.fix_quality) == (None, None, None, 0)
    assert not fix.valid


@given(st.text(max_size=120))
def test_any_text_parses_or_gives_none(text: str) -> None:
    """Whatever the remote sends, reading it never raises."""
    parse_nmea(text)
    parse_nmea("$GPGGA," + text)


# Characters of the Latin-1 range that ``str.isdigit`` or ``float`` take but that are no NMEA
# digits: superscripts, fractions, and the no-break space ``float`` strips (SR-8.7).
NOT_ASCII_DIGITS = ("\u00b2", "\u00b3", "\u00b9", "\u00bc", "\u00bd", "\u00a0", "\u0085")
GGA_FIELDS = "$GPGGA,{time},{lat},N,{lon},E,{quality},08,0.9,545.4,M,46.9,M,,"


@pytest.mark.parametrize("odd", NOT_ASCII_DIGITS)
def test_a_digit_that_is_not_ascii_is_not_a_digit(odd: str) -> None:
    """A GGA whose quality, time or position holds a character that is a digit only to
    Unicode (``²``) gives no value for that field, never an exception (the sentence used to
    stop the robot with ``internal`` while a client subscribed to ``gps``)."""
    fields = {"time": "123519", "lat": "4807.038", "lon": "01131.000", "quality": "1"}
    for name, value in fields.items():
        for spoiled in (odd, value[:-1] + odd, odd + value, value[:2] + odd + value[2:]):
            fix = parse_nmea(GGA_FIELDS.format(**{**fields, name: spoiled}))
            assert fix is not None
            got = {
                "time": fix.utc_time,
                "lat": fix.latitude,
                "lon": fix.longitude,
                "quality": fix.fix_quality,
            }[name]
            assert got is None, (name, spoiled, got)


@pytest.mark.parametrize("word", ["nan", "inf", "-inf", "1e3", "1_0", "+5", "-5", " 5", "0x1"])
def test_numbers_are_plain_ascii_decimals(word: str) -> None:
    """Only ``ddmm.mmmm`` of ASCII digits is a position and ``hhmmss[.ss]`` a time: no NaN,
    infinity, exponent, sign, underscore or padding that Python's own number parsers accept."""
    fix = parse_nmea(
        GGA_FIELDS.format(time=f"1235{word}", lat=f"48{word}", lon=f"011{word}", quality=word)
    )
    assert fix is not None
    assert (fix.utc_time, fix.latitude, fix.longitude, fix.fix_quality) == (None, None, None, None)


_LATIN1 = st.characters(min_codepoint=0, max_codepoint=0xFF)
_FIELD = st.one_of(
    st.text(st.sampled_from("0123456789.") | st.sampled_from(NOT_ASCII_DIGITS), max_size=14),
    st.text(_LATIN1, max_size=14),
)


_HEMISPHERE = st.sampled_from(["N", "S", "E", "W", "A", "V", "", "\u00b2"])


@given(
    st.sampled_from(["GGA", "RMC", "GLL"]),
    st.lists(st.one_of(_FIELD, _HEMISPHERE), min_size=7, max_size=14),
)
def test_any_fields_give_finite_values_in_range(kind: str, fields: list[str]) -> None:
    """Whatever each field of a GGA, RMC or GLL holds, the sentence parses or gives ``None``,
    and every number it gives is finite and in range (so every JSON encoder takes it)."""
    fix = parse_nmea(f"$GP{kind}," + ",".join(fields))
    if fix is None:
        return
    if fix.latitude is not None:
        assert -90 <= fix.latitude <= 90
    if fix.longitude is not None:
        assert -180 <= fix.longitude <= 180
    if fix.fix_quality is not None:
        assert 0 <= fix.fix_quality <= 9
