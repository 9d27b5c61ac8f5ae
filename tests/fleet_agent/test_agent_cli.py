"""srcs-fleet-agent's and the console's refusals before any network (docs/fleet.md "The
agent's unit"): 78 for a certificate it cannot read (the unit does not restart), 2 for a name
that could widen a topic."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.cli import srcsctl


def _agent(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    base = ["--socket", str(tmp_path / "api.sock"), "--fleet", "f1", "--broker", "127.0.0.1"]
    certs = ["--cafile", str(tmp_path / "ca.pem"), "--cert", str(tmp_path / "a.pem")]
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.fleet_agent", *base, *certs, "--key",
         str(tmp_path / "a.key"), *args],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip


def test_a_missing_certificate_exits_78(tmp_path: Path) -> None:
    done = _agent(tmp_path, "--robot", "robot-a")
    assert done.returncode == 78
    assert "cannot read" in done.stderr


@pytest.mark.parametrize("name", ["robot/#", "+", "a b"])
def test_a_robot_name_that_could_widen_a_topic_exits_2(tmp_path: Path, name: str) -> None:
    done = _agent(tmp_path, "--robot", name)
    assert done.returncode == 2
    assert "1 to 64 letters" in done.stderr


def test_the_console_refuses_a_wildcard_robot(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        srcsctl.main(
            ["fleet", "stop", "robot-#", "--fleet", "f1", "--broker", "127.0.0.1",
             "--cafile", "x", "--cert", "x", "--key", "x", "--name", "console-1"]
        )  # fmt: skip
    assert exited.value.code == 2
    assert "1 to 64 letters" in capsys.readouterr().err


def test_the_console_without_a_broker_says_so_and_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("ca.pem", "c.pem", "c.key"):
        (tmp_path / name).write_text("not a certificate")
    status = srcsctl.main(
        ["fleet", "status", "--fleet", "f1", "--broker", "127.0.0.1:1",
         "--cafile", str(tmp_path / "ca.pem"), "--cert", str(tmp_path / "c.pem"),
         "--key", str(tmp_path / "c.key"), "--name", "console-1"]
    )  # fmt: skip
    assert status == 1
    assert "srcsctl fleet" in capsys.readouterr().err
