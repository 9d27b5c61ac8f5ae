"""srcsd.toml(5), the configuration file's man page generated from its JSON Schema
(``supervisord/cli/config_page.py``; docs/configuration.md "The man page: srcsd.toml(5)",
SR-11.2): every section and every key of the schema is on the page, under its section, with
its type, default or "Required", range and description; the rules only the loader checks are
listed; the package build writes it with srcsd(8) (the package's install is checked in
tests/packaging/test_deb.py); ``man -l --warnings`` renders it without a warning."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from supervisord import __version__
from supervisord.cli import config_page, reference
from supervisord.config import schema as config_schema

MAN = shutil.which("man")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def page() -> str:
    return reference.toml_page()


def _sections(schema: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The schema's sections as headed in the file, and each table's schema."""
    found = {}
    for name, section in schema["properties"].items():
        if section.get("type") == "array":
            found[f"[[{name}]]"] = section["items"]
        else:
            found[f"[{name}]"] = section
    return found


def _key_entries(page: str) -> dict[str, dict[str, str]]:
    """The page's keys by section: ``.SS [vsc]`` then ``.TP`` / ``.B KEY`` / text."""
    body = page[page.index(".SH SECTIONS AND KEYS") : page.index(".SH RULES BETWEEN KEYS")]
    found: dict[str, dict[str, str]] = {}
    for block in body.split("\n.SS ")[1:]:
        heading, _, rest = block.partition("\n")
        entries = found.setdefault(heading.replace("\\-", "-"), {})
        for entry in rest.split(".TP\n.B ")[1:]:
            name, _, text = entry.partition("\n")
            entries[name.replace("\\-", "-")] = text.replace("\\-", "-").replace("\\e", "\\")
    return found


def test_every_section_and_key_of_the_schema_is_on_the_page(page: str) -> None:
    """Each section in the file's order, each key under its own section, with its description,
    its type, its default when it has one (else whether it is required) and its range."""
    schema = config_schema.json_schema()
    sections = _sections(schema)
    entries = _key_entries(page)
    assert list(entries) == list(sections)
    for heading, table in sections.items():
        keys = table["properties"]
        assert list(entries[heading]) == list(keys), heading
        for key, key_schema in keys.items():
            text = entries[heading][key]
            assert key_schema["description"] in text.replace("\n", " "), (heading, key)
            if "default" in key_schema:
                default = config_page.toml_value(key_schema["default"])
                assert f"Default: {default}." in text, (heading, key)
            elif key in table.get("required", []):
                assert "Required." in text, (heading, key)
            if "minimum" in key_schema and key_schema["minimum"] != key_schema.get("maximum"):
                assert f"from {key_schema['minimum']} to {key_schema['maximum']}" in text
            for value in key_schema.get("enum", []):
                assert config_page.toml_value(value) in text, (heading, key, value)


def test_a_key_the_page_lacks_is_found(page: str) -> None:
    """The check above can fail: a page without ``[vsc] heartbeat_hz`` does not list it."""
    assert "heartbeat_hz" in _key_entries(page)["[vsc]"]
    cut = re.sub(r"\.TP\n\.B heartbeat_hz\n[^\n]*\n\.br\n[^\n]*\n", "", page)
    assert "heartbeat_hz" not in _key_entries(cut)["[vsc]"]


def test_keys_of_one_transport_or_kind_say_so(page: str) -> None:
    """The schema's if/then rules, in words: a serial key only with transport = "serial", the
    hidraw needed with HID, GPIO's chip and line needed with kind = "gpio", the proof test off
    on CAN."""
    entries = _key_entries(page)
    assert 'Only with transport = "serial".' in entries["[vsc]"]["port"]
    assert 'Required with transport = "hid".' in entries["[vsc]"]["hidraw"]
    assert 'With transport = "can": must be "off".' in entries["[vsc]"]["prooftest"]
    for key in ("chip", "line"):
        assert 'Only with kind = "gpio". Required with kind = "gpio".' in " ".join(
            entries["[[outputs]]"][key].split()
        )
    assert "Only with" not in entries["[[outputs]]"]["role"]


def test_the_rules_between_keys_and_the_header(page: str) -> None:
    """Every rule the loader alone enforces is listed; the header names the page, section 5,
    the package's version; NAME, SYNOPSIS, DESCRIPTION, FILES and SEE ALSO in man-pages(7)
    order; srcsd(8) points here."""
    rules = page[page.index(".SH RULES BETWEEN KEYS") : page.index(".SH FILES")]
    for key in config_schema.CROSS_CHECKS:
        assert f".B {config_page.roff(key)}\n" in rules, key
    header = page.split("\n", 1)[0]
    assert header.startswith('.TH SRCSD.TOML "5" ')
    assert f'"srcs\\-supervisord {config_page.roff(__version__)}"' in header
    order = [".SH NAME", ".SH SYNOPSIS", ".SH DESCRIPTION", ".SH FILES", ".SH SEE ALSO"]
    assert [page.index(h) for h in order] == sorted(page.index(h) for h in order)
    srcsd = reference.man_page(next(c for c in reference.COMMANDS if c.name == "srcsd"))
    assert ".BR srcsd.toml (5)" in srcsd


def test_the_command_line_writes_it_with_srcsd_only(tmp_path: Path) -> None:
    """``man OUTDIR --only srcsd`` (the robot's package build) writes srcsd.toml.5 beside
    srcsd.8; the collector's ``--only srcsctl ...`` does not (it has no daemon)."""
    for only, expected in (
        (["srcsd"], ["srcsd.8", "srcsd.toml.5"]),
        (["srcsctl", "srcs-fleet-pki"], ["srcs-fleet-pki.8", "srcsctl.1"]),
    ):
        out = tmp_path / only[0]
        subprocess.run(
            [sys.executable, "-m", "supervisord.cli.reference", "man", str(out), "--only", *only],
            cwd=tmp_path,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            check=True,
            capture_output=True,
            timeout=120,
        )
        assert sorted(p.name for p in out.iterdir()) == expected


def test_the_page_does_not_depend_on_the_day(monkeypatch: pytest.MonkeyPatch) -> None:
    """Dated by ``SOURCE_DATE_EPOCH``, as the other pages: a reproducible build."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "86400")
    assert '"1970\\-01\\-02"' in reference.toml_page().split("\n", 1)[0]


@pytest.mark.skipif(MAN is None, reason="needs man-db and groff")
def test_man_renders_it_without_a_warning(page: str, tmp_path: Path) -> None:
    """``man -l --warnings`` renders the page with nothing on stderr (groff's warnings go
    there), its title and every section heading in the text."""
    assert MAN is not None
    path = tmp_path / "srcsd.toml.5"
    path.write_text(page)
    result = subprocess.run(
        [MAN, "-l", "--warnings", str(path)],
        capture_output=True,
        text=True,
        env={**os.environ, "MANWIDTH": "80", "MANPAGER": "cat", "PAGER": "cat"},
        timeout=60,
        check=False,
    )
    assert (result.returncode, result.stderr) == (0, "")
    assert "SRCSD.TOML(5)" in result.stdout
    for heading in _sections(config_schema.json_schema()):
        assert heading in result.stdout
