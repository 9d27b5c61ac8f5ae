"""Build ``docs/traceability.md`` from the tests' own citations of ``docs/requirements.md``.

    .venv/bin/python -m tests.trace           # write docs/traceability.md
    .venv/bin/python -m tests.trace --check   # exit 1 when the file is stale or a rule is broken

Where the IDs come from:

- **requirements**: every ``- **SR-N.M**`` / ``- **PR-N.M**`` item of ``docs/requirements.md``,
  grouped under its ``## SR-N`` / ``## PR-N`` heading (a *section*);
- **citations**: every ``SR-N``, ``SR-N.M``, ``PR-N`` or ``PR-N.M`` (and ranges written
  ``SR-1 to SR-5``) in a test's docstring, in its class's docstring or in its module's
  docstring, for every ``test_*`` function of ``tests/**/test_*.py``;
- **hazards**: every ``| hazard | rule | test |`` table of ``docs/safety.md``, with the IDs its
  rule column cites and the tests its test column names.

What counts (``docs/requirements.md`` "Traceability"): a test that cites a requirement proves
it; a test that cites only the requirement's section is listed beside it, but does not count as
its proof, because a section names many promises and a test asserts a few. A requirement that
no pytest test can prove carries ``*Proven by:* bench `FILE```, ``*Proven by:* system tier
`FILE``` or ``*Proven by:* fleet tier `FILE``` in its text; the file must exist.

The module is pure apart from :func:`main`: :func:`build` returns the page and the problems, and
``tests/test_traceability.py`` runs it.
"""

from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REQUIREMENTS = "docs/requirements.md"
SAFETY = "docs/safety.md"
OUTPUT = "docs/traceability.md"

ID = r"(?:SR|PR)-\d+(?:\.\d+)?"
# "SR-1 to SR-5", "PR-1.1 to PR-1.4", or one ID alone.
CITATION = re.compile(rf"\b({ID})(?:\s+to\s+({ID}))?\b")
ITEM = re.compile(rf"^- \*\*({ID})\*\*\s*(.*)$")
SECTION = re.compile(r"^## ((?:SR|PR)-\d+) (.*)$")
PROVEN_BY = re.compile(r"\*Proven by:\* (bench|system tier|fleet tier) `([^`]+)`")
HAZARD_HEADER = "| hazard | rule | test |"
TEST_REF = re.compile(r"`(tests/[^`:]+\.py)::([A-Za-z_][A-Za-z0-9_]*)(?:\[[^`]*\])?`")


@dataclass(frozen=True)
class Requirement:
    """One requirement item of docs/requirements.md."""

    rid: str
    section: str
    text: str
    proven_by: tuple[str, str] | None  # ("bench", "bench/stop_latency.py") or None


@dataclass
class Catalogue:
    """The requirements, by section."""

    sections: dict[str, str] = field(default_factory=dict)  # "SR-2" -> title
    items: dict[str, Requirement] = field(default_factory=dict)  # "SR-2.1" -> requirement

    def members(self, section: str) -> list[str]:
        """The requirement IDs of one section, in document order."""
        return [rid for rid, r in self.items.items() if r.section == section]

    def known(self, rid: str) -> bool:
        """Whether an ID names a section or a requirement."""
        return rid in self.sections or rid in self.items


@dataclass(frozen=True)
class Test:
    """One pytest test function and the IDs its docstrings cite."""

    node: str  # "tests/safety/test_causes.py::test_startup_is_stopped_with_cause_startup"
    cited: frozenset[str]


@dataclass(frozen=True)
class Hazard:
    """One row of a hazard table of docs/safety.md."""

    table: str  # the heading the table stands under
    hazard: str
    rule: str
    cited: tuple[str, ...]
    tests: tuple[str, ...]


def _split_id(rid: str) -> tuple[str, int, int | None]:
    kind, rest = rid.split("-", 1)
    major, _, minor = rest.partition(".")
    return kind, int(major), int(minor) if minor else None


def expand(first: str, last: str | None) -> list[str]:
    """One citation as the IDs it names: ``SR-1 to SR-3`` is SR-1, SR-2 and SR-3."""
    if last is None:
        return [first]
    k1, a1, b1 = _split_id(first)
    k2, a2, b2 = _split_id(last)
    if k1 != k2:
        return [first, last]
    if b1 is None and b2 is None:
        return [f"{k1}-{n}" for n in range(a1, a2 + 1)]
    if b1 is not None and b2 is not None and a1 == a2:
        return [f"{k1}-{a1}.{n}" for n in range(b1, b2 + 1)]
    return [first, last]


def citations(text: str) -> list[str]:
    """Every requirement or section ID a text cites, ranges expanded, in order."""
    found: list[str] = []
    for m in CITATION.finditer(text):
        found += expand(m.group(1), m.group(2))
    return found


def parse_requirements(text: str) -> Catalogue:
    """The sections and requirement items of docs/requirements.md."""
    cat = Catalogue()
    section = ""
    current: list[str] | None = None
    rid = ""

    def close() -> None:
        if current is not None:
            body = " ".join(current)
            m = PROVEN_BY.search(body)
            proof = (m.group(1), m.group(2)) if m else None
            cat.items[rid] = Requirement(rid, section, body, proof)

    for line in text.splitlines():
        if m := SECTION.match(line):
            close()
            current = None
            section = m.group(1)
            cat.sections[section] = m.group(2).strip()
        elif m := ITEM.match(line):
            close()
            rid = m.group(1)
            current = [m.group(2).strip()]
        elif current is not None and line.startswith("  ") and line.strip():
            current.append(line.strip())
        else:
            close()
            current = None
    close()
    return cat


def _test_files(root: Path) -> Iterator[Path]:
    yield from sorted((root / "tests").rglob("test_*.py"))


def collect_tests(root: Path) -> list[Test]:
    """Every ``test_*`` function under tests/ with the IDs of its docstrings."""
    tests: list[Test] = []
    for path in _test_files(root):
        rel = path.relative_to(root).as_posix()
        module = ast.parse(path.read_text(encoding="utf-8"))
        module_ids = citations(ast.get_docstring(module) or "")
        for node in module.body:
            scopes: list[tuple[str, list[str], ast.AST]] = []
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                scopes.append(("", [], node))
            elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
                class_ids = citations(ast.get_docstring(node) or "")
                for sub in node.body:
                    scopes.append((node.name + "::", class_ids, sub))
            for prefix, outer, fn in scopes:
                if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                    continue
                if not fn.name.startswith("test"):
                    continue
                own = citations(ast.get_docstring(fn) or "")
                ids = frozenset(own + outer + module_ids)
                tests.append(Test(f"{rel}::{prefix}{fn.name}", ids))
    return tests


def parse_hazards(text: str) -> list[Hazard]:
    """Every row of every ``| hazard | rule | test |`` table of docs/safety.md."""
    hazards: list[Hazard] = []
    heading = ""
    in_table = False
    for line in text.splitlines():
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
            in_table = False
        elif line.strip() == HAZARD_HEADER:
            in_table = True
        elif in_table and line.startswith("|---"):
            continue
        elif in_table and line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) < 3:
                continue
            hazard, rule, tests = cells[0], cells[1], " | ".join(cells[2:])
            refs = tuple(f"{p}::{n}" for p, n in TEST_REF.findall(tests))
            hazards.append(Hazard(heading, hazard, rule, tuple(citations(rule)), refs))
        else:
            in_table = False
    return hazards


@dataclass(frozen=True)
class Result:
    """The generated page and what is wrong with the tree."""

    page: str
    problems: tuple[str, ...]


def _cell(items: Iterable[str]) -> str:
    listed = [f"`{i}`" for i in items]
    return "<br>".join(listed) if listed else "—"


HEADER = [
    "# Traceability",
    "",
    "Generated by `tests/trace.py` from `docs/requirements.md`, the docstrings of the tests",
    "and the hazard tables of `docs/safety.md`; do not edit by hand. Rebuild it with",
    "`.venv/bin/python -m tests.trace`; `tests/test_traceability.py` fails when it is stale,",
    "when a test cites an unknown ID, or when a requirement has no proof.",
    "",
    "A test *proves* a requirement when its docstring (or its class's or module's) cites the",
    "requirement's ID. A test that cites only the whole section is listed under *section*: it",
    "exercises the section, but does not count as the proof of each requirement in it.",
]


def _unknown(cat: Catalogue, tests: list[Test], hazards: list[Hazard]) -> list[str]:
    """Unknown IDs cited by tests or hazard rows, and hazard rows naming no real test."""
    nodes = {t.node for t in tests}
    problems = [
        f"{t.node} cites {rid}, which {REQUIREMENTS} does not define"
        for t in tests
        for rid in sorted(t.cited)
        if not cat.known(rid)
    ]
    for h in hazards:
        problems += [
            f"{SAFETY} hazard {h.hazard!r} cites unknown {r}" for r in h.cited if not cat.known(r)
        ]
        problems += [
            f"{SAFETY} hazard {h.hazard!r} names {n}, which is no test"
            for n in h.tests
            if n not in nodes
        ]
    return problems


def _requirement_lines(
    root: Path, cat: Catalogue, tests: list[Test], problems: list[str]
) -> list[str]:
    """One table per section: each requirement with the tests (or bench) that prove it."""
    direct: dict[str, list[str]] = {rid: [] for rid in cat.items}
    by_section: dict[str, list[str]] = {sec: [] for sec in cat.sections}
    for t in sorted(tests, key=lambda t: t.node):
        for rid in t.cited:
            if rid in direct:
                direct[rid].append(t.node)
            elif rid in by_section:
                by_section[rid].append(t.node)
    lines = ["", "## Requirement → tests"]
    for sec, title in cat.sections.items():
        lines += ["", f"### {sec} {title}", ""]
        lines += ["| requirement | proven by | section |", "|---|---|---|"]
        count = len(by_section[sec])
        section_cell = f"{count} test{'s' if count != 1 else ''}" if count else "—"
        for rid in cat.members(sec):
            proof = list(direct[rid])
            proven_by = cat.items[rid].proven_by
            if proven_by is not None:
                kind, target = proven_by
                if not (root / target.split("::")[0]).exists():
                    problems.append(f"{rid} is proven by {kind} {target}, which does not exist")
                proof.insert(0, f"{kind}: {target}")
            elif not proof:
                problems.append(f"{rid} has no test that cites it")
            lines.append(f"| {rid} | {_cell(proof) if proof else '**none**'} | {section_cell} |")
        if by_section[sec]:
            lines += ["", f"Tests citing the whole of {sec}:", ""]
            lines += [f"- `{n}`" for n in by_section[sec]]
    return lines


def _hazard_lines(hazards: list[Hazard]) -> list[str]:
    """The hazard tables of docs/safety.md as hazard -> requirements -> tests."""
    lines = [
        "",
        "## Hazard → requirement → tests",
        "",
        "The hazard tables of `docs/safety.md`, each row with the requirements its rule cites and",
        "the tests it names. A rule that names only a choice of `docs/safety.md` has no ID.",
    ]
    table = None
    for h in hazards:
        if h.table != table:
            table = h.table
            lines += ["", f"### {table}", "", "| hazard | requirements | tests |", "|---|---|---|"]
        req_cell = ", ".join(dict.fromkeys(h.cited)) or f"({h.rule})"
        lines.append(f"| {h.hazard} | {req_cell} | {_cell(h.tests)} |")
    return lines


def build(root: Path = ROOT) -> Result:
    """The traceability page, and every broken rule (unknown ID, unproven requirement...)."""
    cat = parse_requirements((root / REQUIREMENTS).read_text(encoding="utf-8"))
    tests = collect_tests(root)
    hazards = parse_hazards((root / SAFETY).read_text(encoding="utf-8"))
    problems = _unknown(cat, tests, hazards)
    lines = HEADER + _requirement_lines(root, cat, tests, problems) + _hazard_lines(hazards)
    lines.append("")
    return Result("\n".join(lines), tuple(problems))


def main(argv: list[str]) -> int:
    """Write the page, or with ``--check`` report staleness and problems; 1 when anything is
    wrong."""
    result = build(ROOT)
    out = ROOT / OUTPUT
    status = 0
    for problem in result.problems:
        print(problem, file=sys.stderr)
        status = 1
    if "--check" in argv:
        if not out.exists() or out.read_text(encoding="utf-8") != result.page:
            print(f"{OUTPUT} is stale: run .venv/bin/python -m tests.trace", file=sys.stderr)
            status = 1
    else:
        out.write_text(result.page, encoding="utf-8")
        print(f"wrote {OUTPUT}")
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
