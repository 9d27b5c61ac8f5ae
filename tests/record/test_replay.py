"""Replaying a flight recorder window (SR-7.13; ``supervisord/record/replay.py``,
``srcsctl replay``, docs/record.md "Replay"): a window replays to exactly the records the core
made, from the daemon's start or from a snapshot; a window whose inputs were changed, dropped
or added, or a record that says otherwise, is a mismatch at the first step that parts; a
window that cannot be replayed says why."""

from __future__ import annotations

import dataclasses
import io
import json
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.cli.replay import (
    EXIT_BAD_INPUT,
    EXIT_MISMATCH,
    EXIT_NOT_CHECKED,
    EXIT_NOT_THE_RECORD,
    run_replay,
)
from supervisord.protocol.messages import VscHeartbeat
from supervisord.record.flight import MAX_NESTING, FlightWriter, read_window
from supervisord.record.jsonl import RecordWriter
from supervisord.record.replay import ReplayError, replay
from supervisord.safety.events import VscReceived
from tests.record.flight_rig import Run, run, story

RECORD = "stops.jsonl"


def _written(tmp_path: Path, story_run: Run, **window: Any) -> Path:
    """The run's records in a record file and its window beside it; the window's path."""
    with RecordWriter(tmp_path / RECORD) as records:
        for record in story_run.records:
            records.append(record)
    return FlightWriter(tmp_path / RECORD, 1 << 20).write(story_run.window(**window))


def _replay(tmp_path: Path, which: str, *, record: bool = True) -> tuple[int, str]:
    out, errors = io.StringIO(), io.StringIO()
    code = run_replay(which, tmp_path / RECORD if record else None, out, errors)
    return code, out.getvalue() + errors.getvalue()


@pytest.mark.parametrize("base", ["start", "snapshot"])
def test_a_window_replays_to_the_recorded_records(tmp_path: Path, base: str) -> None:
    """SR-7.13: from the daemon's start (a fresh core) or from a snapshot taken mid-run, the
    replay makes every record the core made after the base, equal field for field (but the
    wall-clock time), the stop's included; ``srcsctl replay SEQ`` says so and exits 0."""
    inputs = story()
    story_run = run(inputs, snapshot_at=[len(inputs) // 2])
    bases = story_run.bases if base == "start" else story_run.bases[1:]
    path = _written(tmp_path, story_run, bases=bases)
    result = replay(read_window(path), {r["seq"]: r for r in story_run.records})
    assert result.matches, result.mismatch
    after = bases[0].after_seq
    assert result.compared == len([r for r in story_run.records if r["seq"] > after])
    code, said = _replay(tmp_path, str(story_run.stop["seq"]))
    assert code == 0, said
    assert "replay matches the record" in said
    assert f"#{story_run.stop['seq']} RUN -> STOPPED state_change [vsc_estop]  as recorded" in said


def test_the_newest_window_and_a_window_file_alone(tmp_path: Path) -> None:
    """SR-7.13: without a number, the newest window of the record; a window file by its path
    finds its record by its folder (``PATH.flight``)."""
    story_run = run(story())
    path = _written(tmp_path, story_run)
    assert _replay(tmp_path, None)[0] == 0  # type: ignore[arg-type]
    code, said = _replay(tmp_path, str(path), record=False)
    assert code == 0, said
    assert "not in the record files" not in said


def _tamper(path: Path, change: Any) -> None:
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    inputs = [json.loads(line) for line in lines[1:-1]]
    inputs = change(inputs)
    header["inputs"] = len(inputs)
    body = [json.dumps(header), *(json.dumps(i) for i in inputs), json.dumps({"end": len(inputs)})]
    path.write_text("\n".join(body) + "\n")


def _stop_cleared(inputs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    last = inputs[-1]
    assert last["message"]["payload"] == "090001000000"  # Operational, e-stop word 1
    last["message"]["payload"] = "090000000000"
    return inputs


def _takeover_dropped(inputs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    operational = "090000000000"  # a heartbeat in Operational, no e-stop
    first_operational = next(
        i for i, line in enumerate(inputs) if line.get("message", {}).get("payload") == operational
    )
    return inputs[:first_operational] + inputs[first_operational + 1 :]


def _link_break_added(inputs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    line = {"event": "link_broken", "now": inputs[-10]["now"], "reason": "EIO"}
    return [*inputs[:-10], line, *inputs[-10:]]


@pytest.mark.parametrize(
    ("change", "where"),
    [
        (_stop_cleared, "MISMATCH at the end of the window: record #"),
        (_takeover_dropped, "MISMATCH at step"),
        (_link_break_added, "MISMATCH at step"),
    ],
    ids=["the stopping heartbeat edited", "the takeover dropped", "a link break added"],
)
def test_a_tampered_window_is_a_mismatch(tmp_path: Path, change: Any, where: str) -> None:
    """SR-7.13: a window whose inputs were edited (the stopping heartbeat's e-stop bit
    cleared), dropped (the takeover) or added (a link break): the replay parts from the record
    and ``srcsctl replay`` names where and exits 1."""
    story_run = run(story())
    path = _written(tmp_path, story_run)
    _tamper(path, change)
    code, said = _replay(tmp_path, str(story_run.stop["seq"]))
    assert code == EXIT_MISMATCH, said
    assert where in said, said
    assert "replay matches" not in said


def test_a_record_that_says_otherwise_is_a_mismatch(tmp_path: Path) -> None:
    """SR-7.13: the record's stop names another cause than the replay makes: a mismatch at
    the step that made it, with the differing fields."""
    story_run = run(story())
    stop = story_run.stop
    stop["causes"][0]["details"]["sources"] = "local"
    path = _written(tmp_path, story_run)
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_MISMATCH, said
    assert f"MISMATCH at step {len(story_run.inputs)}" in said, said
    assert "differing fields: causes" in said


def test_records_the_files_no_longer_hold_are_counted_not_failed(tmp_path: Path) -> None:
    """SR-7.13: records before the stop that the files no longer hold (rotated away, or never
    written: a full disk) cannot be compared: the replay says how many, and still checks the
    stop record against the record file."""
    story_run = run(story())
    with RecordWriter(tmp_path / RECORD) as records:
        records.append(story_run.stop)
    path = FlightWriter(tmp_path / RECORD, 1 << 20).write(story_run.window())
    code, said = _replay(tmp_path, str(path))
    assert code == 0, said
    assert f"({len(story_run.records) - 1} not in the record files)" in said


@pytest.mark.parametrize("record_file", ["missing", "a folder"])
def test_a_stop_record_the_record_file_does_not_hold_is_not_checked(
    tmp_path: Path, record_file: str
) -> None:
    """SR-7.13: a window whose stop record the record file does not hold (rotated away, never
    written) or whose record file cannot be read (here a folder has its name) is replayed
    against the window's own copy only: ``srcsctl replay`` says so plainly, claims no match
    with the record file, and exits 3."""
    story_run = run(story())
    path = FlightWriter(tmp_path / RECORD, 1 << 20).write(story_run.window())
    if record_file == "a folder":
        (tmp_path / RECORD).mkdir()
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_NOT_CHECKED, said
    assert "NOT CHECKED against the record file" in said, said
    reason = "cannot be read" if record_file == "a folder" else "does not hold record #"
    assert reason in said, said
    assert "replay matches" not in said


def test_a_window_without_a_base_cannot_be_replayed(tmp_path: Path) -> None:
    """SR-7.11, SR-7.13: a window whose start the ring's bound cut keeps no base: replay says
    why and exits 2, never replaying from a state it does not have."""
    story_run = run(story())
    path = _written(tmp_path, story_run, bases=[], keep=20, cut="the ring's bound cut its start")
    assert len(read_window(path).inputs) == 20
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_BAD_INPUT
    assert "the ring's bound cut its start" in said


def test_a_snapshot_of_another_version_cannot_be_replayed(tmp_path: Path) -> None:
    """SR-7.11, SR-7.13: a snapshot this code cannot restore (a class it does not have) is
    refused with the version that wrote it."""
    inputs = story()
    story_run = run(inputs, snapshot_at=[10])
    base = story_run.bases[1]
    state = json.loads(json.dumps(base.state))
    state["f"]["_book"]["c"] = "supervisord.safety.book:OldBook"
    path = _written(tmp_path, story_run, bases=[dataclasses.replace(base, state=state)])
    with pytest.raises(ReplayError, match="cannot restore"):
        replay(read_window(path), {})
    assert _replay(tmp_path, str(path))[0] == EXIT_BAD_INPUT


def test_a_missing_window_is_a_usage_error(tmp_path: Path) -> None:
    """SR-7.13: a number with no window beside the record, or no window at all: exit 2, the
    message naming the record it looked in."""
    code, said = _replay(tmp_path, "12")
    assert code == EXIT_BAD_INPUT
    assert f"no window of record 12: there is no record 12 in {tmp_path / RECORD}" in said
    assert _replay(tmp_path, None)[0] == EXIT_BAD_INPUT  # type: ignore[arg-type]


def test_every_step_is_shown_with_all(tmp_path: Path) -> None:
    """SR-7.13: ``--all`` shows a line per input; without it, the inputs that made no record
    are counted between the ones that did."""
    story_run = run(story())
    path = _written(tmp_path, story_run)
    out = io.StringIO()
    assert run_replay(str(path), None, out, io.StringIO(), show_all=True) == 0
    lines = [line for line in out.getvalue().splitlines() if re.match(r" +[0-9]+ ", line)]
    assert len(lines) == len(story_run.inputs) + 1  # and the fresh core's start
    assert any(
        isinstance(e, VscReceived) and isinstance(e.message, VscHeartbeat) for e in story_run.inputs
    )
    quiet = io.StringIO()
    assert run_replay(str(path), None, quiet, io.StringIO()) == 0
    assert "inputs" in quiet.getvalue()
    assert len(quiet.getvalue().splitlines()) < len(lines)


def _stop_word_and_copy_edited(path: Path, word: int) -> None:
    """The window's stopping heartbeat says e-stop word ``word``, and its copy of the stop
    record is edited to match what a core makes of that: a consistent forgery."""
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    last = json.loads(lines[-2])
    assert last["message"]["payload"] == "090001000000"  # Operational, e-stop word 0x01
    last["message"]["payload"] = "0900" + word.to_bytes(4, "little").hex()
    lines[-2] = json.dumps(last)
    path.write_text("\n".join(lines) + "\n")
    made = replay(read_window(path), {}).steps[-1].records[0][0]  # what the edit makes
    header["stop"] = {**made, "utc": header["stop"]["utc"]}
    lines[0] = json.dumps(header)
    path.write_text("\n".join(lines) + "\n")


def test_a_window_whose_copy_of_the_stop_differs_from_the_record_file_is_not_the_record(
    tmp_path: Path,
) -> None:
    """SR-7.13: the record file is the record that counts: a window whose stopping e-stop word
    was edited (0x01, the remote's, to 0x04) together with its copy of the stop record replays
    to that copy, but the record file says remote, 0x00000001: ``srcsctl replay`` names the
    differing fields, never says it matches, and exits 5."""
    story_run = run(story())
    path = _written(tmp_path, story_run)
    _stop_word_and_copy_edited(path, 0x04)
    assert read_window(path).stop["causes"] != story_run.stop["causes"]
    code, said = _replay(tmp_path, str(story_run.stop["seq"]))
    assert code == EXIT_NOT_THE_RECORD, said
    assert f"copy of stop record #{story_run.stop['seq']} differs from the record file" in said
    assert "differing fields: causes" in said, said
    assert "replay matches" not in said
    assert "reproduced" not in said


def _with_line(path: Path, index: int, line: str) -> None:
    """``path`` with its line ``index`` replaced by ``line``."""
    lines = path.read_text().splitlines()
    lines[index] = line
    path.write_text("\n".join(lines) + "\n")


def _snapshot_window(tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    """A window from a snapshot base, and its snapshot line."""
    inputs = story()
    story_run = run(inputs, snapshot_at=[len(inputs) // 2])
    path = _written(tmp_path, story_run, bases=story_run.bases[1:])
    return path, json.loads(path.read_text().splitlines()[1])


@pytest.mark.parametrize(
    ("index", "depth"),
    [(2, 100_000), (-2, 100_000), (2, MAX_NESTING + 1)],
    ids=["an input past the parser's stack", "the last input", "an input just past the bound"],
)
def test_a_deeply_nested_line_cannot_be_read(tmp_path: Path, index: int, depth: int) -> None:
    """SR-7.13: a window line nested deeper than any window's (lists in lists, however deep)
    is a window that cannot be read: ``srcsctl replay`` says which line and exits 2, never a
    traceback and never a mismatch."""
    path, _ = _snapshot_window(tmp_path)
    _with_line(path, index, "[" * depth + "]" * depth)
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_BAD_INPUT, said
    assert "nested" in said, said


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (lambda f: f.update(handle=1), "does not declare: ['handle']"),
        (lambda f: f.pop("_state"), "declared fields missing: ['_state']"),
        (lambda f: f.update(_sequence="41"), "_sequence: not of its declared type"),
        (lambda f: f["_book"]["f"].update(pulse=None), "does not declare: ['pulse']"),
    ],
    ids=["a key that shadows a method", "a key missing", "a value of another type", "nested"],
)
def test_a_hostile_snapshot_cannot_be_replayed(tmp_path: Path, change: Any, said: str) -> None:
    """SR-7.11, SR-7.13: a snapshot with a field its class does not declare (``handle``, which
    would shadow the core's method), without one it declares, or with a value of another
    type is refused as a window that cannot be replayed (exit 2), the field named."""
    path, line = _snapshot_window(tmp_path)
    change(line["snapshot"]["f"])
    _with_line(path, 1, json.dumps(line))
    code, output = _replay(tmp_path, str(path))
    assert code == EXIT_BAD_INPUT, output
    assert said in output, output


DEEP = '"deep"'


def _deep_text(depth: int) -> str:
    """A JSON value of lists and objects in turn, ``depth`` deep, as text (the encoder's own
    stack would not reach)."""
    opening = "".join("[" if level % 2 else '{"v":' for level in range(depth))
    closing = "".join("]" if level % 2 else "}" for level in reversed(range(depth)))
    return opening + "1" + closing


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    depth=st.integers(min_value=MAX_NESTING + 1, max_value=50_000),
    where=st.sampled_from(["input", "snapshot", "stop"]),
)
def test_any_nesting_past_the_bound_is_exit_2(
    tmp_path_factory: Any, depth: int, where: str
) -> None:
    """SR-7.13, property: lists and objects nested any depth past the bound in an input, the
    snapshot or the header's stop record give exit 2, never a traceback."""
    tmp_path = tmp_path_factory.mktemp("deep")
    path, line = _snapshot_window(tmp_path)
    lines = path.read_text().splitlines()
    if where == "input":
        lines[2] = _deep_text(depth)
    elif where == "snapshot":
        line["snapshot"]["f"]["_book"] = "deep"
        lines[1] = json.dumps(line).replace(DEEP, _deep_text(depth))
    else:
        header = json.loads(lines[0])
        header["stop"]["causes"] = "deep"
        lines[0] = json.dumps(header).replace(DEEP, _deep_text(depth))
    path.write_text("\n".join(lines) + "\n")
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_BAD_INPUT, said
    assert "nested" in said, said


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.text(max_size=5),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3)
    ),
    max_leaves=8,
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    key=st.text(min_size=1, max_size=12),
    value=JSON_VALUES,
    owner=st.sampled_from(["", "_book", "_proof", "_display", "_budget"]),
)
def test_any_extra_snapshot_key_is_exit_2(
    tmp_path_factory: Any, key: str, value: Any, owner: str
) -> None:
    """SR-7.13, property: any key a class does not declare, with any JSON value, on the core
    or on an object inside it, gives exit 2, never a traceback."""
    tmp_path = tmp_path_factory.mktemp("extra")
    path, line = _snapshot_window(tmp_path)
    fields = line["snapshot"]["f"]
    target = fields[owner]["f"] if owner else fields
    if key in target:
        return  # a declared field: not an extra key
    target[key] = value
    _with_line(path, 1, json.dumps(line))
    code, said = _replay(tmp_path, str(path))
    assert code == EXIT_BAD_INPUT, said
