"""The configuration's side of the record's files (SR-7.9, SR-7.8, SR-11.1; docs/record.md
"What the record file is", docs/configuration.md "One owner per path"): every file the
record may use is a regular file or not there yet, and is the record's alone."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.config.test_config_rules import load, refused


@pytest.mark.parametrize(
    "name",
    ["stops.jsonl", "stops.jsonl.2", "stops.jsonl.transitions", "stops.jsonl.transitions.1"],
)
def test_a_fifo_under_any_name_of_the_record_is_refused(tmp_path: Path, name: str) -> None:
    """SR-7.9: a FIFO at the record's path, a rotated file's, or the stop transitions' is
    refused at ``record.path``, saying what is there (the loader looks, never opens)."""
    os.mkfifo(tmp_path / name)
    error = refused(tmp_path, {"record": {"path": "stops.jsonl", "keep": 2}})
    assert error.key == "record.path", str(error)
    assert "FIFO" in error.fix, str(error)


def test_a_symlink_at_the_record_path_is_refused(tmp_path: Path) -> None:
    """SR-7.9: a symlink at the record's path is refused (rotation would move the link)."""
    (tmp_path / "elsewhere.jsonl").write_text("")
    (tmp_path / "stops.jsonl").symlink_to(tmp_path / "elsewhere.jsonl")
    error = refused(tmp_path, {"record": {"path": "stops.jsonl"}})
    assert "symbolic link" in error.fix, str(error)


def test_a_regular_record_file_and_absent_ones_are_accepted(tmp_path: Path) -> None:
    """SR-7.9: an existing regular record file (a restart) and missing rotated files load."""
    (tmp_path / "stops.jsonl").write_text("")
    config = load(tmp_path, {"record": {"path": "stops.jsonl"}})
    assert config.record.path == tmp_path / "stops.jsonl"


def test_an_output_at_the_stop_transitions_file_is_refused(tmp_path: Path) -> None:
    """SR-7.8, SR-11.1: the stop transitions' file is the record's: a sim output writing
    ``stops.jsonl.transitions`` would replace it. Refused, naming both keys."""
    error = refused(
        tmp_path,
        {"outputs[0].path": "stops.jsonl.transitions", "record": {"path": "stops.jsonl"}},
    )
    assert {error.key, "outputs[0].path", "record.path"} == {"outputs[0].path", "record.path"}
    assert "one owner" in error.fix, str(error)
