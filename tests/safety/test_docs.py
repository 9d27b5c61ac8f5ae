"""``docs/safety.md`` agrees with the code: the diagram matches the table, and every test the
hazard table names exists."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from supervisord.safety import TABLE, diagram

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "safety.md"
TEST_REF = re.compile(r"`(tests/safety/test_\w+\.py)::(test_\w+)`")


def test_diagram_in_the_docs_matches_the_table() -> None:
    """The mermaid diagram between the markers is exactly what the table generates."""
    document = DOC.read_text(encoding="utf-8")
    assert diagram.extract(document) == diagram.render()
    assert diagram.main(["--check", "--file", str(DOC)]) == 0


def test_diagram_has_one_arrow_per_row() -> None:
    """Every row of the table is one arrow, plus the start arrow."""
    rendered = diagram.render()
    assert rendered.count("-->") == len(TABLE) + 1


def test_splice_replaces_only_between_the_markers() -> None:
    """Splicing keeps the text around the markers and is idempotent."""
    document = f"before\n{diagram.BEGIN}\nold\n{diagram.END}\nafter\n"
    once = diagram.splice(document, "new")
    assert once == f"before\n{diagram.BEGIN}\nnew\n{diagram.END}\nafter\n"
    assert diagram.splice(once, "new") == once
    with pytest.raises(diagram.MarkersMissing):
        diagram.splice("no markers", "new")


def test_check_fails_on_a_stale_diagram(tmp_path: Path) -> None:
    """``--check`` exits 1 on a stale document; a rewrite then makes it pass."""
    stale = tmp_path / "safety.md"
    stale.write_text(f"{diagram.BEGIN}\nold\n{diagram.END}\n", encoding="utf-8")
    with pytest.raises(SystemExit) as caught:
        diagram.main(["--check", "--file", str(stale)])
    assert caught.value.code == 1
    assert diagram.main(["--file", str(stale)]) == 0
    assert diagram.main(["--check", "--file", str(stale)]) == 0


def test_every_test_named_in_the_hazard_table_exists() -> None:
    """Each ``tests/safety/test_x.py::test_name`` in docs/safety.md names a real test function."""
    references = TEST_REF.findall(DOC.read_text(encoding="utf-8"))
    assert len(references) >= 30
    for path, name in references:
        tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
        functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        assert name in functions, f"{path}::{name} does not exist"


def test_every_test_has_a_docstring() -> None:
    """Every test function in tests/safety states in its docstring what it pins down."""
    for path in sorted((ROOT / "tests" / "safety").glob("test_*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_"):
                assert ast.get_docstring(node), f"{path.name}::{node.name} has no docstring"
