"""The units under systemd 247: Debian 11's ``systemd-analyze verify`` on every unit in ``units/``.

An older systemd ignores a directive it does not know, with a warning, and runs the unit
without it: a sandbox setting silently missing. This job lists every directive systemd 247
(Debian 11, bullseye) does not know, and holds the units to the table of docs/install.md
"systemd versions": it fails when 247 does not know a directive the table does not name,
when a row says a directive needs a systemd newer than 247 and 247 knows it anyway, or when a
row names a directive the units no longer use.

How: a bullseye root (``roots.base``) with its ``systemd`` package (a cached layer); the units
are bound read-only into it and copied as instances (``srcsd@platform.service``), and the
package's programs their ``ExecStart=`` names (``packaged_programs``) are stood in for by
empty executables (``verify`` checks that they exist; the package, which needs Python 3.11,
cannot be installed on Debian 11).
Nothing is started: ``systemd-analyze verify`` only loads the units.

usage: python3 -m tests.platforms.units
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from tests.platforms.report import Report, tail
from tests.platforms.roots import REPO, RootError, base, enter, layer, scratch

SUITE = "bullseye"
OLDEST = 247
"""Debian 11's systemd: the oldest the units are checked against."""
INSTALL_DOC = REPO / "docs/install.md"
SECTION = "## systemd versions"
UNKNOWN = re.compile(r"^(?P<file>\S+?):\d+: Unknown (?:key name|lvalue) '(?P<key>\w+)'")
DIRECTIVE = re.compile(r"^([A-Z]\w+)=", re.MULTILINE)
ROW = re.compile(r"^\|\s*`(?P<key>[A-Z]\w+)=[^`]*`\s*\|\s*(?P<version>\d+)\s*\|", re.MULTILINE)
"""A row of the table: | `Directive=` (or `Directive=value`) | version | ... |"""

PACKAGE_BIN = "/opt/srcsd/bin/"
EXEC_START = re.compile(r"^ExecStart=(\S+)", re.MULTILINE)
VERIFY = r"""
mkdir -p /tmp/units /opt/srcsd/bin
for unit in /srv/units/*.service; do
    name=$(basename "$unit")
    cp "$unit" "/tmp/units/${name%@.service}@platform.service"
done
for program in "$@"; do
    printf '#!/bin/sh\n' >"$program"
    chmod 0755 "$program"
done
systemctl --version | head -n 1
cd /tmp/units
SYSTEMD_LOG_COLOR=0 systemd-analyze verify /tmp/units/*.service
"""


def table() -> dict[str, int]:
    """The rows of docs/install.md "systemd versions": directive -> minimum systemd."""
    text = INSTALL_DOC.read_text()
    if SECTION not in text:
        return {}
    section = text.split(SECTION, 1)[1].split("\n## ", 1)[0]
    return {match["key"]: int(match["version"]) for match in ROW.finditer(section)}


def used() -> set[str]:
    """Every directive the unit files set."""
    return {key for path in sorted((REPO / "units").glob("*.service")) for key in _keys(path)}


def packaged_programs() -> list[str]:
    """The package's programs that the units start (``ExecStart=/opt/srcsd/bin/...``): each is
    stood in for by an empty executable, read from the units so that a new unit needs no
    change here."""
    return sorted(
        {
            program
            for path in (REPO / "units").glob("*.service")
            for program in EXEC_START.findall(path.read_text())
            if program.startswith(PACKAGE_BIN)
        }
    )


def _keys(path: Path) -> set[str]:
    return set(DIRECTIVE.findall(path.read_text()))


def main() -> int:
    report = Report("units")
    try:
        bullseye = base(SUITE, "amd64")
        systemd = layer([bullseye], "systemd", "apt-get install -y -q systemd >/dev/null\n")
    except RootError as error:
        report.fail(f"a {SUITE} root with systemd", str(error))
        return report.end()
    result = enter(
        ["sh", "-ec", VERIFY, "verify", *packaged_programs()],
        layers=[systemd, bullseye],
        work=scratch("units"),
        binds=[(REPO / "units", "/srv/units:ro")],
        timeout=300,
    )
    output = result.stdout + result.stderr
    release = result.stdout.splitlines()[0] if result.stdout else "?"
    report.say(f"checked with {release}")
    report.check(result.returncode == 0, "systemd-analyze verify loads every unit", tail(output))
    unknown: dict[str, set[str]] = {}
    for line in output.splitlines():
        if match := UNKNOWN.match(line):
            unknown.setdefault(match["key"], set()).add(Path(match["file"]).name)
    for line in output.splitlines():
        if line.strip() and not UNKNOWN.match(line) and not line.startswith("systemd "):
            report.say(f"verify said: {line}")  # anything else 247 found, for the reader
    rows = table()
    report.check(bool(rows), f'docs/install.md has the table "{SECTION[3:]}"')
    if unknown:
        for key, files in sorted(unknown.items()):
            report.say(f"systemd {OLDEST} does not know {key}= ({', '.join(sorted(files))})")
    else:
        report.say(f"systemd {OLDEST} knows every directive of units/")
    for key in sorted(unknown):
        report.check(
            key in rows and rows[key] > OLDEST,
            f"{key}= (unknown to systemd {OLDEST}) is in the table with its minimum version",
            f"add a row to docs/install.md {SECTION[3:]!r}",
        )
    in_units = used()
    for key, version in sorted(rows.items()):
        if version > OLDEST:
            report.check(
                key in unknown,
                f"{key}= (table: systemd {version}) is unknown to systemd {OLDEST}",
                f"systemd {OLDEST} knows it: the table's version is wrong",
            )
        else:
            report.check(
                key not in unknown,
                f"{key}= (table: systemd {version}) is known to systemd {OLDEST}",
            )
        report.check(key in in_units, f"{key}= (in the table) is still used by units/")
    return report.end()


if __name__ == "__main__":
    sys.exit(main())
