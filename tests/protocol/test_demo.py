"""The README's first command runs and shows the story it promises."""

from __future__ import annotations

import subprocess

from tests.protocol.test_decode_cli import SRCSCTL


def test_demo_shows_stop_and_takeover() -> None:
    """Sped up 50 times, the demo shows Local, Operational, the remote e-stop and the
    takeover back to Operational, decoded through a real pseudo-terminal."""
    done = subprocess.run(
        [SRCSCTL, "demo", "--speed", "50"], capture_output=True, timeout=60, check=True, text=True
    )
    modes = [
        line.split("mode ")[1].split()[0] for line in done.stdout.splitlines() if "mode " in line
    ]
    assert modes == [
        "SEARCHING",
        "LOCAL",
        "OPERATIONAL",
        "LOCAL",
        "OPERATIONAL",
        "PAUSE",
        "OPERATIONAL",
    ]
    assert "E-STOP (remote)" in done.stdout
