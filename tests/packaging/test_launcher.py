"""The package's launcher (packaging/build_deb.py ``LAUNCHER``): run by its own absolute path,
as the units' ``ExecStart=`` runs it, it execs its Python at once, with no child process
(SR-9.8: under srcsd@'s SCHED_FIFO a child's exit and the read of its output wake the
real-time process from below, and the kernel's rtapp monitors flag each, docs/install.md);
through a link it still finds its own tree (SR-0.2).

The launcher is written into a tree of its own here (``bin/python3`` a link to this Python),
so no package is built; a ``PATH`` without ``dirname`` and ``readlink`` is what shows that no
child is asked for.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.packaging import build_script

ROOT = Path(__file__).resolve().parents[2]
PROBE = "import os, sys\n\ndef main():\n    print(sys.argv[1:], os.getpid())\n    return 0\n"


def _launcher_text() -> str:
    return str(build_script.build_deb().LAUNCHER).format(
        name="probe", package="srcs-supervisord", module="probe", function="main"
    )


def _tree(tmp_path: Path) -> Path:
    """``tmp_path/bin/probe``, the launcher, beside ``python3`` (this Python)."""
    bin_dir = tmp_path / "tree" / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python3").symlink_to(sys.executable)
    launcher = bin_dir / "probe"
    launcher.write_text(_launcher_text())
    launcher.chmod(0o755)
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "probe.py").write_text(PROBE)
    return launcher


def _run(path: Path, tmp_path: Path, search: str) -> subprocess.CompletedProcess[str]:
    env = {"PATH": search, "PYTHONPATH": str(tmp_path / "lib"), "LC_ALL": "C"}
    return subprocess.run(
        [str(path), "--config", "x.toml"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_run_by_its_absolute_path_it_execs_python_with_no_child(tmp_path: Path) -> None:
    """SR-9.8: no ``dirname`` or ``readlink`` on the path, and the launcher still runs: it
    asked for none. The program runs in the launcher's own process (one exec, no fork): the pid
    it prints is the one the launcher was started as."""
    launcher = _tree(tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    process = subprocess.Popen(
        [str(launcher), "--config", "x.toml"],
        env={"PATH": str(empty), "PYTHONPATH": str(tmp_path / "lib"), "LC_ALL": "C"},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert out == f"['--config', 'x.toml'] {process.pid}\n"


def test_through_a_link_it_finds_its_own_tree(tmp_path: Path) -> None:
    """SR-0.2: a link elsewhere (as /usr/sbin/srcsd is) runs the python3 beside the launcher,
    not one beside the link."""
    launcher = _tree(tmp_path)
    elsewhere = tmp_path / "sbin"
    elsewhere.mkdir()
    (elsewhere / "probe").symlink_to(launcher)
    result = _run(elsewhere / "probe", tmp_path, os.environ.get("PATH", "/usr/bin:/bin"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("['--config', 'x.toml'] ")
