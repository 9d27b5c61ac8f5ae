"""Python 3.10's gaps, filled where the code needs them (docs/install.md "Python versions")."""

from __future__ import annotations

import datetime as dt

import pytest

from supervisord.compat import from_iso
from supervisord.config import toml


def test_an_iso_time_with_z_is_utc() -> None:
    """SR-7.2: ``--since 2026-11-24T14:02Z`` and a record's ``utc`` read the same on every
    Python: ``Z`` is UTC, an offset is kept, a time without a zone stays naive."""
    utc = dt.timezone.utc
    assert from_iso("2026-11-24T14:02Z") == dt.datetime(2026, 11, 24, 14, 2, tzinfo=utc)
    assert from_iso("2026-11-24T14:02:00.5z").tzinfo == utc
    offset = from_iso("2026-11-24T15:02+01:00")
    assert offset == dt.datetime(2026, 11, 24, 14, 2, tzinfo=utc)
    assert from_iso("2026-11-24T14:02").tzinfo is None
    with pytest.raises(ValueError, match="Invalid isoformat"):
        from_iso("yesterday-ish")


def test_toml_reads_and_refuses_as_tomllib_does() -> None:
    """SR-11.2: the config's reader parses TOML and refuses a broken file with its own error."""
    assert toml.loads('[robot]\nname = "r"\n') == {"robot": {"name": "r"}}
    with pytest.raises(toml.TOMLDecodeError):
        toml.loads("[robot\n")
