"""The install and bring-up pages' commands create the directories they write into
(docs/install.md, docs/bringup.md; SR-0.2): a team follows them on a fresh Debian 12 or 13,
where a directory that only some systems have (``/etc/sysusers.d`` is absent on Debian 12)
makes the step fail."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = ("docs/install.md", "docs/bringup.md")
# What exists on a fresh Debian 12 or 13 with the package installed: the directories of its
# dependencies (systemd, udev), and /etc/srcs, which its postinst creates (tmpfiles, below).
PRESENT = {Path("/etc/systemd/system"), Path("/etc/udev/rules.d")}


def created_by_package() -> set[Path]:
    """The directories ``units/srcsd.tmpfiles.conf`` creates (the postinst applies it)."""
    lines = (REPO / "units/srcsd.tmpfiles.conf").read_text().splitlines()
    return {Path(line.split()[1]) for line in lines if line.startswith("d ")}


def commands(page: str) -> list[str]:
    """Each shell command of the page: the lines of its ``sh`` blocks and of its indented
    blocks, without ``sudo`` and comments."""
    found: list[str] = []
    fenced = False
    for line in (REPO / page).read_text().splitlines():
        if line.strip().startswith("```"):
            fenced = line.strip() in ("```sh", "```bash", "```console") if not fenced else False
            continue
        text = line.strip() if fenced else line[4:] if line.startswith("    ") else ""
        text = re.sub(r"\s+#.*$", "", text).removeprefix("sudo ").strip()
        if text and not text.startswith("#"):
            found.append(text)
    return found


def written(words: list[str]) -> tuple[Path | None, bool]:
    """The path a ``cp``, ``install`` or ``>`` writes, and whether the command creates its
    directory itself (``install -D``); ``None`` for any other command."""
    if words[0] in ("cp", "install") and len(words) >= 3 and not words[-1].startswith("-"):
        target = words[-1]
        if "-d" in words[1:-1]:
            return None, True
        return Path(target if not target.endswith("/") else target + "x"), "-D" in words
    if ">" in words and words.index(">") + 1 < len(words):
        return Path(words[words.index(">") + 1]), False
    return None, False


@pytest.mark.parametrize("page", PAGES)
def test_each_command_that_writes_a_file_has_its_directory(page: str) -> None:
    """SR-0.2: every ``cp``, ``install`` and ``>`` into an absolute path writes into a directory
    that Debian with the package has, or that an earlier command of the page made
    (``mkdir -p``, ``install -D``): the page runs as written on a fresh system."""
    made = PRESENT | created_by_package()
    missing = []
    for command in commands(page):
        try:
            words = shlex.split(command)
        except ValueError:
            continue
        if not words:
            continue
        if words[0] == "mkdir" and "-p" in words:
            made |= {Path(w) for w in words[1:] if not w.startswith("-")}
            continue
        path, creates = written(words)
        if path is None or not path.is_absolute():
            continue
        if creates:
            made |= set(path.parents)
        elif path.parent not in made:
            missing.append(f"{command!r}: {path.parent} may not exist")
    assert not missing, "\n".join(missing)


def _first(found: list[str], pattern: str) -> int | None:
    return next((i for i, command in enumerate(found) if re.search(pattern, command)), None)


@pytest.mark.parametrize("page", PAGES)
def test_commissioning_is_a_step_after_the_start_and_before_the_motion_service(page: str) -> None:
    """SR-8.18, SR-8.10: a VSC fresh from the box has key 85 off, so the pages a team follows
    commission it (``srcsctl ... commission``) once srcsd@ runs, and before any command starts
    a service behind the gate (``robot-motion@``), which would otherwise wait out its
    ``wait-ready --timeout`` at every boot."""
    found = commands(page)
    start = _first(found, r"systemctl enable .*srcsd@")
    commission = _first(found, r"^srcsctl .*\bcommission\b")
    motion = _first(found, r"systemctl (enable|start|restart) .*robot-motion@")
    assert start is not None, f"{page}: no command starts srcsd@"
    assert commission is not None, f"{page}: no srcsctl ... commission step"
    assert start < commission, f"{page}: commissioning before srcsd@ runs: {found[commission]!r}"
    if motion is not None:
        assert commission < motion, f"{page}: {found[motion]!r} before commissioning"
