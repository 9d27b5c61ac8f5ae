"""``srcsctl log`` on a record file whose texts hold terminal controls (SR-13.7): a record file
copied from a robot is another party's bytes, and ``log`` prints its records through the same
line as ``fleet`` (supervisord/cli/record_text.py), escaped."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.cli.test_fleet import HOSTILE, raw_controls
from tests.record.test_unknown_cause import LINE

SRCSCTL = str(Path(sys.executable).with_name("srcsctl"))


def _hostile_file(tmp_path: Path) -> Path:
    """Three records: a typed one raising a cause named, detailed and triggered by
    :data:`HOSTILE`, and rejected by a re-arm whose reason is it; and one from a state so
    named (no typed record: shown as written)."""
    raised: dict[str, Any] = {
        **LINE,
        "causes": [
            {**LINE["causes"][0], "name": "evil" + HOSTILE, "details": {"reason": HOSTILE}},
        ],
        "changes": [{"name": "evil" + HOSTILE, "change": "raised"}],
        "trigger": {"event": "tick" + HOSTILE},
    }
    untyped = {**LINE, "seq": 8, "from": "RUN" + HOSTILE, "kind": "x" + HOSTILE}
    path = tmp_path / "stops.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in (raised, untyped)))
    return path


@pytest.mark.parametrize("mode", [[], ["--causes"], ["-o", "cat"], ["-o", "verbose"], ["-r"]])
def test_log_shows_a_record_files_text_escaped(tmp_path: Path, mode: list[str]) -> None:
    """SR-13.7: every control, bidi and separator character of a record's cause name,
    details, trigger, state and kind is shown as its escape, on the record's own line."""
    done = subprocess.run(
        [SRCSCTL, "log", "--file", str(_hostile_file(tmp_path)), *mode],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert raw_controls(done.stdout) == []
    assert raw_controls(done.stderr) == []
    lines = done.stdout.splitlines()
    assert len(lines) == 2, lines
    assert "evil\\x1b]0;owned\\x07" in done.stdout
    assert "RUN\\x1b]0;owned" in done.stdout
    assert "\\u202e" in done.stdout


def test_replay_shows_a_record_files_text_escaped(tmp_path: Path) -> None:
    """SR-13.7: a record file whose stop record says otherwise with :data:`HOSTILE` text (a
    detail, and a field of its own named so) is a mismatch that ``srcsctl replay`` prints with
    every control, bidi and separator character escaped."""
    from supervisord.cli.replay import EXIT_MISMATCH, run_replay  # noqa: PLC0415
    from supervisord.record.flight import FlightWriter  # noqa: PLC0415
    from supervisord.record.jsonl import RecordWriter  # noqa: PLC0415
    from tests.record.flight_rig import run, story  # noqa: PLC0415

    story_run = run(story())
    story_run.stop["causes"][0]["details"]["sources"] = HOSTILE
    story_run.stop["extra" + HOSTILE] = HOSTILE
    with RecordWriter(tmp_path / "stops.jsonl") as records:
        for record in story_run.records:
            records.append(record)
    path = FlightWriter(tmp_path / "stops.jsonl", 1 << 20).write(story_run.window())
    # The window carries a typed record, which has no field of its own named so: the file
    # copied from a robot is another party's bytes, so its copy of the stop says it too.
    header, *rest = path.read_text().splitlines(keepends=True)
    forged = json.loads(header)
    forged["stop"] = story_run.stop
    path.write_text(json.dumps(forged) + "\n" + "".join(rest))
    out, errors = io.StringIO(), io.StringIO()
    code = run_replay(str(path), tmp_path / "stops.jsonl", out, errors)
    said = out.getvalue() + errors.getvalue()
    assert code == EXIT_MISMATCH, said
    assert raw_controls(said) == []
    assert "differing fields: " in said
    assert "\\u202e" in said
