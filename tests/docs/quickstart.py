"""The first-hour page's commands, as the tests run them (docs/quickstart.md; SR-0.2).

Every ``sh`` block of the page starts with a tag line: ``# test: STEP in root and guest``
(``in root``, ``in guest``): the block's commands, run as written in that place; or
``# test: STEP by hand``: what only a person with the hardware does, which the test replaces
by the simulator as the page says. ``blocks`` reads them in order; ``STEPS`` is the order
the page must keep. The platform tier runs the ``root`` blocks in a fresh Debian root
(tests/platforms/quickstart.py), the system tier the ``guest`` blocks in its booted virtual
machine (tests/system/guest/quickstart.py); tests/docs/test_quickstart.py checks the page.

Standard library only, Python 3.10: the platform tier runs this with the host's python3.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

PAGE = Path(__file__).resolve().parents[2] / "docs" / "quickstart.md"
PLACES = ("root", "guest")
TAG = re.compile(r"^# test: (?P<step>[a-z]+) (?:in (?P<places>[a-z ]+)|(?P<hand>by hand))$")

STEPS = (
    ("names", "by hand"),
    ("install", "root"),
    ("plug", "by hand"),
    ("device", "root guest"),
    ("users", "root guest"),
    ("config", "root guest"),
    ("commission", "guest"),
    ("enable", "guest"),
    ("motion", "guest"),
    ("takeover", "by hand"),
    ("running", "guest"),
    ("stoptest", "guest"),
    ("rearm", "by hand"),
    ("death", "guest"),
    ("again", "by hand"),
)
"""The page's steps in their order, each with where the tests run it: the package, the device
and its group, the users, the robot's config, commissioning, the units enabled, the motion
service, the first takeover, the first field stop test, the motion service's death."""


class PageError(ValueError):
    """A block without its tag, or a tag the tests cannot read; the message has the line."""


@dataclass(frozen=True)
class Block:
    """One ``sh`` block: its step, where it runs (empty: by hand), its text and first line."""

    step: str
    places: frozenset[str]
    text: str
    line: int

    @property
    def by_hand(self) -> bool:
        return not self.places

    @property
    def where(self) -> str:
        return "by hand" if self.by_hand else " ".join(p for p in PLACES if p in self.places)


def blocks(page: str) -> list[Block]:
    """The page's ``sh`` blocks in order; PageError for one whose first line is no tag."""
    found: list[Block] = []
    lines = page.splitlines()
    index = 0
    while index < len(lines):
        if lines[index].strip() != "```sh":
            index += 1
            continue
        start = index + 1
        end = start
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        if end == len(lines):
            raise PageError(f"line {index + 1}: a ```sh block without its end")
        body = lines[start:end]
        match = TAG.match(body[0]) if body else None
        if match is None:
            raise PageError(
                f"line {start + 1}: a ```sh block must start with '# test: STEP in root and "
                f"guest' (or 'in root', 'in guest', 'by hand'), not {body[:1]}"
            )
        places = frozenset() if match["hand"] else frozenset(match["places"].split(" and "))
        if not places <= set(PLACES):
            raise PageError(f"line {start + 1}: places are root and guest, not {sorted(places)}")
        found.append(Block(match["step"], places, "\n".join(body[1:]) + "\n", start + 1))
        index = end + 1
    return found


def without(page: str, step: str) -> str:
    """The page with the block of ``step`` taken out (the mutation the tests run)."""
    kept = [b for b in blocks(page) if b.step != step]
    removed = [b for b in blocks(page) if b.step == step]
    if not removed:
        raise PageError(f"no step {step} on the page")
    lines = page.splitlines()
    out: list[str] = []
    skip: set[int] = set()
    for block in removed:
        # From the ```sh line to its closing fence (0-based: line - 2 .. line + len - 1).
        first = block.line - 2
        last = first + block.text.count("\n") + 2
        skip.update(range(first, last + 1))
    out = [line for number, line in enumerate(lines) if number not in skip]
    assert len(blocks("\n".join(out))) == len(kept)
    return "\n".join(out) + "\n"


def script(page: str, place: str, hand: dict[str, str]) -> str:
    """A bash script of the page's blocks for ``place``, in order: each block as written,
    each hand step as ``hand[STEP]`` (the test's stand-in; nothing when it has none), each
    announced by ``== STEP`` on stdout; it stops at the first command that fails."""
    parts = ["set -euo pipefail"]
    for block in blocks(page):
        if block.by_hand:
            parts.append(f"echo '== {block.step} (by hand: the test)'")
            parts.append(hand.get(block.step, ":"))
        elif place in block.places:
            parts.append(f"echo '== {block.step}'")
            parts.append(block.text)
    parts.append("echo '== done'")
    return "\n".join(parts) + "\n"


def last_step(output: str) -> str:
    """The step a script's output reached last (``done`` when it ran to the end)."""
    marks = [line[3:].split(" (")[0] for line in output.splitlines() if line.startswith("== ")]
    return marks[-1] if marks else ""
