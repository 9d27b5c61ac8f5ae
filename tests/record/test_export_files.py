"""The files ``srcsctl`` writes are safe against links and shared folders (SR-11.4;
``supervisord/cli/output_file.py``, docs/srcsctl.md "Files srcsctl writes"): the real
``srcsctl replay --mcap --plot`` never writes through a link planted at a temporary name (the
old fixed ``.NAME.tmp`` made root overwrite a file of another user's choosing), refuses a
link or a device as its target and leaves it as it was (``--plot /dev/stdout`` once replaced
the system's ``/dev/stdout`` with a file), and writes to standard output for ``-``; the man
pages and completions are written the same way."""

from __future__ import annotations

import ast
import io
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from mcap.reader import make_reader

from supervisord.cli import reference
from supervisord.cli.output_file import OutputRefused, write_output
from tests.record.stop_kinds import KINDS, RECORD

ROOT = Path(__file__).resolve().parents[2]
SECRET = b"root's own file, not to be written\n"


def _window(folder: Path) -> int:
    """A remote e-stop's record and window in ``folder``; the stop's sequence number."""
    story = KINDS["remote_estop"]()
    story.write(folder)
    seq: int = story.stop["seq"]
    return seq


def _srcsctl(folder: Path, *args: str) -> subprocess.CompletedProcess[bytes]:
    """The real ``srcsctl replay`` of the window in ``folder``, run there."""
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsctl", "replay", "--file", RECORD, *args],
        capture_output=True,
        timeout=120,
        cwd=folder,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        check=False,
    )


def _victim(tmp_path: Path, name: str = "victim") -> Path:
    """A file another user wants overwritten (root's ``/etc/shadow`` in the attack)."""
    victim = tmp_path / "elsewhere" / name
    victim.parent.mkdir(exist_ok=True)
    victim.write_bytes(SECRET)
    return victim


def test_a_link_planted_at_the_old_temporary_name_is_never_written_through(
    tmp_path: Path,
) -> None:
    """SR-11.4: in a shared folder another user plants ``.stop.svg.tmp`` and ``.stop.mcap.tmp``
    as links to a file of theirs choosing; ``replay --mcap --plot`` writes both files whole
    (exit 0), each a regular file, and neither victim is changed; the links are left alone
    and no temporary file of the run remains."""
    seq = _window(tmp_path)
    victims = [_victim(tmp_path, "a"), _victim(tmp_path, "b")]
    for name, victim in zip(("stop.svg", "stop.mcap"), victims, strict=True):
        (tmp_path / f".{name}.tmp").symlink_to(victim)
    done = _srcsctl(tmp_path, str(seq), "--mcap", "stop.mcap", "--plot", "stop.svg")
    assert done.returncode == 0, done.stdout + done.stderr
    for victim in victims:
        assert victim.read_bytes() == SECRET, f"{victim} was written through the link"
    assert (tmp_path / "stop.svg").read_bytes().startswith(b"<svg")
    assert not (tmp_path / "stop.svg").is_symlink()
    with (tmp_path / "stop.mcap").open("rb") as file:
        assert any(True for _ in make_reader(file).iter_messages())
    assert (tmp_path / ".stop.svg.tmp").is_symlink()
    left = sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp"))
    assert left == [".stop.mcap.tmp", ".stop.svg.tmp"], left


@pytest.mark.parametrize("option", ["--plot", "--mcap"])
@pytest.mark.parametrize("kind", ["a link to a file", "a link like /dev/stdout", "a FIFO"])
def test_a_link_or_a_device_as_the_target_is_refused(
    tmp_path: Path, option: str, kind: str
) -> None:
    """SR-11.4: ``--plot`` or ``--mcap`` naming a symbolic link (to a file, or to the process's
    standard output as ``/dev/stdout`` is) or a FIFO is refused before the replay: exit 2, what
    to give instead, no traceback; the link is still the same link and what it names, and the
    FIFO, are as they were."""
    seq = _window(tmp_path)
    victim = _victim(tmp_path)
    target = tmp_path / "out"
    if kind == "a link to a file":
        target.symlink_to(victim)
    elif kind == "a link like /dev/stdout":
        target.symlink_to("/proc/self/fd/1")
    else:
        os.mkfifo(target)
    before = os.readlink(target) if target.is_symlink() else None
    done = _srcsctl(tmp_path, str(seq), option, "out")
    said = done.stderr.decode()
    assert done.returncode == 2, said
    assert "Traceback" not in said, said
    assert "- for standard output" in said, said
    assert ("symbolic link" in said) == (before is not None), said
    if before is not None:
        assert target.is_symlink()
        assert os.readlink(target) == before
    else:
        assert target.is_fifo()
    assert victim.read_bytes() == SECRET
    assert b"replay matches" not in done.stdout  # refused before the replay


def test_plot_dash_writes_the_picture_to_standard_output(tmp_path: Path) -> None:
    """SR-11.4: ``--plot -`` writes the SVG to standard output and nothing else (the replay's
    text goes to standard error); no file named ``-`` is made."""
    seq = _window(tmp_path)
    done = _srcsctl(tmp_path, str(seq), "--plot", "-")
    assert done.returncode == 0, done.stderr
    root = ET.fromstring(done.stdout)  # noqa: S314 - our own output
    assert root.tag == "{http://www.w3.org/2000/svg}svg", root.tag
    said = done.stderr.decode()
    assert "replay matches the record" in said, said
    assert "plot: wrote standard output" in said, said
    assert not (tmp_path / "-").exists()


def test_mcap_dash_writes_the_file_to_standard_output(tmp_path: Path) -> None:
    """SR-11.4: ``--mcap -`` writes the MCAP file to standard output, read whole by the mcap
    library's reader; ``--mcap - --plot -`` is refused (exit 2): one stream holds one file."""
    seq = _window(tmp_path)
    done = _srcsctl(tmp_path, str(seq), "--mcap", "-")
    assert done.returncode == 0, done.stderr
    messages = list(make_reader(io.BytesIO(done.stdout)).iter_messages())
    assert messages
    both = _srcsctl(tmp_path, str(seq), "--mcap", "-", "--plot", "-")
    assert both.returncode == 2, both.stderr
    assert b"only one of --mcap and --plot" in both.stderr
    assert not both.stdout


def test_a_failed_write_leaves_no_temporary_file_and_the_old_file(tmp_path: Path) -> None:
    """SR-11.4: a write that fails midway leaves the target as it was and no temporary file."""
    target = tmp_path / "out"
    target.write_bytes(b"before")

    def fail(file: object) -> None:
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        write_output(target, fail)
    assert target.read_bytes() == b"before"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    write_output(target, lambda file: file.write(b"after"))
    assert target.read_bytes() == b"after"
    assert oct(target.stat().st_mode & 0o777) != "0o600"  # the umask's, as open() would


def test_the_man_pages_are_never_written_through_a_link(tmp_path: Path) -> None:
    """SR-11.4: ``python -m supervisord.cli.reference man DIR`` (a package build, perhaps as
    root) refuses a link planted at a page's name and leaves its victim as it was."""
    victim = _victim(tmp_path)
    pages = tmp_path / "man"
    pages.mkdir()
    (pages / "srcsctl.1").symlink_to(victim)
    with pytest.raises(OutputRefused, match="symbolic link"):
        reference.write_man(pages)
    assert victim.read_bytes() == SECRET
    assert reference.main(["man", str(pages)]) == 1
    assert victim.read_bytes() == SECRET
    (pages / "srcsctl.1").unlink()
    written = reference.write_man(pages)
    assert all(path.is_file() and not path.is_symlink() for path in written)


WRITERS = {"write_text", "write_bytes", "symlink_to", "mkfifo", "os.replace", "os.rename"}
"""Calls that make or replace a file at a path: only ``output_file`` may, in the commands
(``os.replace``, not ``str.replace``)."""
ALLOWED = {
    "output_file.py": "the helper itself",
    "demo.py": "srcsd.log in the demo's own private temporary folder (mkdtemp)",
    # The collector's own tools (not srcsctl): each writes under a random name made by
    # tempfile (mkdtemp, mkstemp: exclusive, never through a link) and renames it into place,
    # with modes of its own (a key 0600); a link at the target is replaced, not followed.
    "fleet_pki.py": "keys and certificates made in a private mkdtemp folder, then renamed",
    "fleet_targets.py": "Prometheus' targets written by mkstemp, then renamed",
    # The window and records a collector's replay reads, laid out in a private folder of its
    # own (TemporaryDirectory: 0700, a random name), never at a path its user names.
    "fleet_replay.py": "the replay's input in its own private TemporaryDirectory",
}


def _writes(path: Path) -> list[str]:
    """Where ``path``'s code makes a file itself: a writer call, or ``open`` with a mode that
    writes (``w``, ``a``, ``x``, ``+``)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Call):
            continue
        name = getattr(node.func, "attr", getattr(node.func, "id", ""))
        owner = getattr(node.func, "value", None)
        if isinstance(owner, ast.Name) and owner.id == "os":
            name = f"os.{name}"
        modes = [
            a.value
            for a in (*node.args, *(k.value for k in node.keywords if k.arg == "mode"))
            if isinstance(a, ast.Constant) and isinstance(a.value, str)
        ]
        writes = name == "open" and any(
            set(m) & set("wax+") and set(m) <= set("rwaxbt+") for m in modes
        )
        if name in WRITERS or writes:
            found.append(f"{path.name}:{node.lineno} {name}")
    return found


def test_every_file_a_command_writes_goes_through_the_helper() -> None:
    """SR-11.4: no command module (``supervisord/cli``) makes or replaces a file but through
    ``output_file`` (the demo's log in its own private folder excepted), so a new output path
    cannot skip the rule unseen."""
    folder = ROOT / "supervisord" / "cli"
    found = [w for p in sorted(folder.glob("*.py")) if p.name not in ALLOWED for w in _writes(p)]
    assert found == [], found
    for name in ALLOWED:
        assert name == "output_file.py" or _writes(folder / name), f"{name}: no longer needed"
