"""A simulated output's process killed in the middle of a write leaves its
temporary file beside the output; the next open removes it (``supervisord/outputs/sim.py``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.testkit.output_conformance import T0

WRITER = """
import sys, time
from pathlib import Path
from supervisord.outputs.sim import SimOutput, SimSpec
out = SimOutput(SimSpec(name="drive", path=Path(sys.argv[1])))
out.open(0)
print("ready", flush=True)
on = False
while True:
    on = not on
    out.set(on, 0)
"""


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_a_temporary_left_by_a_dead_process_is_removed_on_open(tmp_path: Path) -> None:
    """A temporary file of the output's name left by a process that no longer exists (a
    kill between the temporary's creation and its rename) is gone once the output opens;
    the output file shows off."""
    path = tmp_path / "drive"
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    stale = tmp_path / f".drive.{int(dead.stdout)}.tmp"
    stale.write_bytes(b"1")
    other = tmp_path / ".lamp.1.tmp"  # another output's temporary is not ours to remove
    other.write_bytes(b"1")
    out = SimOutput(SimSpec(name="drive", path=path))
    out.open(T0)
    try:
        assert _temporaries(tmp_path) == [other.name]
        assert path.read_bytes() == b"0\n"
    finally:
        out.close()


def test_a_writer_killed_mid_write_leaves_nothing_after_the_next_open(tmp_path: Path) -> None:
    """A real process switching the output as fast as it can is killed (SIGKILL) at an
    arbitrary moment, twenty times; after each kill the next open leaves no temporary file
    beside the output."""
    path = tmp_path / "drive"
    for round_ in range(20):
        child = subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, text=True
        )
        try:
            assert child.stdout is not None
            assert child.stdout.readline().strip() == "ready"
            time.sleep(0.001 * (round_ % 7))
        finally:
            os.kill(child.pid, signal.SIGKILL)
            child.wait()
            if child.stdout is not None:
                child.stdout.close()
        out = SimOutput(SimSpec(name="drive", path=path))
        out.open(T0)
        try:
            assert _temporaries(tmp_path) == []
        finally:
            out.close()
