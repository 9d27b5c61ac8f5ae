"""Mutation testing of the safety core and of the daemon's parts (docs/verification.md "Mutation
testing"; ``./dev mutate``, ``./dev mutate --daemon``).

One change at a time in the core's modules, made in the source text so that everything else
stays as written: a comparison operator (its boundary twin, ``<`` and ``<=``, and its negation,
``<`` and ``>=``; ``==``, ``is``, ``in`` and their negations), ``and`` and ``or``, ``not``
dropped, an integer constant plus or minus one, ``True`` and ``False``, and a statement dropped
(a call, an assignment, a ``raise``, a ``del``). Left alone: docstrings, annotations,
decorators, assertions (internal checks: mutated, they only fail louder), text (formatting,
f-strings and the slice that truncates a text) and ``canonical`` (the exploration's view of the
state, not the product's behaviour).

Each mutant runs the tests of ``tests/safety`` that execute its line (the exhaustive
exploration's bounded run among them; for a part of the daemon, those of ``tests/daemon`` and
``tests/api``), fastest first, stopping at the first failure, in a
process forked from this one with the mutated module served in place of the file: a mutant is
*killed* when a test fails (or it runs past its time), and *survives* otherwise. A survivor is
either killed by a new test or listed in ``verify/equivalent.py`` with the argument for why no
test can tell it from the original. Which tests execute which line is measured once, tracing
the suite (cached under ``${XDG_CACHE_HOME:-~/.cache}/srcs-mutate``).
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import importlib.abc
import importlib.util
import json
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType, ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
SUPERVISORD = ROOT / "supervisord"
PACKAGE = SUPERVISORD / "safety"
TARGETS = (
    "core.py",
    "prooftest.py",
    "causes.py",
    "book.py",
    "budget.py",
    "config.py",
    "transitions.py",
    "decision.py",
    "events.py",
    "availability.py",
    "vsc.py",
    "clients.py",
    "battery.py",
    "outputs.py",
    "step.py",
    "conditions.py",
    "charging.py",
    "proofrequest.py",
    "vscmessage.py",
    "rearm.py",
    "cheap.py",
    "deadline.py",
    "finish.py",
    "reflex.py",
    "face.py",
    "view.py",
)
SUITE = "tests/safety"
DAEMON_TARGETS = tuple(
    f"daemon/{name}"
    for name in (
        "timings.py",
        "refusal_log.py",
        "stop_request.py",
        "loop_status.py",
        "service_manager.py",
        "waiter.py",
        "listener.py",
        "link_port.py",
        "record_path.py",
        "output_bank.py",
        "parts.py",
        "lifecycle.py",
        "deadlines.py",
        "internal_fault.py",
        "answer.py",
    )
)
"""The parts the daemon's loop composes (``--daemon``), named by their path under supervisord/:
a name alone is one of the safety core's, in supervisord/safety (so ``verify/equivalent.py``
names the core's as it always has, and ``daemon/reflex.py`` is not ``reflex.py``)."""
DAEMON_SUITES = ("tests/daemon", "tests/api")
"""The tests of the daemon's parts (the listener's are in tests/api). A test that runs the
real srcsd as a process of its own executes no line in the runner's process, so the trace
gives it no mutant: a part is judged by the tests that run it in process."""
SKIPPED_FUNCTIONS = frozenset({"canonical"})
SKIPPED_NAMES = frozenset({"__all__", "_NOT_CANONICAL", "RATE_SLACK_NS"})  # canonical's alone

_NEGATED = {
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
    ast.Lt: ast.GtE,
    ast.LtE: ast.Gt,
    ast.Gt: ast.LtE,
    ast.GtE: ast.Lt,
}
_BOUNDARY = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt}
_TEXT = {
    ast.Eq: "==",
    ast.NotEq: "!=",
    ast.Is: "is",
    ast.IsNot: "is not",
    ast.In: "in",
    ast.NotIn: "not in",
    ast.Lt: "<",
    ast.LtE: "<=",
    ast.Gt: ">",
    ast.GtE: ">=",
}


@dataclass(frozen=True)
class Mutant:
    """One change: bytes ``start`` to ``end`` of ``file`` become ``replacement``."""

    file: str  # the module's file: a name in supervisord/safety, or a path under supervisord/
    line: int
    start: int
    end: int
    replacement: str
    what: str  # e.g. ">= -> >"
    original_line: str
    mutated_line: str
    at_import: bool  # at module level or in a class body: run when the module is imported
    where: str  # the enclosing class and function ("SafetyCore.__init__"; "" at module level)

    @property
    def key(self) -> tuple[str, str, str, str]:
        """What identifies the mutant across edits elsewhere: its file, where in it, and its
        line before and after (``verify/equivalent.py`` lists equivalent mutants by it)."""
        return self.file, self.where, self.original_line.strip(), self.mutated_line.strip()

    def source(self) -> str:
        data = path_of(self.file).read_bytes()
        return (data[: self.start] + self.replacement.encode() + data[self.end :]).decode()


class _Finder(ast.NodeVisitor):
    """Every mutant of one module (the module docstring says which)."""

    def __init__(self, file: str, data: bytes) -> None:
        self.file = file
        self.data = data
        self.offsets = [0]
        for line in data.split(b"\n"):
            self.offsets.append(self.offsets[-1] + len(line) + 1)
        self.found: list[Mutant] = []
        self._depth = 0  # functions entered (statements are dropped only inside one)
        self._functions = 0  # functions entered, ``__init__`` included
        self._where: list[str] = []  # the classes and functions around the node

    def at(self, line: int, col: int) -> int:
        return self.offsets[line - 1] + col

    def span(self, node: ast.AST) -> tuple[int, int]:
        start = self.at(node.lineno, node.col_offset)  # type: ignore[attr-defined]
        end = self.at(node.end_lineno, node.end_col_offset)  # type: ignore[attr-defined]
        return start, end

    def add(self, start: int, end: int, replacement: str, what: str) -> None:
        data = self.data
        line_start = data.rfind(b"\n", 0, start) + 1
        line_end = data.find(b"\n", start)
        original = data[line_start:line_end].decode()
        mutated = (data[line_start:start] + replacement.encode() + data[end:line_end]).decode()
        mutated = mutated.split("\n")[0] if "\n" in mutated else mutated
        line = data.count(b"\n", 0, start) + 1
        at_import = self._functions == 0
        where = ".".join(self._where)
        self.found.append(
            Mutant(
                self.file, line, start, end, replacement, what, original, mutated, at_import, where
            )
        )

    # -- what is left alone

    def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
        if node.name in SKIPPED_FUNCTIONS:
            return
        self.visit(node.args)
        # Statements are dropped inside functions, but not in ``__init__``, where a dropped
        # assignment only fails later with AttributeError.
        depth = self._depth
        self._depth = 0 if node.name == "__init__" else depth + 1
        self._functions += 1
        self._where.append(node.name)
        self._body(node.body)
        self._where.pop()
        self._functions -= 1
        self._depth = depth

    visit_AsyncFunctionDef = visit_FunctionDef  # type: ignore[assignment]

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        self._where.append(node.name)
        self._body(node.body)
        self._where.pop()

    def _body(self, body: list[ast.stmt]) -> None:
        for index, statement in enumerate(body):
            docstring = (
                index == 0
                and isinstance(statement, ast.Expr)
                and isinstance(statement.value, ast.Constant)
                and isinstance(statement.value.value, str)
            )
            if not docstring:
                self.visit(statement)

    def visit_Module(self, node: ast.Module) -> None:
        self._body(node.body)

    def visit_Assert(self, node: ast.Assert) -> None:
        return

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        return

    def visit_Slice(self, node: ast.Slice) -> None:
        return

    def visit_Import(self, node: ast.Import) -> None:
        return

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        return

    def visit_arguments(self, node: ast.arguments) -> None:
        for default in [*node.defaults, *node.kw_defaults]:
            if default is not None:
                self.visit(default)

    def visit_AnnAssign(self, node: ast.AnnAssign) -> None:
        if node.value is not None:
            self.visit(node.value)
            if _keeps(node.target):
                self._drop(node)

    def visit_Assign(self, node: ast.Assign) -> None:
        names = {t.id for t in node.targets if isinstance(t, ast.Name)}
        if names & SKIPPED_NAMES:
            return
        self.visit(node.value)
        if any(_keeps(t) for t in node.targets):
            self._drop(node)

    # -- the mutations

    def _drop(self, node: ast.stmt) -> None:
        if self._depth:
            self.add(*self.span(node), "pass", "statement dropped")

    def visit_Expr(self, node: ast.Expr) -> None:
        self.visit(node.value)
        if isinstance(node.value, ast.Call):
            self._drop(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        self.visit(node.value)
        self._drop(node)

    def visit_Raise(self, node: ast.Raise) -> None:
        self._drop(node)

    def visit_Delete(self, node: ast.Delete) -> None:
        self._drop(node)

    def visit_Compare(self, node: ast.Compare) -> None:
        self.generic_visit(node)
        left: ast.expr = node.left
        for op, right in zip(node.ops, node.comparators, strict=True):
            start, end = self.span(left)[1], self.span(right)[0]
            gap = self.data[start:end].decode()
            text = _TEXT[type(op)]
            at = gap.find(text if text != "in" else " in")
            if text == "in":
                at += 1
            if at < 0:
                raise ValueError(f"{self.file}:{node.lineno}: no {text!r} in {gap!r}")
            for other in {_NEGATED[type(op)], _BOUNDARY.get(type(op))} - {None}:
                assert other is not None
                self.add(
                    start + at, start + at + len(text), _TEXT[other], f"{text} -> {_TEXT[other]}"
                )
            left = right

    def visit_BoolOp(self, node: ast.BoolOp) -> None:
        self.generic_visit(node)
        text, other = ("and", "or") if isinstance(node.op, ast.And) else ("or", "and")
        start, end = self.span(node)
        pieces, cursor = [], start
        for value in node.values[1:]:
            value_start = self.span(value)[0]
            gap = self.data[cursor:value_start].decode()
            at = gap.rfind(f" {text} ")
            if at < 0:
                at = gap.rfind(f"{text} ")
                if at < 0:
                    raise ValueError(f"{self.file}:{node.lineno}: no {text!r} in {gap!r}")
            else:
                at += 1
            pieces.append(cursor + at)
            cursor = self.span(value)[1]
        replaced = self.data[start:end]
        for offset in reversed(pieces):
            local = offset - start
            replaced = replaced[:local] + other.encode() + replaced[local + len(text) :]
        self.add(start, end, replaced.decode(), f"{text} -> {other}")

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        self.generic_visit(node)
        if isinstance(node.op, ast.Not):
            start = self.span(node)[0]
            operand = self.span(node.operand)[0]
            self.add(start, operand, "", "not dropped")

    def visit_Constant(self, node: ast.Constant) -> None:
        value = node.value
        start, end = self.span(node)
        if isinstance(value, bool):
            self.add(start, end, str(not value), f"{value} -> {not value}")
        elif isinstance(value, int):
            for other in (value + 1, value - 1):
                self.add(start, end, str(other), f"{value} -> {other}")


def _keeps(target: ast.expr) -> bool:
    """Whether assigning ``target`` stores a fact in an object (an attribute, an item), which a
    dropped statement would lose; a local name dropped would only fail with NameError."""
    if isinstance(target, ast.Tuple):
        return any(_keeps(t) for t in target.elts)
    return isinstance(target, ast.Attribute | ast.Subscript)


def path_of(file: str) -> Path:
    """The file of a module as the runner names it (``core.py``, ``daemon/listener.py``)."""
    return SUPERVISORD / file if "/" in file else PACKAGE / file


def module_of(file: str) -> str:
    """The module's import name (``supervisord.safety.core``, ``supervisord.daemon.listener``)."""
    name = file.removesuffix(".py").replace("/", ".")
    return f"supervisord.{name}" if "/" in file else f"supervisord.safety.{name}"


@dataclass(frozen=True)
class Scope:
    """What one run traces: its modules and the tests that judge them."""

    targets: tuple[str, ...]
    suites: tuple[str, ...]
    name: str  # of its trace in the cache

    @staticmethod
    def of(files: Sequence[str]) -> Scope:
        """The scope of ``files``: the safety core's, or the daemon's parts' (not both)."""
        daemon = {"/" in file for file in files}
        if len(daemon) > 1:
            raise SystemExit("name modules of the safety core or of the daemon, not both")
        # A module named beyond the list is traced too: a line no trace sees is a survivor.
        if daemon == {True}:
            return Scope(tuple(dict.fromkeys([*DAEMON_TARGETS, *files])), DAEMON_SUITES, "daemon")
        return Scope(tuple(dict.fromkeys([*TARGETS, *files])), (SUITE,), "safety")


def mutants(files: Sequence[str] = TARGETS) -> list[Mutant]:
    """Every mutant of ``files`` (names in supervisord/safety, paths under supervisord/), in
    source order."""
    found: list[Mutant] = []
    for file in files:
        data = path_of(file).read_bytes()
        finder = _Finder(file, data)
        finder.visit(ast.parse(data))
        found += sorted(finder.found, key=lambda m: (m.start, m.what))
    return found


# -- running


class _MutantLoader(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Serves the mutated source in place of one module's file."""

    def __init__(self, name: str, source: str, path: str) -> None:
        self.name, self.text, self.path = name, source, path

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> Any:
        if fullname != self.name:
            return None
        return importlib.util.spec_from_loader(fullname, self, origin=self.path)

    def create_module(self, spec: Any) -> None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        module.__file__ = self.path
        exec(compile(self.text, self.path, "exec"), module.__dict__)  # noqa: S102 -- the mutant


def _cache_dir() -> Path:
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "srcs-mutate"


def _fingerprint(scope: Scope) -> str:
    digest = hashlib.sha256(" ".join(scope.targets).encode())
    packages = {path_of(file).parent for file in scope.targets} | {PACKAGE}
    sources = [p for package in sorted(packages) for p in package.glob("*.py")]
    sources += [p for suite in scope.suites for p in (ROOT / suite).glob("*.py")]
    sources += (ROOT / "verify").glob("*.py")
    for path in sorted(p for p in sources if p.name not in ("mutate.py", "equivalent.py")):
        digest.update(str(path.relative_to(ROOT)).encode() + path.read_bytes())
    return digest.hexdigest()[:16]


def _spawn(body: Callable[[], int]) -> int:
    """Run ``body()`` (returning an exit code) in a child process with its output discarded;
    the child's pid."""
    pid = os.fork()
    if pid == 0:  # the child
        code = 70
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(null, 2)
            code = int(body())
        except BaseException:
            (_cache_dir() / "last-error.txt").write_text(traceback.format_exc())
            raise
        finally:
            os._exit(code)
    return pid


def _forked(body: Callable[[], int], timeout: float) -> int | None:
    """``body()``'s exit code in a child process, or ``None`` if it ran past ``timeout``
    seconds (then it is killed)."""
    pid = _spawn(body)
    deadline = time.monotonic() + timeout
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return None
        time.sleep(0.02)


def _clear_caches(targets: Sequence[str]) -> None:
    """Empty the memo of every cached function of the targets (``reflex.prepare``). A call the
    memo answers runs none of the function's lines, so without this the trace would give them
    to the first test that made the call alone, and a mutant of them would run against that
    test only, not against the tests that read its result later."""
    for file in targets:
        module = sys.modules.get(module_of(file))
        if module is None:
            continue  # not imported yet: nothing cached
        for value in vars(module).values():
            clear = getattr(value, "cache_clear", None)
            if callable(clear) and getattr(value, "__module__", None) == module.__name__:
                clear()


class _Tracer:
    """A pytest plugin recording which lines of the targets each test executes, and its time."""

    def __init__(self, targets: Sequence[str]) -> None:
        self.targets = targets
        self.files = {str(path_of(f)): f for f in targets}
        self.lines: set[tuple[str, int]] = set()
        self.by_test: dict[str, dict[str, Any]] = {}

    def _trace(self, frame: FrameType, event: str, arg: object) -> Any:
        file = self.files.get(frame.f_code.co_filename)
        if file is None:
            return None

        def local(frame: FrameType, event: str, arg: object) -> Any:
            if event == "line":
                self.lines.add((file, frame.f_lineno))
            return local

        return local

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_call(self, item: pytest.Item) -> Iterator[None]:
        _clear_caches(self.targets)
        self.lines = set()
        started = time.perf_counter()
        sys.settrace(self._trace)
        try:
            yield
        finally:
            sys.settrace(None)
            self.by_test[item.nodeid] = {
                "seconds": time.perf_counter() - started,
                "lines": sorted(self.lines),
            }


def coverage(scope: Scope) -> dict[str, dict[str, Any]]:
    """For every test of the scope's suites: its time and the target lines it executes
    (cached)."""
    cache = _cache_dir() / f"coverage-{scope.name}-{_fingerprint(scope)}.json"
    if cache.exists():
        loaded: dict[str, dict[str, Any]] = json.loads(cache.read_text())
        return loaded
    cache.parent.mkdir(parents=True, exist_ok=True)
    out = cache.with_suffix(".partial")

    def plain() -> int:
        return int(pytest.main([*scope.suites, "-q", "-p", "no:cacheprovider"]))

    def traced() -> int:
        tracer = _Tracer(scope.targets)
        pytest.main([*scope.suites, "-q", "-p", "no:cacheprovider"], plugins=[tracer])
        out.write_text(json.dumps(tracer.by_test))
        return 0

    print(
        "running the suite unmutated, then tracing it (once per change of the sources)", flush=True
    )
    code = _forked(plain, timeout=3600)
    if code != 0:
        raise SystemExit(f"the suite does not pass unmutated (exit {code}): fix it first")
    if _forked(traced, timeout=7200) != 0:
        raise SystemExit("tracing the suite failed")
    out.replace(cache)
    result: dict[str, dict[str, Any]] = json.loads(cache.read_text())
    return result


def _start(mutant: Mutant, tests: list[str]) -> int:
    """The pid of a child running ``tests`` against ``mutant``: the mutated module served in
    place of its file, stopping at the first failure."""
    module = module_of(mutant.file)
    source = mutant.source()
    storage = _cache_dir() / "hypothesis"

    def body() -> int:
        os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = str(storage)
        sys.meta_path.insert(0, _MutantLoader(module, source, str(path_of(mutant.file))))
        return int(pytest.main([*tests, "-x", "-q", "-p", "no:cacheprovider"]))

    return _spawn(body)


CHECKER_TESTS = ("rejects_each_broken_core", "counterexample_is_a_regression_test")
"""Tests of the checker itself: they load core.py from its file, so no mutant reaches them."""


def _run_all(
    found: list[Mutant], equivalent: set[tuple[str, str, str, str]], jobs: int, scope: Scope
) -> dict[str, list[Mutant]]:
    """Run every mutant of ``found`` against the tests that execute its line, ``jobs`` at a
    time; each outcome (``killed``, ``timeout``, ``survived``, ``equivalent``, ``listed but
    killed``) with its mutants. The outcomes are also kept, as they come, for ``--survivors``."""
    tests = coverage(scope)
    by_line: dict[tuple[str, int], list[str]] = {}
    for nodeid, seen in tests.items():
        for file, line in seen["lines"]:
            by_line.setdefault((file, line), []).append(nodeid)
    results_path = _cache_dir() / "results.json"
    results = json.loads(results_path.read_text()) if results_path.exists() else {}
    outcomes: dict[str, list[Mutant]] = {}
    started = time.perf_counter()

    def record(m: Mutant, outcome: str) -> None:
        if m.key in equivalent:
            outcome = "equivalent" if outcome == "survived" else "listed but killed"
        outcomes.setdefault(outcome, []).append(m)
        results["|".join(m.key)] = outcome
        results_path.write_text(json.dumps(results, indent=1))
        if outcome in ("survived", "listed but killed"):
            print(
                f"{outcome.upper()} {m.file}:{m.line} {m.where}: {m.what}: {m.mutated_line.strip()}"
            )
        done = sum(len(v) for v in outcomes.values())
        if done % 25 == 0 or done == len(found):
            counts = {k: len(v) for k, v in outcomes.items()}
            print(f"... {done}/{len(found)} {counts} {time.perf_counter() - started:.0f} s")
        sys.stdout.flush()

    waiting = list(found)
    running: dict[int, tuple[Mutant, float]] = {}
    while waiting or running:
        while waiting and len(running) < jobs:
            m = waiting.pop(0)
            # A line run at import (a constant, a class attribute) reaches every test.
            covering = list(tests) if m.at_import else by_line.get((m.file, m.line), [])
            selected = [t for t in covering if not any(c in t for c in CHECKER_TESTS)]
            if not selected:
                record(m, "survived")  # no test executes the line
                continue
            selected.sort(key=lambda t: tests[t]["seconds"])
            budget = 60 + 5 * sum(tests[t]["seconds"] for t in selected)
            running[_start(m, selected)] = (m, time.monotonic() + budget)
        if not running:
            continue  # every mutant taken so far needed no run (no test executes its line)
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid:
            m, _ = running.pop(pid)
            record(m, "survived" if os.waitstatus_to_exitcode(status) == 0 else "killed")
            continue
        for pid, (m, deadline) in list(running.items()):
            if time.monotonic() > deadline:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                del running[pid]
                record(m, "timeout")
        time.sleep(0.05)
    return outcomes


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="./dev mutate", description=__doc__)
    parser.add_argument(
        "files",
        nargs="*",
        help=f"modules: of the safety core by name, of the daemon by path (daemon/listener.py); "
        f"default: {' '.join(TARGETS)}",
    )
    parser.add_argument(
        "--daemon", action="store_true", help=f"the daemon's parts: {' '.join(DAEMON_TARGETS)}"
    )
    parser.add_argument("--list", action="store_true", help="list the mutants and stop")
    parser.add_argument("--match", help="only the mutants whose changed line contains this text")
    parser.add_argument("--survivors", action="store_true", help="only the last run's survivors")
    parser.add_argument("-j", "--jobs", type=int, default=1, help="mutants run at once")
    args = parser.parse_args(argv)
    from verify.equivalent import EQUIVALENT  # noqa: PLC0415 -- a data file, read when run

    files = args.files or (DAEMON_TARGETS if args.daemon else TARGETS)
    scope = Scope.of(files)
    found = mutants(files)
    if args.match:
        found = [m for m in found if args.match in m.mutated_line]
    if args.survivors:
        path = _cache_dir() / "results.json"
        last = json.loads(path.read_text()) if path.exists() else {}
        found = [m for m in found if last.get("|".join(m.key)) != "killed"]
    if args.list:
        for m in found:
            print(f"{m.file}:{m.line} {m.where}: {m.what}: {m.mutated_line.strip()}")
        print(f"{len(found)} mutants")
        return 0
    os.chdir(ROOT)
    sys.path.insert(0, str(ROOT))
    started = time.perf_counter()
    outcomes = _run_all(found, {e.key for e in EQUIVALENT}, args.jobs, scope)
    count = {k: len(outcomes.get(k, [])) for k in ("killed", "timeout", "survived", "equivalent")}
    killed = count["killed"] + count["timeout"]
    print(
        f"\nmutation score: {killed}/{len(found)} killed ({count['timeout']} by a timeout), "
        f"{count['equivalent']} equivalent (verify/equivalent.py), {count['survived']} survived: "
        f"{killed}/{len(found) - count['equivalent']} of the mutants not equivalent; "
        f"{time.perf_counter() - started:.0f} s"
    )
    every = {m.key for m in mutants([*TARGETS, *DAEMON_TARGETS])}
    stale = [e for e in EQUIVALENT if e.key not in every]
    for entry in stale:
        print(f"stale entry in verify/equivalent.py (no such mutant any more): {entry.key}")
    wrong = outcomes.get("listed but killed", [])
    return 1 if count["survived"] or stale or wrong else 0


if __name__ == "__main__":
    sys.exit(main())
