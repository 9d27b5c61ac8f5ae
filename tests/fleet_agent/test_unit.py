"""The agent's unit and its user (docs/fleet.md "The agent's unit"): systemd accepts the unit,
and systemd-sysusers makes the user it runs as, from units/, whose files the robot's package
installs (SR-13.13)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

UNITS = Path(__file__).resolve().parents[2] / "units"
UNIT = UNITS / "srcs-fleet-agent@.service"
SYSUSERS = UNITS / "srcs-fleet-agent.sysusers.conf"


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


@pytest.mark.skipif(shutil.which("systemd-sysusers") is None, reason="needs systemd-sysusers")
def test_sysusers_makes_the_user_the_unit_runs_as(tmp_path: Path) -> None:
    """systemd-sysusers, run on the file as the postinst runs it but into an empty root, makes
    the unit's User= and Group=, with no login shell; the unit adds srcsd's group, the API
    socket's, and no other."""
    (tmp_path / "etc").mkdir()
    subprocess.run(
        ["systemd-sysusers", f"--root={tmp_path}", str(SYSUSERS)],
        check=True,
        capture_output=True,
        timeout=60,
    )
    users = {
        line.split(":")[0]: line.split(":")
        for line in (tmp_path / "etc/passwd").read_text().splitlines()
    }
    groups = {line.split(":")[0] for line in (tmp_path / "etc/group").read_text().splitlines()}
    unit = UNIT.read_text()
    (user,) = re.findall(r"^User=(\S+)$", unit, re.MULTILINE)
    (group,) = re.findall(r"^Group=(\S+)$", unit, re.MULTILINE)
    assert user in users, users
    assert users[user][6] == "/usr/sbin/nologin"
    assert group in groups, groups
    assert re.findall(r"^SupplementaryGroups=(.*)$", unit, re.MULTILINE) == ["srcsd"]
