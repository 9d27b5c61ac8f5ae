"""SR-7.9: a record that cannot be opened for want of permission is said with whose it is and
what to do. ``srcsctl log`` never answers "nothing" for a record it may not read: a user
outside the record's group, and a user in it facing a record left root's by a run as root,
each get exit 1 and that message, with ``--file`` and ``-f`` alike; never a traceback, never
exit 0 without the records. ``srcsd`` as its service user, facing a record a run as root
left behind, names the ``chown`` that gives it back."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.daemon.test_srcsctl import SRCSCTL, _records

SRCSD = str(Path(SRCSCTL).with_name("srcsd"))

NOBODY = 65534
GROUP = 4242
"""The record's group in these tests: a number no account of the machine needs to have."""


@pytest.fixture
def shared() -> Iterator[Path]:
    """A folder every user may pass through (pytest's own are root's alone), removed after."""
    folder = Path(tempfile.mkdtemp(prefix="srcs-log-access-"))
    folder.chmod(0o755)
    try:
        yield folder
    finally:
        shutil.rmtree(folder)


def _log_as(groups: str, *args: str) -> subprocess.CompletedProcess[str]:
    """``srcsctl log ARGS`` as the user nobody with the supplementary ``groups`` given."""
    who = ["--clear-groups"] if not groups else [f"--groups={groups}"]
    return subprocess.run(
        ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", *who, SRCSCTL, "log", *args],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )


def _record_in(shared: Path, *, folder_group: int, file_owner: int, file_mode: int) -> Path:
    """A record of three entries in a folder ``root:folder_group`` 0750, the file
    ``file_owner:file_owner`` with ``file_mode``."""
    folder = shared / "srcsd"
    folder.mkdir()
    path = _records(folder)
    os.chown(folder, 0, folder_group)
    folder.chmod(0o750)
    os.chown(path, file_owner, file_owner)
    path.chmod(file_mode)
    return path


@pytest.mark.parametrize("follow", [False, True], ids=["file", "follow"])
def test_a_user_outside_the_group_is_told_to_join_it(shared: Path, follow: bool) -> None:
    """SR-7.9: a user outside the record's group gets exit 1, "Permission denied" and the
    command that lets them read it (join the group, or sudo), for ``--file`` and ``-f``."""
    path = _record_in(shared, folder_group=GROUP, file_owner=NOBODY, file_mode=0o640)
    done = _log_as("", "--file", str(path), *(["-f"] if follow else []))
    assert done.returncode == 1, done
    assert "Traceback" not in done.stderr
    assert f"cannot read {path.parent}: Permission denied" in done.stderr
    assert f"usermod -aG {GROUP} $USER" in done.stderr
    assert done.stdout == ""


@pytest.mark.parametrize("follow", [False, True], ids=["file", "follow"])
def test_a_record_left_by_root_says_how_to_give_it_back(shared: Path, follow: bool) -> None:
    """SR-7.9: a user in the record's group facing a record file of root's (a run by hand as
    root) gets exit 1, not an empty answer: whose it is and the chown that gives it back to
    the service's user."""
    path = _record_in(shared, folder_group=GROUP, file_owner=0, file_mode=0o600)
    done = _log_as(str(GROUP), "--file", str(path), *(["-f"] if follow else []))
    assert done.returncode == 1, done
    assert "Traceback" not in done.stderr
    assert f"cannot read {path}: Permission denied: it is root:root, mode 600" in done.stderr
    assert f"sudo chown -R srcsd:srcsd {path.parent}" in done.stderr
    assert "not_a_file" not in done.stderr


def test_the_group_reads_the_record(shared: Path) -> None:
    """SR-7.9: the same folder and file, readable by the group, are read by its member: the
    refusals above come from the permissions alone."""
    path = _record_in(shared, folder_group=GROUP, file_owner=NOBODY, file_mode=0o640)
    os.chown(path, 0, GROUP)
    done = _log_as(str(GROUP), "--file", str(path))
    assert done.returncode == 0, done.stderr
    assert [line.split()[1] for line in done.stdout.splitlines()] == ["#1", "#2", "#3"]


CONFIG = """\
[robot]
name = "bot"

[vsc]
transport = "serial"
port = "vsc"

[[outputs]]
name = "drive"
kind = "sim"

[record]
path = "stops.jsonl"
journal = false

[api]
socket = "api.sock"
"""


def test_srcsd_names_the_chown_for_a_record_left_by_root(shared: Path) -> None:
    """SR-7.9: srcsd run as its service user on a record file that a run as root left
    root:root 0600 does not start (exit 1) and says whose the file is and the ``chown`` that
    gives the record back to the service."""
    folder = shared / "robot"
    folder.mkdir()
    config = folder / "robot.toml"
    config.write_text(CONFIG)
    record = folder / "stops.jsonl"
    record.touch(mode=0o600)
    os.chown(folder, NOBODY, NOBODY)  # the service's own folder, as tmpfiles makes it
    done = subprocess.run(
        [
            "setpriv",
            f"--reuid={NOBODY}",
            f"--regid={NOBODY}",
            "--clear-groups",
            SRCSD,
            "--config",
            str(config),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1, done
    assert f"cannot start: cannot open {record}: Permission denied: it is root:root, mode 600" in (
        done.stderr
    )
    assert f"sudo chown -R srcsd:srcsd {folder}" in done.stderr
