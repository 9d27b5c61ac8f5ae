"""``srcsd --check-config FILE``: every mistake of the file, printed for a person.

One line per mistake, in file order, as a compiler prints them (editors jump to them)::

    robot.toml:21: error: rearm.local-reset = true: unknown key: did you mean 'local_reset'? ...
    robot.toml:4:13: error: line 4, column 13 = "name = mower": correct the TOML syntax there ...
    robot.toml:62: warning: api.admin_group = "srcs-admin": no such group on this machine: ...
    robot.toml:17: warning: clients[0].user = (not set): unbound: any program that can ...

with the value as TOML writes it (``true``, ``"text"``), then a last line with the verdict.
The check is the daemon's start (SR-11.2): what this machine lacks that the daemon needs (a
user or group, the directory of the record or of a socket, unless srcsd@NAME.service makes it:
:mod:`supervisord.config.directories`) is an error; ``--portable``, for a config written on
one machine for another, makes those warnings (exit 0). A valid config's own warnings
(:meth:`DaemonConfig.warnings`) are warnings either way, as the daemon starts with them.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TextIO

from supervisord import strict
from supervisord.config.collect import Finding, Report, collect
from supervisord.config.directories import present_or_made_by_unit
from supervisord.config.loader import NotOnMachine

SHOWN_ITEMS = 3
"""Items of an array or table shown in a message before ``...``."""


def toml_value(value: object) -> str:
    """``value`` as TOML writes it, bounded as the loader's messages are: ``true``,
    ``"text"``, ``[1, 2]``, ``{ a = 1 }``; ``(not set)`` for a missing key."""
    if value is strict.MISSING:
        return "(not set)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        cut = value[: strict.SHOWN_TEXT]
        return json.dumps(cut, ensure_ascii=False) + ("..." if len(value) > len(cut) else "")
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, int):
        return strict.shown(value)  # a million digits are described, not printed
    if isinstance(value, dt.date | dt.time):
        return value.isoformat()
    if isinstance(value, list | tuple):
        items = [toml_value(item) for item in value[:SHOWN_ITEMS]]
        return f"[{', '.join(items)}{', ...' if len(value) > SHOWN_ITEMS else ''}]"
    if isinstance(value, Mapping):
        pairs = [f"{key} = {toml_value(item)}" for key, item in list(value.items())[:SHOWN_ITEMS]]
        return "{ " + ", ".join(pairs) + (", ..." if len(value) > SHOWN_ITEMS else "") + " }"
    return strict.shown(value)


def finding_line(file: str, finding: Finding) -> str:
    """``FILE:LINE: error: KEY = VALUE: FIX`` (``FILE:LINE:COLUMN`` for a syntax error, the
    only place TOML gives a column; ``FILE:`` alone where the key has no line)."""
    error = finding.error
    where = ""
    if finding.where is not None:
        line, column = finding.where
        syntax = error.key.startswith("line ")
        where = f"{line}:{column}:" if syntax else f"{line}:"
    kind = "warning" if finding.warning else "error"
    on_machine = isinstance(error, NotOnMachine) and finding.warning
    machine = (
        " (a warning only with --portable: the daemon's start refuses it)" if on_machine else ""
    )
    return f"{file}:{where} {kind}: {error.key} = {toml_value(error.value)}: {error.fix}{machine}"


def report_lines(file: str, report: Report) -> list[str]:
    """Every finding, the notes, and the verdict when the file is not valid."""
    lines = [finding_line(file, finding) for finding in report.findings]
    lines += [f"{file}: note: {note}" for note in report.notes]
    if report.config is None:
        errors = report.errors
        warnings = len(report.findings) - errors
        counted = f"{errors} error{'s' * (errors != 1)}"
        if warnings:
            counted += f", {warnings} warning{'s' * (warnings != 1)}"
        lines.append(f"{file}: not valid: {counted}")
    return lines


def check_config_main(
    path: str | Path,
    *,
    portable: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """Print ``FILE: OK — ...`` and any warnings and return 0, or print every mistake (to
    stderr) and return 1. ``portable``: what this machine lacks is a warning."""
    out = out or sys.stdout
    err = err or sys.stderr
    there = present_or_made_by_unit(Path(path).absolute())
    report = collect(path, strict_machine=not portable, directory_there=there)
    config = report.config
    if config is None:
        for line in report_lines(str(path), report):
            print(line, file=err)
        return 1
    outputs, clients = len(config.outputs), len(config.safety.clients)
    print(
        f"{path}: OK — robot {config.robot.name}, transport {config.vsc.transport.value}, "
        f"{outputs} output{'s' * (outputs != 1)}, {clients} client{'s' * (clients != 1)}",
        file=out,
    )
    for line in report_lines(str(path), report):  # the warnings, each at its key's line
        print(line, file=err)
    return 0
