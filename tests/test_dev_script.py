"""The README's two commands install what each needs and no more (README "Two commands"):
``./dev demo`` only what the demo uses, ``./dev test`` the tests' real tools besides; the
README names each list as the ``dev`` script has it."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).parents[1]
DEV = ROOT / "dev"
SRCSCTL = ROOT / ".venv" / "bin" / "srcsctl"
TESTS_ONLY = {"socat", "lintian", "prometheus", "chromium", "systemd-journal-remote"}


def _needs(command: str) -> list[str]:
    done = subprocess.run(
        [str(DEV), "needs", command], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_the_demo_needs_only_the_venv() -> None:
    """``./dev demo`` asks Debian for python3-venv alone; ``./dev test`` for the tests' tools
    (a browser, a metrics server, Debian's package checker...) and the demo's too."""
    demo, tests = _needs("demo"), _needs("test")
    assert demo == ["python3-venv"]
    assert set(demo) <= set(tests)
    assert set(tests) >= TESTS_ONLY


def test_the_demo_runs_with_nothing_on_the_path(tmp_path: Path) -> None:
    """The demo's story runs to its end with an empty PATH: it starts nothing but the venv's
    own Python (no socat, no browser), so the venv is all it needs."""
    empty = tmp_path / "bin"
    empty.mkdir()
    done = subprocess.run(
        [str(SRCSCTL), "demo", "--auto"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env={**os.environ, "PATH": str(empty)},
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "supervisor: RUN" in done.stdout


def test_the_readme_names_each_commands_packages() -> None:
    """The README's sentence for each command lists exactly the packages the script has."""
    readme = (ROOT / "README.md").read_text()
    for command in ("demo", "test"):
        said = re.search(rf"^- `\./dev {command}` installs (.*?):", readme, re.M | re.S)
        assert said is not None, command
        assert re.findall(r"`([a-z0-9.-]+)`", said.group(1)) == _needs(command), command
