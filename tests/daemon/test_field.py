"""What a field engineer sees of a running ``srcsd``: its version everywhere, the exit status
of a bad configuration (SR-11.2), and the priority of every log line."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import supervisord
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import SrcsdProcess
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG, SRCSD

BIN = Path(SRCSD).parent
UNIT = Path(__file__).parents[2] / "units" / "srcsd@.service"


@pytest.mark.parametrize("program", ["srcsd", "srcsctl", "srcs-sim"])
def test_every_program_says_its_version(program: str) -> None:
    """``--version`` prints the program's name and the package's version, and exits 0."""
    path = shutil.which(program) or str(BIN / program)
    result = subprocess.run(
        [path, "--version"], capture_output=True, text=True, timeout=30, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"{program} {supervisord.__version__}"


def test_version_comes_from_the_package_metadata() -> None:
    """``supervisord.__version__`` is the installed distribution's version, not a copy."""
    from importlib.metadata import version  # noqa: PLC0415

    assert supervisord.__version__ == version("srcs-supervisord")
    assert re.fullmatch(r"\d+\.\d+\.\d+.*", supervisord.__version__)


def test_bad_config_exits_78_and_the_unit_does_not_restart_it(tmp_path: Path) -> None:
    """A configuration error is EX_CONFIG (78), which the unit lists in
    RestartPreventExitStatus= so systemd does not restart-loop it (SR-6.5's clean refusal)."""
    bad = tmp_path / "bad.toml"
    bad.write_text(CONFIG.replace('transport = "serial"', 'transport = "x"'))
    result = subprocess.run(
        [SRCSD, "--config", str(bad)], capture_output=True, text=True, timeout=30, check=False
    )
    assert result.returncode == 78, result.stderr
    assert "vsc.transport" in result.stderr
    missing = subprocess.run(
        [SRCSD, "--config", str(tmp_path / "none.toml")],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert missing.returncode == 78
    unit = UNIT.read_text()
    assert re.search(r"^RestartPreventExitStatus=.*\b78\b", unit, re.M), "unit lacks 78"
    assert re.search(r"^Restart=on-failure$", unit, re.M)


def _run_logging(tmp_path: Path, env: dict[str, str]) -> tuple[list[str], int]:
    """Start srcsd with its stderr in a file (so JOURNAL_STREAM can name that file), with no
    VSC at its port (a warning) and then stop it; return its stderr lines."""
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    log = tmp_path / "stderr"
    with log.open("w") as stderr:
        stat = os.fstat(stderr.fileno())
        env = {k: v.replace("@STREAM@", f"{stat.st_dev}:{stat.st_ino}") for k, v in env.items()}
        daemon = subprocess.Popen(
            [SRCSD, "--config", str(config)],
            stderr=stderr,
            env={**os.environ, **env},
        )
        try:
            deadline = 20.0
            import time  # noqa: PLC0415

            end = time.monotonic() + deadline
            while "cannot open" not in log.read_text():
                assert time.monotonic() < end, log.read_text()
                assert daemon.poll() is None, log.read_text()
                time.sleep(0.05)
        finally:
            daemon.terminate()
            status = daemon.wait(timeout=20)
    return log.read_text().splitlines(), status


def test_log_lines_carry_their_priority_for_the_journal(tmp_path: Path) -> None:
    """With stderr connected to the journal (JOURNAL_STREAM names it, sd-daemon(3)), every line
    starts with its syslog priority ``<N>``, so ``journalctl -p warning`` sees the warnings."""
    os.environ.pop("JOURNAL_STREAM", None)
    lines, status = _run_logging(tmp_path, {"JOURNAL_STREAM": "@STREAM@"})
    assert status == 0
    assert lines, "no log lines"
    assert all(re.match(r"<[0-7]>", line) for line in lines), lines
    starting = [line for line in lines if "robot test-robot" in line]
    assert starting, lines
    assert starting[0].startswith("<6>"), lines
    warnings = [line for line in lines if "cannot open" in line]
    assert warnings, lines
    assert warnings[0].startswith("<4>"), lines


def test_log_lines_on_a_terminal_have_no_prefix(tmp_path: Path) -> None:
    """Without the journal (or with JOURNAL_STREAM naming another file) lines are plain text
    with the level in words, and the start line names the version."""
    lines, status = _run_logging(tmp_path, {"JOURNAL_STREAM": "1:2"})
    assert status == 0
    assert not any(re.match(r"<[0-7]>", line) for line in lines), lines
    start = next(line for line in lines if "robot test-robot" in line)
    assert f"srcsd {supervisord.__version__}" in start
    assert any(line.startswith("srcsd: WARNING: ") for line in lines), lines


def test_config_error_reaches_the_journal_as_an_error(tmp_path: Path) -> None:
    """The refusal of a bad configuration is logged at priority 3 (err) for the journal."""
    bad = tmp_path / "bad.toml"
    bad.write_text(CONFIG.replace('transport = "serial"', 'transport = "x"'))
    log = tmp_path / "stderr"
    with log.open("w") as stderr:
        stat = os.fstat(stderr.fileno())
        status = subprocess.run(
            [SRCSD, "--config", str(bad)],
            stderr=stderr,
            env={**os.environ, "JOURNAL_STREAM": f"{stat.st_dev}:{stat.st_ino}"},
            timeout=30,
            check=False,
        ).returncode
    assert status == 78
    text = log.read_text()
    assert text.startswith("<3>"), text
    assert "vsc.transport" in text


def test_version_in_status_and_in_the_first_record(tmp_path: Path) -> None:
    """``status`` names the daemon's version, and the record's first entry of a start (the
    startup stop) carries it, so a stop record says which build made it."""
    (tmp_path / "robot.toml").write_text(CONFIG)
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port)
        with (
            SrcsdProcess(tmp_path / "robot.toml").start(serve=peer.serve),
            peer.serving(),
        ):
            ctl = shutil.which("srcsctl") or str(BIN / "srcsctl")
            result = subprocess.run(
                [ctl, "status", "--json", "--config", str(tmp_path / "robot.toml")],
                capture_output=True,
                text=True,
                timeout=30,
                check=False,
            )
            assert result.returncode == 0, result.stderr
            assert json.loads(result.stdout)["daemon"]["version"] == supervisord.__version__
    records = [json.loads(line) for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
    assert records[0]["version"] == supervisord.__version__
    assert all("version" not in r for r in records[1:])


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__]))
