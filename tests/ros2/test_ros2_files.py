"""The bridge's shipped files: the systemd unit example and the parameters example."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from supervisord.ros2.parameters import PARAMETERS

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    """systemd-analyze verify accepts the bridge's unit beside the srcsd@ unit it follows."""
    for name in ("srcs-ros2@.service", "srcsd@.service"):
        shutil.copy(REPO / "units" / name, tmp_path / name)
    result = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / "srcs-ros2@robot-a.service")],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr


def test_examples_and_docs_name_every_parameter() -> None:
    """The parameters file example and docs/ros2.md list exactly the parameters the node
    declares, so neither drifts from the code."""
    example = (REPO / "examples" / "ros2" / "srcs_bridge.yaml").read_text()
    listed = {
        line.split(":")[0].strip()
        for line in example.splitlines()
        if line.startswith("    ") and ":" in line
    }
    assert listed == set(PARAMETERS)
    docs = (REPO / "docs" / "ros2.md").read_text()
    for name in PARAMETERS:
        assert f"| `{name}` |" in docs, name
