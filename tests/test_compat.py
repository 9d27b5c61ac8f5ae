"""Python 3.10's gaps, filled where the code needs them (docs/install.md "Python versions")."""

from __future__ import annotations

import ast
import datetime as dt
from pathlib import Path

import pytest

import supervisord
from supervisord.compat import from_iso
from supervisord.config import toml
from supervisord.protocol.codes import MessageType


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


def test_an_int_enum_reads_as_its_number_on_every_python() -> None:
    """SR-0.3: a member of every integer enum of the program is its number as text, ``str()``
    and f-strings alike, as Python 3.11 made it: on 3.10 ``str()`` of a plain ``IntEnum`` is
    ``MessageType.JOYSTICK``, and the simulator's EEPROM file, keyed by ``str(kind)``, could not
    be read back there (seen on a real 3.10). Each enum derives from ``compat.IntEnum``, which
    is checked in the source, since on 3.11 and later the plain one behaves the same."""
    root = Path(supervisord.__file__).parent
    plain = [
        f"{path.relative_to(root)}:{node.lineno}"
        for path in sorted(root.rglob("*.py"))
        if path.name != "compat.py"
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ClassDef)
        for base in node.bases
        if isinstance(base, ast.Attribute) and base.attr == "IntEnum"
    ]
    assert plain == [], f"derive from supervisord.compat.IntEnum: {plain}"
    joystick = MessageType.JOYSTICK
    assert (str(joystick), f"{joystick}", f"{joystick:#04x}") == ("16", "16", "0x10")
