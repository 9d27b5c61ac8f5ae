"""The config's JSON Schema (config/srcsd.schema.json) is generated from the loader's own
declarations and accepts and refuses the same files as the loader (SR-11.2).

The corpus: every file in config/, the test configs, and mutations generated from the
declarations (an unknown key, a wrong type, out of range, a missing required key, each bound,
each optional key removed). The rules only the loader can check (CROSS_CHECKS: keys related
to one another or to the machine) are excluded explicitly: a case may disagree only when the
loader's refusal names one of them.
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import jsonschema  # type: ignore[import-untyped]  # no stubs in the dev extra
import pytest

from supervisord import strict
from supervisord.cli.demo import DEMO_CONFIG
from supervisord.config import load_config, toml
from supervisord.config.schema import (
    CROSS_CHECKS,
    SECTION,
    VSC_BY_TRANSPORT,
    VSC_COMMON,
    json_schema,
    json_schema_text,
)
from supervisord.errors import ConfigError
from supervisord.outputs import spec_class
from supervisord.safety.config import Transport
from tests.config.test_config_rules import BASE, CAN_OUT, CAN_VSC, GPIO, dump

REPO = Path(__file__).resolve().parents[2]
SCHEMA_FILE = REPO / "config" / "srcsd.schema.json"

TEST_CONFIGS: dict[str, dict[str, object]] = {
    "base": BASE,
    "gpio": {**BASE, "outputs": [{"name": "drive", **GPIO, "pulse_period_ms": 10}]},
    "can": {
        **BASE,
        "vsc": {**CAN_VSC, "channel": "vcan0"},
        "outputs": [{"name": "drive", **CAN_OUT, "counter_byte": 0, "counter_mask": 0xF0}],
    },
    "hid": {**BASE, "vsc": {"transport": "hid", "hidraw": "/dev/hidraw0"}},
    "bus": {
        **BASE,
        "outputs": [{"name": "drive", **CAN_OUT}],
        "output_bus": {"interface": "virtual", "channel": "bus1"},
        "record": {"path": "run/stops.jsonl", "keep": 2},
        "api": {"socket": "run/api.sock", "group": "srcs", "max_clients": 4},
    },
}


def corpus_files() -> dict[str, dict[str, object]]:
    """Every config file shipped (config/ and the demo's) and every test config, parsed."""
    shipped = [*sorted((REPO / "config").glob("*.toml")), DEMO_CONFIG]
    files = {p.name: toml.loads(p.read_text()) for p in shipped}
    return files | {f"test:{name}": data for name, data in TEST_CONFIGS.items()}


def keys_of(path: str, table: dict[str, object]) -> tuple[strict.Key, ...]:
    """The declared keys of the table at ``path`` (a section, a client, an output)."""
    if path == "vsc":
        transport = Transport(table.get("transport", "serial"))
        return VSC_COMMON + VSC_BY_TRANSPORT[transport]
    if path.startswith("outputs["):
        kind = str(table.get("kind", "sim"))
        return SECTION["outputs"].keys + spec_class(kind).options
    return SECTION[path.split("[", maxsplit=1)[0]].keys


def wrong_type(key: strict.Key) -> object:
    """A value of another JSON type than ``key`` takes."""
    if isinstance(key, strict.Whole | strict.Flag):
        return "12"
    if isinstance(key, strict.Either):
        return [1]
    return 12


def outside(key: strict.Key) -> list[object]:
    """Values of the right type that ``key`` refuses."""
    if isinstance(key, strict.Whole):
        if key.values:
            return [key.values[0] + 1]
        return [key.low - 1, key.high + 1]
    if isinstance(key, strict.Choice):
        return ["zz-no-such-value"]
    if isinstance(key, strict.Text):
        values: list[object] = ["", "a\tb"]
        if key.max_length is not None:
            values.append("x" * (key.max_length + 1))
        if key.not_dir:
            values.append("run/")
        return values
    return []


def bounds(key: strict.Key) -> list[object]:
    """Values at the edges of ``key``'s range, which it accepts."""
    if isinstance(key, strict.Whole) and not key.values:
        return [key.low, key.high]
    return []


Case = tuple[str, dict[str, object]]


def mutations(data: dict[str, object]) -> Iterator[Case]:
    """``data`` itself, then one change at a time to each table of it."""
    yield "as is", data
    tables: list[tuple[str, list[object]]] = []
    for name, value in data.items():
        if isinstance(value, dict):
            tables.append((name, [name]))
        elif isinstance(value, list):
            tables += [(f"{name}[{i}]", [name, i]) for i in range(len(value))]
    yield "unknown section", {**data, "zz_unknown": {"a": 1}}
    for path, where in tables:

        def changed(name: str, value: object, where: list[object] = where) -> dict[str, object]:
            new = copy.deepcopy(data)
            node: object = new
            for step in where:
                node = node[step]  # type: ignore[index]
            assert isinstance(node, dict)
            if value is strict.MISSING:
                node.pop(name, None)
            else:
                node[name] = value
            return new

        node: object = data
        for step in where:
            node = node[step]  # type: ignore[index]
        assert isinstance(node, dict)
        yield f"{path}: unknown key", changed("zz_unknown", 1)
        for key in keys_of(path, node):
            if path == "vsc" and key.name == "transport":
                continue  # another transport is another file: each has its own cases
            if path.startswith("outputs[") and key.name == "kind":
                continue
            yield f"{path}.{key.name}: wrong type", changed(key.name, wrong_type(key))
            for value in outside(key):
                yield f"{path}.{key.name} = {value!r}: out of range", changed(key.name, value)
            for value in bounds(key):
                yield f"{path}.{key.name} = {value!r}: a bound", changed(key.name, value)
            if key.name in node:
                what = "missing required" if key.required else "optional left out"
                yield f"{path}.{key.name}: {what}", changed(key.name, strict.MISSING)


def loader_verdict(tmp_path: Path, data: dict[str, object]) -> ConfigError | None:
    """The loader's refusal of ``data`` written as TOML, or ``None`` when it loads."""
    file = tmp_path / "robot.toml"
    file.write_text(dump(data))
    try:
        load_config(file, base_dir=tmp_path, group_exists=lambda _: True, user_uid=lambda _: 1000)
    except ConfigError as error:
        return error
    return None


def cross_check(error: ConfigError) -> str | None:
    """The CROSS_CHECKS entry ``error`` enforces, if it is one of them."""
    if "one owner" in error.fix:
        return "paths"
    general = error.key
    for digit in "0123456789":
        general = general.replace(f"[{digit}]", "[]")
    for key in (general, general.split(".")[0]):
        if key in CROSS_CHECKS:
            return key
    return None


def test_the_committed_schema_is_fresh() -> None:
    """config/srcsd.schema.json is what python -m supervisord.config.schema prints now."""
    assert SCHEMA_FILE.read_text() == json_schema_text(), (
        "regenerate it: python -m supervisord.config.schema > config/srcsd.schema.json"
    )
    printed = subprocess.run(
        [sys.executable, "-m", "supervisord.config.schema"],
        check=True,
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert printed.stdout == SCHEMA_FILE.read_text()
    assert printed.stderr == ""


def test_the_schema_is_valid_json_schema() -> None:
    """The schema itself is valid under its dialect (draft 2020-12), and closed at the top."""
    schema = json.loads(SCHEMA_FILE.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["additionalProperties"] is False


@pytest.mark.parametrize("name", sorted(corpus_files()))
def test_loader_and_schema_agree(tmp_path: Path, name: str) -> None:
    """Over a file and every mutation of it, the loader and a JSON Schema validator accept and
    refuse the same cases, except where the loader enforces a documented cross-check."""
    validator = jsonschema.Draft202012Validator(json_schema())
    agreed, excluded, disagreed = 0, 0, []
    for what, data in mutations(corpus_files()[name]):
        error = loader_verdict(tmp_path, data)
        schema_accepts = validator.is_valid(data)
        if (error is None) == schema_accepts:
            agreed += 1
        elif error is not None and schema_accepts and cross_check(error):
            excluded += 1
        else:
            disagreed.append(f"{what}: loader {error or 'accepts'}, schema {schema_accepts}")
    assert disagreed == []
    assert agreed > 40
    assert excluded <= agreed // 4
