"""The integrator's example of docs/testing.md ("The kit for integrators") runs and passes
as it is written: the page's example is itself tested."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "testkit" / "test_my_robot.py"


def test_the_integrators_example_passes() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pytest", str(EXAMPLE), "-q", "-p", "no:cacheprovider"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    # the clock, every check of both suites (and none skipped)
    assert "\n23 passed" in done.stdout, done.stdout
