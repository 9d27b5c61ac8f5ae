"""The packaged unit's system call filter lets srcsd do what its start needs (SR-8.14).

``srcsd@.service`` denies ``@privileged``, which holds ``@chown``; srcsd gives its operator
socket to ``api.operator_group`` by a chown of the socket's group, so with ``@chown`` denied
every config that names an operator group (the shipped examples, docs/quickstart.md's) failed
its start under systemd: ``cannot serve the API at /run/srcsd/api-operator.sock: Operation not
permitted`` (seen in the system tier's ``quickstart`` scenario). The filter is computed here
as systemd merges the unit's ``SystemCallFilter=`` lines, with the groups as this machine's
``systemd-analyze syscall-filter`` lists them."""

from __future__ import annotations

import functools
import shutil
import subprocess
from pathlib import Path

import pytest

UNIT = Path(__file__).resolve().parents[2] / "units" / "srcsd@.service"
NEEDED = {"chown", "fchownat", "bind", "listen", "link", "unlink", "chmod"}
"""What ``supervisord/api/server.py``'s ``_listen`` calls to make a socket with its group."""


@functools.cache
def members(group: str) -> frozenset[str]:
    """The system calls of ``@group``, nested groups expanded."""
    listed = subprocess.run(
        ["systemd-analyze", "syscall-filter", group],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()[1:]
    found: set[str] = set()
    for line in listed:
        name = line.strip()
        if not name or name.startswith("#"):
            continue
        found |= members(name) if name.startswith("@") else {name}
    return frozenset(found)


def expand(items: list[str]) -> set[str]:
    found: set[str] = set()
    for item in items:
        found |= members(item) if item.startswith("@") else {item}
    return found


def allowed(unit_text: str) -> set[str]:
    """The allow list the unit's lines make, in their order: the first line (not negated)
    sets it, each ``~`` line takes its calls out, each other line puts its calls back."""
    lines = [
        line.split("=", 1)[1].split()
        for line in unit_text.splitlines()
        if line.startswith("SystemCallFilter=")
    ]
    assert lines, "no SystemCallFilter="
    assert not lines[0][0].startswith("~"), "the filter is no allow list"
    calls = expand(lines[0])
    for items in lines[1:]:
        if items[0].startswith("~"):
            calls -= expand([items[0][1:], *items[1:]])
        else:
            calls |= expand(items)
    return calls


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
def test_the_unit_lets_srcsd_give_its_sockets_their_group() -> None:
    """SR-8.14: the calls srcsd's start makes for a socket with a group (the operator
    socket's) are allowed; the rest of @privileged stays denied."""
    calls = allowed(UNIT.read_text())
    assert calls >= NEEDED, sorted(NEEDED - calls)
    assert not calls & {"setuid", "setgroups", "chroot", "capset", "pivot_root", "acct"}
