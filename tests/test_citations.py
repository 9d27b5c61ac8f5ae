"""No tracked file cites an issue number: its readers cannot open the team's issues. A comment,
a docstring or a page says what a change is about by a requirement ID (docs/requirements.md)
or a docs section (``docs/install.md "Signals"``) instead. Changelogs are left out: they are
the history of the releases, written once.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CITATION = re.compile(r"\b[Ii]ssues? #?[0-9]")


def _tracked_text_files() -> list[str]:
    """The repository's tracked files that are text, changelogs left out."""
    listed = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "-z"],
        capture_output=True,
        check=True,
        timeout=60,
    ).stdout.split(b"\0")
    names = []
    for raw in listed:
        name = raw.decode()
        path = ROOT / name
        if not name or "changelog" in path.name.lower() or not path.is_file():
            continue  # nothing, a changelog, or deleted in the working tree
        if b"\0" in path.read_bytes():
            continue  # binary
        names.append(name)
    return names


def test_no_tracked_file_cites_an_issue_number() -> None:
    """Every match of ``\\b[Ii]ssues? #?[0-9]`` in a tracked text file, as file:line."""
    names = _tracked_text_files()
    assert "README.md" in names, names[:20]  # the list is the tree, not nothing
    assert "docs/requirements.md" in names, names[:20]
    found = []
    for name in names:
        text = (ROOT / name).read_text(encoding="utf-8", errors="replace")
        for number, line in enumerate(text.splitlines(), start=1):
            if CITATION.search(line):
                found.append(f"{name}:{number}: {line.strip()}")
    assert not found, "cite a requirement ID or a docs section instead:\n" + "\n".join(found)
