"""A window's numbers at and past every bound (SR-7.13, SR-7.15, SR-7.16; docs/record.md
"Replay"): each number a window file holds (the header's, the stop record's, the
configuration's, the base's, a snapshot's, an input's) set to a value no 64-bit field takes, or
that JSON does not allow, is a window that cannot be read, never a traceback, for the plain
replay and for each export; a time no 64-bit clock holds (an input's ``now``, the base's
``now_ns``, the stop's ``mono_ns``, or a ``utc`` that maps one out of 1970 to 2262) is refused
as that, exit 2, before anything replays or exports it."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.cli.replay import EXIT_BAD_INPUT, run_replay
from supervisord.record.flight import FlightWriter
from supervisord.record.jsonl import RecordWriter
from tests.record.flight_rig import run, story
from tests.record.stop_kinds import KINDS, RECORD

ROOT = Path(__file__).resolve().parents[2]
MARK = "__number__"
BOUNDS = {
    "below int64": str(-(2**63) - 1),
    "int64 low": str(-(2**63)),
    "past int64": str(2**63),
    "past uint64": str(2**64),
    "a huge float": "1e308",
    "past a float": "1e999",
    "NaN": "NaN",
    "Infinity": "-Infinity",
}
TIMES = ("now", "now_ns", "mono_ns")
"""The keys whose numbers are times: past the monotonic clock's range each is exit 2."""
NOT_JSON = ("NaN", "Infinity", "past a float")
"""No number JSON allows (past a float: read as an infinity): exit 2 wherever it stands."""
EXITS = {0, 1, 2, 3, 5}
"""The replay's exit statuses (docs/srcsctl.md): any of them, never a traceback."""


def _numbers(value: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """The path of every number (and null, where a number may stand) in ``value``."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _numbers(item, (*path, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from _numbers(item, (*path, index))
    elif value is None or (isinstance(value, int | float) and not isinstance(value, bool)):
        yield path


def _set(line: str, path: tuple[Any, ...], text: str) -> str:
    """``line`` with the number at ``path`` written as ``text`` (any JSON-like literal)."""
    value = json.loads(line)
    inner = value
    for key in path[:-1]:
        inner = inner[key]
    inner[path[-1]] = MARK
    return json.dumps(value).replace(f'"{MARK}"', text)


def _windows(tmp_path: Path) -> dict[str, tuple[Path, int]]:
    """A client's stop (from the start) and a stop from a snapshot, written as the daemon
    writes them; each window's path and the stop's sequence number."""
    client = KINDS["client_lost"]()
    first = tmp_path / "client"
    first.mkdir()
    snapshot_run = run(story(), snapshot_at=[20])
    second = tmp_path / "snapshot"
    second.mkdir()
    with RecordWriter(second / RECORD) as records:
        for record in snapshot_run.records:
            records.append(record)
    window = FlightWriter(second / RECORD, 1 << 20).write(
        snapshot_run.window(bases=snapshot_run.bases[1:])
    )
    return {
        "client": (client.write(first), client.stop["seq"]),
        "snapshot": (window, snapshot_run.stop["seq"]),
    }


def _cases(lines: list[str], kind: str) -> list[tuple[int, tuple[Any, ...]]]:
    """Which lines of a window to change: the header and the first and last inputs of the
    client's window; the snapshot line of the other."""
    chosen = [0, 2, len(lines) - 2] if kind == "client" else [1]
    return [(index, path) for index in chosen for path in _numbers(json.loads(lines[index]))]


def _exports(folder: Path) -> list[tuple[Path | None, Path | None]]:
    """The plain replay, ``--mcap`` and ``--plot``, each alone."""
    return [(None, None), (folder / "out.mcap", None), (None, folder / "out.svg")]


@pytest.mark.parametrize("bound", list(BOUNDS))
@pytest.mark.parametrize("kind", ["client", "snapshot"])
def test_every_number_of_a_window_at_a_bound(tmp_path: Path, kind: str, bound: str) -> None:
    """SR-7.13: every number of the window, one at a time, set to ``bound``; the plain replay,
    ``--mcap`` and ``--plot`` each end with one of the replay's exit statuses, never an
    exception; a time (or any number past 64 bits, or one JSON has not) is exit 2."""
    path, seq = _windows(tmp_path)[kind]
    lines = path.read_text().splitlines()
    text = BOUNDS[bound]
    tried = 0
    for index, where in _cases(lines, kind):
        changed = [*lines]
        changed[index] = _set(lines[index], where, text)
        path.write_text("\n".join(changed) + "\n")
        refused = (where[-1] in TIMES and index != 1) or bound in NOT_JSON
        for mcap, plot in _exports(tmp_path):
            out, errors = io.StringIO(), io.StringIO()
            record = path.parent.parent / RECORD
            code = run_replay(str(seq), record, out, errors, mcap=mcap, plot=plot)
            said = f"{kind} line {index} {where} = {text} {mcap} {plot}: {errors.getvalue()}"
            assert code in EXITS, said
            if refused:
                assert code == EXIT_BAD_INPUT, said
            tried += 1
    assert tried > 30, tried


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("input", -(2**63) - 1),
        ("input", -1),
        ("input", 2**63),
        ("stop", 2**64),
        ("base", -(2**63)),
        ("utc", "0001-01-01T00:00:00+00:00"),
        ("utc", "9999-12-31T23:59:59-14:00"),
    ],
    ids=str,
)
def test_a_time_out_of_the_clock_is_exit_2_for_mcap(tmp_path: Path, field: str, value: Any) -> None:
    """SR-7.13, SR-7.15: a window whose time is below -2**63 (or below 0, or past 2**63 - 1 ns,
    or whose ``utc`` maps a moment out of 1970 to 2262) given to the real ``srcsctl replay
    --mcap --plot``: exit 2 with what is wrong, no traceback, and neither file written (the
    MCAP writer took such a time only to die in ``struct.pack``)."""
    path, _ = _windows(tmp_path)["client"]
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    if field == "input":
        lines[1] = _set(lines[1], ("now",), str(value))
    elif field == "stop":
        header["stop"]["mono_ns"] = value
    elif field == "base":
        header["base"]["now_ns"] = value
    else:
        header["stop"]["utc"] = value
    if field != "input":
        lines[0] = json.dumps(header)
    path.write_text("\n".join(lines) + "\n")
    mcap, svg = tmp_path / "out.mcap", tmp_path / "out.svg"
    done = subprocess.run(
        [
            *(sys.executable, "-m", "supervisord.cli.srcsctl", "replay", str(path)),
            *("--mcap", str(mcap), "--plot", str(svg)),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
        check=False,
    )
    assert done.returncode == EXIT_BAD_INPUT, done.stdout + done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert "srcsctl replay:" in done.stderr, done.stderr
    assert "1970 to 2262" in done.stderr or "monotonic clock" in done.stderr, done.stderr
    assert not mcap.exists()
    assert not svg.exists()
