"""srcsd.toml(5), the configuration file's man page, generated from its JSON Schema (SR-11.2;
docs/configuration.md "The man page").

The schema (:func:`supervisord.config.schema.json_schema`, the committed copy
``config/srcsd.schema.json``) is made from the declarations the loader reads the file with, so
the page lists every section and key the daemon accepts, each with its type, default, range or
values and description, and which transport or output kind it belongs to (the schema's
``if``/``then`` rules); the rules between keys that JSON Schema cannot say come from
:data:`supervisord.config.schema.CROSS_CHECKS`. A key added, renamed or given another range
changes the page with it: nothing here names a key.

Pure: the caller passes the schema, the rules, the version and the date
(:mod:`supervisord.cli.reference` writes the page beside srcsd(8)).
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Final

NAME: Final = "srcsd.toml"
SECTION: Final = 5
MANUAL: Final = "File Formats"
DOC_DIR: Final = "/usr/share/doc/srcs-supervisord"


def roff(text: str) -> str:
    """Plain text as roff: backslashes and hyphens escaped, no line starting a request."""
    text = text.replace("\\", "\\e").replace("-", "\\-")
    return "\n".join(
        "\\&" + line if line.startswith((".", "'")) else line for line in text.split("\n")
    )


def toml_value(value: object) -> str:
    """A default or an allowed value as it is written in the file (strings in double quotes,
    true and false in lower case)."""
    return json.dumps(value, ensure_ascii=False)


def _kind(schema: Mapping[str, Any]) -> str:
    """The value's type, range or allowed values, in words."""
    if "anyOf" in schema:
        return " or ".join(_kind(option) for option in schema["anyOf"])
    if "enum" in schema:
        return "one of " + ", ".join(toml_value(v) for v in schema["enum"])
    kind = schema.get("type")
    if kind == "integer":
        low, high = schema.get("minimum"), schema.get("maximum")
        if low is not None and low == high:
            return f"the whole number {low}"
        if low is not None and high is not None:
            return f"a whole number from {low} to {high}"
        return "a whole number"
    if kind == "boolean":
        return "true or false"
    if kind == "string":
        words = "a string"
        if "maxLength" in schema:
            words += f" of at most {schema['maxLength']} characters"
        if schema.get("not") == {"pattern": "/$"}:
            words = "a file's path (not a directory's: no trailing /)"
        return words
    return str(kind)


def _conditions(table: Mapping[str, Any]) -> dict[str, list[str]]:
    """Per key, what the table's ``if``/``then`` rules say of it: which values of the
    discriminating key (``transport``, ``kind``) allow it, need it, or fix its value."""
    rules = [
        rule
        for rule in table.get("allOf", [])
        if len(rule.get("if", {}).get("properties", {})) == 1
        and "const" in next(iter(rule["if"]["properties"].values()))
        and not rule["if"].get("required")
    ]
    said: dict[str, list[str]] = {}
    by: dict[str, set[str]] = {}
    values: dict[str, list[str]] = {}
    for rule in rules:
        ((switch, test),) = rule["if"]["properties"].items()
        value = toml_value(test["const"])
        values.setdefault(switch, [])
        if value not in values[switch]:
            values[switch].append(value)
        then = rule["then"]
        for key, allowed in then.get("properties", {}).items():
            if allowed is False:
                by.setdefault(key, set()).add(f"{switch}\0{value}")
            elif isinstance(allowed, dict) and "const" in allowed:
                said.setdefault(key, []).append(
                    f"With {switch} = {value}: must be {toml_value(allowed['const'])}."
                )
            elif isinstance(allowed, dict) and "maximum" in allowed:
                said.setdefault(key, []).append(
                    f"With {switch} = {value}: at most {allowed['maximum']}."
                )
        for key in then.get("required", []):
            said.setdefault(key, []).append(f"Required with {switch} = {value}.")
    for key, refused in by.items():
        for switch, all_values in values.items():
            left = [v for v in all_values if f"{switch}\0{v}" not in refused]
            if len(left) < len(all_values):
                said.setdefault(key, []).insert(0, f"Only with {switch} = {' or '.join(left)}.")
    return said


def _key_entry(name: str, schema: Mapping[str, Any], required: bool, notes: Sequence[str]) -> str:
    facts = [f"Type: {_kind(schema)}."]
    if required:
        facts.append("Required.")
    elif "default" in schema:
        facts.append(f"Default: {toml_value(schema['default'])}.")
    else:
        facts.append("Optional, no fixed default.")
    facts += notes
    examples = schema.get("examples") or []
    if examples:
        facts.append(f"Example: {name} = {toml_value(examples[0])}")
    return f".TP\n.B {roff(name)}\n{roff(str(schema.get('description', '')))}\n.br\n" + roff(
        " ".join(facts)
    )


def _tables(schema: Mapping[str, Any]) -> Iterator[tuple[str, str, Mapping[str, Any], bool]]:
    """Each top-level section: its heading as written in the file (``[vsc]``,
    ``[[outputs]]``), its description, its table's schema and whether the file needs it."""
    needed = set(schema.get("required", []))
    for name, section in schema["properties"].items():
        if section.get("type") == "array":
            yield f"[[{name}]]", section.get("description", ""), section["items"], name in needed
        else:
            yield f"[{name}]", section.get("description", ""), section, name in needed


def _section_text(heading: str, doc: str, table: Mapping[str, Any], needed: bool) -> str:
    many = heading.startswith("[[")
    lines = [f".SS {roff(heading)}", roff(doc)]
    if many:
        lines.append(
            roff(
                f"An array of tables: one {heading} heading per entry"
                + (", at least one." if needed else ", as many as needed.")
            )
        )
    else:
        lines.append(roff("This section is required." if needed else "This section is optional."))
    required = set(table.get("required", []))
    conditions = _conditions(table)
    for key, key_schema in table.get("properties", {}).items():
        lines.append(_key_entry(key, key_schema, key in required, conditions.get(key, [])))
    return "\n".join(lines)


def config_page(
    schema: Mapping[str, Any], cross_checks: Mapping[str, str], version: str, date: str
) -> str:
    """The roff source of srcsd.toml(5) from the configuration's JSON Schema and the rules
    between keys only the loader enforces."""
    sections = "\n".join(_section_text(*table) for table in _tables(schema))
    rules = "\n".join(
        f".TP\n.B {roff(key)}\n{roff(rule)}" for key, rule in sorted(cross_checks.items())
    )
    source = roff(f"srcs-supervisord {version}")
    header = f'.TH {roff(NAME.upper())} "{SECTION}" "{roff(date)}" "{source}" "{MANUAL}"'
    description = [
        "The configuration of srcsd(8), the safety supervisor of one robot: a TOML file, "
        "/etc/srcs/NAME.toml for the service srcsd@NAME. The whole file is checked before "
        "anything is opened; a key the daemon does not know, a value of the wrong type or "
        "out of its range, or a rule below that does not hold refuses the start (exit 78) "
        "with the key, the line and what to write instead.",
        "srcsd --check-config FILE runs the same checks without starting, and also "
        "checks the machine: the users and groups the file names, and the directories of "
        "the files it opens or creates.",
        "Each section and key below is as the daemon reads it: the type and range, the "
        "default when the key is left out, and the transport or output kind it belongs to. "
        "This page is generated from the file's JSON Schema, which editors can check the "
        f"file against ({DOC_DIR}/examples/srcsd.schema.json).",
    ]
    return "\n".join(
        [
            header,
            ".nh",
            ".ad l",
            ".SH NAME",
            f"{roff(NAME)} \\- the configuration file of srcsd, the SRCS safety supervisor",
            ".SH SYNOPSIS",
            ".B /etc/srcs/\\fINAME\\fB.toml",
            ".SH DESCRIPTION",
            "\n.PP\n".join(roff(p) for p in description),
            ".SH SECTIONS AND KEYS",
            sections,
            ".SH RULES BETWEEN KEYS",
            roff("Checked by the daemon and by --check-config, not by the JSON Schema:"),
            rules,
            ".SH FILES",
            f".TP\n.B {roff('/etc/srcs/NAME.toml')}\n"
            + roff("a robot's configuration, one per srcsd@NAME instance"),
            f".TP\n.B {roff(DOC_DIR + '/examples/')}\n"
            + roff(
                "example configurations (example-serial-gpio.toml, example-can.toml) and "
                "srcsd.schema.json, the JSON Schema"
            ),
            f".TP\n.B {roff(DOC_DIR + '/docs/configuration.md')}\n"
            + roff("the configuration explained, with worked examples"),
            ".SH SEE ALSO",
            ".BR srcsd (8),\n.BR srcsctl (1),\n.BR systemd.service (5)",
            "",
        ]
    )
