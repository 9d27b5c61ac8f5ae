"""python-can is loaded only for a robot whose config names a CAN bus (SR-9.4).

Each case builds the daemon's parts from a real config file in a fresh interpreter (a
subprocess, so no other test's imports count) and reports which libraries it loaded.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from supervisord.testkit.daemon import MINIMAL_CONFIG

REPO = Path(__file__).resolve().parents[2]

PROBE = """
import json, sys
from supervisord.config import load_config
from supervisord.daemon.assemble import build_api, build_supervisor
config = load_config(sys.argv[1])
build_supervisor(config, build_api(config))
print(json.dumps(sorted(m for m in ("can", "serial") if m in sys.modules)))
"""

SERIAL_VSC = 'transport = "serial"\nport = "vsc"\n'
CAN_VSC = MINIMAL_CONFIG.replace(
    SERIAL_VSC,
    'transport = "can"\ninterface = "virtual"\nchannel = "srcs-import-test"\n'
    "require_watchdog = false\n",
)


def loaded(tmp_path: Path, config: str) -> list[str]:
    """The libraries among python-can and pyserial that building the daemon imported."""
    (tmp_path / "robot.toml").write_text(config)
    # Our own interpreter running our own probe on our own config.
    result = subprocess.run(
        [sys.executable, "-c", PROBE, str(tmp_path / "robot.toml")],
        cwd=tmp_path,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    names: list[str] = json.loads(result.stdout.strip().splitlines()[-1])
    return names


def test_a_serial_robot_never_imports_python_can(tmp_path: Path) -> None:
    """Building the whole daemon for a serial VSC loads pyserial and not python-can."""
    assert loaded(tmp_path, MINIMAL_CONFIG) == ["serial"]


def test_a_can_robot_imports_python_can(tmp_path: Path) -> None:
    """The same probe sees python-can when the VSC is on CAN (the probe can tell)."""
    assert "can" in loaded(tmp_path, CAN_VSC)
