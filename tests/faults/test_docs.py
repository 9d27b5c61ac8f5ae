"""``docs/faults.md`` and the fault suite agree: every scenario test is listed once, every
listed test exists, every scenario cites the requirements of ``docs/requirements.md`` it
exercises, by known IDs (``SR-N.M``, ``PR-N.M`` or a whole section)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.trace import REQUIREMENTS, citations, parse_requirements
from tests.trace import ROOT as REPO

ROOT = Path(__file__).parents[2]
DOC = ROOT / "docs" / "faults.md"
ROW = re.compile(r"^\| (\d+) \|(.+)\| ((?:SR|PR)-[^|]+)\|([^|]+)\| `(tests/faults/[^`]+)` \|$")


def _ids(decorator: ast.expr) -> list[str] | None:
    """The ids of a ``pytest.mark.parametrize`` decorator (``pytest.param(..., id=)`` or
    ``ids=[...]``), or ``None`` for any other decorator."""
    if not (
        isinstance(decorator, ast.Call) and ast.unparse(decorator.func).endswith("parametrize")
    ):
        return None
    for keyword in decorator.keywords:
        if keyword.arg == "ids":
            assert isinstance(keyword.value, ast.List)
            return [ast.literal_eval(e) for e in keyword.value.elts]
    values = decorator.args[1]
    assert isinstance(values, ast.List)
    ids = []
    for element in values.elts:
        assert isinstance(element, ast.Call), "give every case an id"
        [named] = [k for k in element.keywords if k.arg == "id"]
        ids.append(ast.literal_eval(named.value))
    return ids


def scenario_tests() -> dict[str, str]:
    """``path::function[id]`` -> docstring, for every test in ``tests/faults``."""
    found: dict[str, str] = {}
    for path in sorted((ROOT / "tests" / "faults").glob("test_*.py")):
        if path.name == "test_docs.py":
            continue
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if not (isinstance(node, ast.FunctionDef) and node.name.startswith("test_")):
                continue
            base = f"tests/faults/{path.name}::{node.name}"
            doc = ast.get_docstring(node) or ""
            ids = next((i for d in node.decorator_list if (i := _ids(d)) is not None), None)
            if ids is None:
                found[base] = doc
            for case in ids or []:
                found[f"{base}[{case}]"] = doc
    return found


def listed() -> list[tuple[int, str, str]]:
    """(number, rule, test) of every row of the scenario table."""
    rows = []
    for line in DOC.read_text().splitlines():
        match = ROW.match(line)
        if match:
            rows.append((int(match[1]), match[3].strip(), match[5]))
    return rows


def test_every_scenario_is_listed_once_and_every_listed_test_exists() -> None:
    """Each fault test (each parametrized case) is one numbered row of docs/faults.md."""
    tests = scenario_tests()
    rows = listed()
    names = [test for _, _, test in rows]
    assert len(names) == len(set(names)), "a test listed twice"
    assert sorted(names) == sorted(tests), (
        f"not listed: {sorted(set(tests) - set(names))}; "
        f"listed but missing: {sorted(set(names) - set(tests))}"
    )
    assert [number for number, _, _ in rows] == list(range(1, len(rows) + 1))
    assert len(rows) >= 30
    assert f"{len(rows)} scenarios" in DOC.read_text()


def test_every_scenario_cites_its_rule() -> None:
    """Each scenario's docstring and its row cite requirements, and only IDs that exist."""
    catalogue = parse_requirements((REPO / REQUIREMENTS).read_text(encoding="utf-8"))
    rules = {test: rule for _, rule, test in listed()}
    for test, doc in scenario_tests().items():
        cited = citations(doc)
        assert cited, f"{test}: the docstring cites no requirement of {REQUIREMENTS}"
        unknown = [rid for rid in cited + citations(rules[test]) if not catalogue.known(rid)]
        assert not unknown, f"{test}: unknown IDs {unknown}"
