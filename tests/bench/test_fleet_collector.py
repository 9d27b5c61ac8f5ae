"""The fleet collector bench, small: two robots, two records each, through the real
systemd-journal-remote over HTTPS in the bench's own network namespace (SR-13.4)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_the_collector_bench_takes_in_every_record_and_answers() -> None:
    """SR-13.4: every record sent is taken in (202) and one more shows in journalctl and in
    ``srcsctl fleet`` within the bench's bound; the table has a row per fleet size."""
    if os.geteuid() != 0 or not Path("/lib/systemd/systemd-journal-remote").exists():
        pytest.skip("needs root (a network namespace) and systemd-journal-remote")
    run = subprocess.run(
        [sys.executable, "-m", "bench.fleet_collector", "--robots", "2,3", "--records", "2",
         "--split-robots", "2"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
        check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    rows = [
        line for line in run.stdout.splitlines() if line.startswith("| ") and "robots" not in line
    ]
    assert [row.split("|")[1:4] for row in rows] == [
        [" 2 ", " host ", " 4 "],
        [" 3 ", " none ", " 6 "],
    ]
    assert [row.split("|")[9] for row in rows] == [" 2 ", " 1 "]  # a file per robot, or one
