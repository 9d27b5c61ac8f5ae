"""The protocol layer does no I/O: it opens nothing, reads no clock, sleeps never, starts no
thread (issue: "a test proves it")."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import supervisord.protocol

PACKAGE = Path(supervisord.protocol.__file__).parent
ALLOWED_MODULES = {
    "__future__",
    "collections.abc",
    "dataclasses",
    "datetime",  # only for dt.time values; the clock calls are forbidden below
    "enum",
    "itertools",  # pure: the checksum's running sums
    "operator",
    "struct",
    "typing",
    "typing_extensions",  # only under TYPE_CHECKING, for Python 3.10 (supervisord/compat.py)
    "supervisord.compat",
    "supervisord.errors",
}
# Called names that would read a clock, open a file, sleep or talk to the terminal. The
# ``time`` module itself is not importable (above), so ``dt.time(...)`` values stay allowed.
FORBIDDEN_CALLS = {"open", "now", "today", "utcnow", "sleep", "monotonic", "input", "print"}


def violations(source: str) -> list[str]:
    """Every impure import or call in ``source``."""
    found: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import | ast.ImportFrom):
            names = (
                [alias.name for alias in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
            )
            found += [
                f"{node.lineno}: imports {name}"
                for name in names
                if name not in ALLOWED_MODULES and not name.startswith("supervisord.protocol")
            ]
        elif isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in FORBIDDEN_CALLS:
                found.append(f"{node.lineno}: calls {name}")
    return found


def test_protocol_modules_are_pure() -> None:
    """No module of supervisord/protocol imports an I/O module or calls a clock, file or sleep."""
    files = sorted(PACKAGE.glob("*.py"))
    assert len(files) >= 8
    for path in files:
        assert violations(path.read_text()) == [], path.name


@pytest.mark.parametrize(
    "source",
    [
        "import socket",
        "import time",
        "from threading import Thread",
        "import serial",
        "x = open('f')",
        "import datetime as dt\nt = dt.datetime.now()",
        "time.sleep(1)",
    ],
)
def test_the_check_catches_impure_code(source: str) -> None:
    """The purity check is not vacuous: each kind of I/O it forbids is caught."""
    assert violations(source)
