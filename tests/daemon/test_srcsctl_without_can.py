"""``srcsctl``'s operator commands on a robot without python-can: the e-stop needs nothing
optional (SR-8.8). python-can really fails to import here, as on a robot where it is not
installed: a ``can`` package earlier on the path raises ``ImportError`` when imported."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import SrcsdProcess
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG

NO_CAN = "raise ImportError(\"No module named 'can' (not installed on this robot)\")\n"


@pytest.fixture
def without_can(tmp_path: Path) -> dict[str, str]:
    """The environment of a process in which ``import can`` fails."""
    shadow = tmp_path / "no-python-can"
    (shadow / "can").mkdir(parents=True)
    (shadow / "can" / "__init__.py").write_text(NO_CAN)
    path = os.pathsep.join(p for p in (str(shadow), os.environ.get("PYTHONPATH", "")) if p)
    return {**os.environ, "PYTHONPATH": path}


@pytest.fixture
def config(tmp_path: Path) -> Iterator[Path]:
    """A running ``srcsd`` (it has python-can: only srcsctl's is missing) and its config."""
    path = tmp_path / "robot.toml"
    path.write_text(CONFIG)
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port)
        with SrcsdProcess(path).start(serve=peer.serve) as daemon, peer.serving():
            yield path
    assert daemon.exit_status == 0


def _ctl(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "supervisord.cli.srcsctl", *args]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=30, check=False)


def test_the_shadow_really_breaks_python_can(without_can: dict[str, str]) -> None:
    """SR-8.8, the premise of this module's proof: in its environment ``import can`` raises
    ImportError (a shadow that failed to shadow would prove nothing)."""
    probe = subprocess.run(
        [sys.executable, "-c", "import can"],
        env=without_can,
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert probe.returncode != 0
    assert "ImportError" in probe.stderr


def test_estop_status_hold_and_release_work_without_python_can(
    without_can: dict[str, str], config: Path
) -> None:
    """SR-8.8: with python-can absent, ``estop`` stops the real daemon, ``status`` shows it,
    ``hold`` and ``release`` do what they say; ``decode`` alone says what it needs."""
    where = ("--config", str(config))
    estop = _ctl(without_can, "estop", *where)
    assert estop.returncode == 0, estop.stderr
    assert "local_estop" in _active(without_can, where)
    assert _ctl(without_can, "release", *where).returncode == 0
    hold = _ctl(without_can, "hold", *where)
    assert hold.returncode == 0, hold.stderr
    assert "client_hold:srcsctl" in _active(without_can, where)
    assert _ctl(without_can, "release", "hold", *where).returncode == 0
    assert "client_hold:srcsctl" not in _active(without_can, where)
    human = _ctl(without_can, "status", *where)
    assert human.returncode == 0, human.stderr
    assert "STOPPED" in human.stdout

    decode = _ctl(without_can, "decode", "--can", "-")
    assert decode.returncode == 1
    assert "srcsctl decode: needs python-can" in decode.stderr
    assert "Traceback" not in decode.stderr


def _active(env: dict[str, str], where: tuple[str, str]) -> set[str]:
    status = _ctl(env, "status", "--json", *where)
    assert status.returncode == 0, status.stderr
    return {c["name"] for c in json.loads(status.stdout)["causes"] if c["active"]}
