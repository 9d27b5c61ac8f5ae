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
    assert fix.utc_time == dt.time(12, 35, 19, tzinfo=dt.UTC)
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
    assert fix.utc_time == dt.time(1, 2, 3, 500_000, tzinfo=dt.UTC)
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
