"""The documented check is the daemon's start (SR-11.2): ``srcsd --check-config FILE``, as the
docs write it, fails with the line for what this machine lacks that the daemon's start refuses
(a user, a group, the directory of the record or of a socket), and ``--portable`` makes those
warnings; the real daemon refuses a missing directory as a config error (exit 78, no restart)
rather than failing its bind (exit 1, restarted). docs/configuration.md "Checking a config"."""

from __future__ import annotations

import pwd
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
EXAMPLE = "config/example-serial-gpio.toml"

VALID = """\
[robot]
name = "bench"

[vsc]
transport = "serial"
port = "no-vsc"

[[outputs]]
name = "drive"
kind = "sim"

[record]
path = "{record}"
journal = false

[api]
socket = "{socket}"
"""


def _srcsd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsd", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=ROOT,
    )


def _line(text: str, start: str) -> int:
    return 1 + next(i for i, line in enumerate(text.splitlines()) if line.startswith(start))


def test_the_documented_check_fails_for_the_shipped_example_without_its_users() -> None:
    """SR-11.2: the example's ``srcsd --check-config FILE`` fails (exit 1) on a machine
    without its clients' user, naming the key at its line as an error; ``--portable`` (a
    config checked here for another machine) passes it, the user a warning that says so."""
    try:
        pwd.getpwnam("robot")
    except KeyError:
        pass
    else:  # pragma: no cover - a machine with the example's user
        pytest.skip("this machine has the user robot")
    text = (ROOT / EXAMPLE).read_text()
    line = _line(text, 'user = "robot"')
    checked = _srcsd("--check-config", EXAMPLE)
    assert checked.returncode == 1, checked.stdout
    assert f'{EXAMPLE}:{line}: error: clients[0].user = "robot": no such user' in checked.stderr
    portable = _srcsd("--check-config", EXAMPLE, "--portable")
    assert portable.returncode == 0, portable.stderr
    assert f'{EXAMPLE}:{line}: warning: clients[0].user = "robot"' in portable.stderr
    assert "a warning only with --portable" in portable.stderr


@pytest.mark.parametrize("key", ["record", "socket"])
def test_a_directory_the_daemon_needs_fails_the_check_and_the_start(
    tmp_path: Path, key: str
) -> None:
    """SR-11.2: a record or socket in a directory that does not exist fails the documented
    check (exit 1, the key at its line) and the real daemon's start with exit 78 (EX_CONFIG:
    the unit does not restart it), not a failed open or bind (exit 1, five restarts)."""
    paths = {"record": tmp_path / "stops.jsonl", "socket": tmp_path / "api.sock"}
    paths[key] = tmp_path / "absent" / paths[key].name
    text = VALID.format(**paths)
    config = tmp_path / "robot.toml"
    config.write_text(text)
    line = _line(text, "path =" if key == "record" else "socket =")
    name = "record.path" if key == "record" else "api.socket"
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1, checked.stdout
    assert f"{config}:{line}: error: {name} = " in checked.stderr
    assert f"the directory of the {key}, {tmp_path / 'absent'}, does not exist" in checked.stderr
    assert f"install -d -o srcsd -g srcsd -m 0750 {tmp_path / 'absent'}" in checked.stderr
    started = _srcsd("--config", str(config))
    assert started.returncode == 78, started.stderr
    assert f"{config}:{line}: error: {name} = " in started.stderr
    assert _srcsd("--check-config", str(config), "--portable").returncode == 0
    (tmp_path / "absent").mkdir()
    assert _srcsd("--check-config", str(config)).returncode == 0


def test_the_units_own_directories_count_as_there_for_the_check(tmp_path: Path) -> None:
    """SR-11.2: srcsd@NAME.service makes /run/srcsd/NAME and /var/lib/srcsd/NAME at its start
    (RuntimeDirectory=, StateDirectory=), so the check of NAME.toml before the first start
    passes them, and refuses a robot's directory that the unit of this name does not make."""
    if Path("/run/srcsd/other").exists():  # pragma: no cover - a robot named other here
        pytest.skip("/run/srcsd/other exists on this machine")
    config = tmp_path / "robot-a.toml"
    config.write_text(
        VALID.format(record="/var/lib/srcsd/robot-a/stops.jsonl", socket="/run/srcsd/robot-a/a.s")
    )
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 0, checked.stderr
    config.write_text(
        VALID.format(record="/var/lib/srcsd/robot-a/stops.jsonl", socket="/run/srcsd/other/a.s")
    )
    checked = _srcsd("--check-config", str(config))
    assert checked.returncode == 1
    assert 'error: api.socket = "/run/srcsd/other/a.s": the directory of the socket' in (
        checked.stderr
    )
