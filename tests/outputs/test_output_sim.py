"""The simulated output: its mirror file and its stuck-line fault (supervisord.outputs.sim)."""

from __future__ import annotations

from pathlib import Path

import pytest

from supervisord.errors import ConfigError
from supervisord.outputs import OutputError, OutputFault, parse_output_spec
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.testkit.output_conformance import T0


def test_file_shows_each_change(tmp_path: Path) -> None:
    """The mirror file reads 0 after open, 1 after on and 0 after off and close."""
    path = tmp_path / "enable"
    out = SimOutput(SimSpec(name="a", path=path))
    out.open(T0)
    assert path.read_bytes() == b"0\n"
    out.set(True, T0)
    assert path.read_bytes() == b"1\n"
    out.set(False, T0)
    assert path.read_bytes() == b"0\n"
    out.set(True, T0)
    out.close()
    assert path.read_bytes() == b"0\n"


def test_file_is_replaced_not_rewritten_in_place(tmp_path: Path) -> None:
    """Each change replaces the file (a new inode), so a reader never sees a partial write, and
    no temporary file is left behind."""
    path = tmp_path / "enable"
    out = SimOutput(SimSpec(name="a", path=path))
    out.open(T0)
    first = path.stat().st_ino
    with path.open("rb") as held:  # a reader holding the old file still sees a whole value
        out.set(True, T0)
        assert held.read() == b"0\n"
    assert path.stat().st_ino != first
    out.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["enable"]


def test_open_overwrites_a_stale_on(tmp_path: Path) -> None:
    """SR-6: a file left at 1 by an earlier run reads 0 as soon as the output is acquired
    (opened), the open's read-back says off, and the line stays off through its close."""
    path = tmp_path / "enable"
    path.write_text("1\n")
    out = SimOutput(SimSpec(name="a", path=path))
    opened = out.open(T0)
    assert opened.ok, opened
    assert (opened.requested, opened.written, opened.observed) == (False, False, False)
    assert path.read_text() == "0\n"
    assert out.is_open
    assert out.device_level is False
    closed = out.close()
    assert closed is not None
    assert closed.ok, closed
    assert path.read_text() == "0\n"


def test_open_fails_when_the_file_cannot_be_written(tmp_path: Path) -> None:
    """A path in a missing directory makes open raise OutputError, holding nothing."""
    out = SimOutput(SimSpec(name="a", path=tmp_path / "missing" / "enable"))
    with pytest.raises(OutputError, match="cannot write"):
        out.open(T0)
    assert not out.is_open


def test_stuck_at_from_config_is_a_mismatch() -> None:
    """A line configured stuck on reports MISMATCH on open and on close; its level stays on."""
    out = SimOutput(SimSpec(name="a", stuck_at=True))
    rb = out.open(T0)
    assert rb.fault is OutputFault.MISMATCH
    assert (rb.written, rb.observed) == (False, True)
    assert out.device_level is True
    assert out.set(True, T0).ok
    closing = out.close()
    assert closing is not None
    assert closing.fault is OutputFault.MISMATCH


def test_stick_shows_in_the_file_and_heals(tmp_path: Path) -> None:
    """Sticking a line shows its stuck level in the file at once; healing lets the next write
    through."""
    path = tmp_path / "enable"
    out = SimOutput(SimSpec(name="a", path=path))
    out.open(T0)
    out.stick(True)
    assert path.read_text() == "1\n"
    rb = out.set(False, T0)
    assert rb.fault is OutputFault.MISMATCH
    out.stick(None)
    assert out.set(False, T0).ok
    assert path.read_text() == "0\n"
    out.close()


def test_spec_from_config(tmp_path: Path) -> None:
    """A sim table with path, stuck_at and role parses into a SimSpec."""
    spec = parse_output_spec(
        "lamp", {"kind": "sim", "path": str(tmp_path / "x"), "stuck_at": "off", "role": "power"}
    )
    assert isinstance(spec, SimSpec)
    assert spec.path == tmp_path / "x"
    assert spec.stuck_at is False
    assert spec.role.value == "power"


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ({"kind": "sim", "stuck_at": "sometimes"}, "outputs.lamp.stuck_at"),
        ({"kind": "sim", "path": ""}, "outputs.lamp.path"),
        ({"kind": "sim", "path": 3}, "outputs.lamp.path"),
        ({"kind": "sim", "colour": "red"}, "outputs.lamp.colour"),
        ({"kind": "sim", "role": "brake"}, "outputs.lamp.role"),
    ],
)
def test_spec_rejects_bad_options(table: dict[str, object], key: str) -> None:
    """A bad or unknown sim option raises ConfigError naming its full key."""
    with pytest.raises(ConfigError) as e:
        parse_output_spec("lamp", table)
    assert e.value.key == key
