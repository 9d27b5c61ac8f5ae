"""The agent's unit (docs/fleet.md "The fleet stop"): systemd accepts it."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

UNIT = Path(__file__).resolve().parents[2] / "units/srcs-fleet-agent@.service"


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    """systemd-analyze verify accepts the unit (its ExecStart pointed at this checkout, its
    environment file at an example)."""
    env = tmp_path / "fleet-robot-a.env"
    env.write_text("SRCS_FLEET=f1\nSRCS_FLEET_ROBOT=robot-a\nSRCS_FLEET_BROKER=127.0.0.1\n")
    text = (
        UNIT.read_text()
        .replace(
            "/opt/srcsd/bin/srcs-fleet-agent", f"{sys.executable} -m supervisord.cli.fleet_agent"
        )
        .replace("/etc/srcs/fleet-%i.env", str(tmp_path / "fleet-%i.env"))
    )
    (tmp_path / "srcs-fleet-agent@.service").write_text(text)
    result = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / "srcs-fleet-agent@robot-a.service")],
        check=False,
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr
