"""The safety core is pure: no module of it imports anything that does I/O or keeps time."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import supervisord.safety

PACKAGE = Path(supervisord.safety.__file__).parent
FORBIDDEN = {
    "asyncio",
    "can",
    "ctypes",
    "fcntl",
    "gpiod",
    "io",
    "logging",
    "mmap",
    "multiprocessing",
    "os",
    "pathlib",
    "random",
    "select",
    "selectors",
    "serial",
    "shutil",
    "signal",
    "socket",
    "subprocess",
    "sys",
    "systemd",
    "tempfile",
    "threading",
    "time",
}
CLOCKS = {"datetime"}  # pure date arithmetic is fine in the codecs, but the core has no clock
FORBIDDEN_CALLS = {"open", "print", "input", "exec", "eval", "__import__", "breakpoint"}
TOOL = "diagram.py"  # the documentation tool: files only inside main(), imported by nobody


def _imports(tree: ast.AST) -> list[str]:
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def _module_files() -> list[Path]:
    return sorted(PACKAGE.glob("*.py"))


def _supervisord_closure() -> set[str]:
    """Every ``supervisord`` module the core's modules import, transitively."""
    seen: set[str] = set()
    todo = [f"supervisord.safety.{p.stem}" for p in _module_files() if p.name != TOOL]
    while todo:
        name = todo.pop()
        if name in seen or name.endswith(".__init__"):
            continue
        seen.add(name)
        spec = importlib.util.find_spec(name)
        assert spec is not None
        assert spec.origin is not None
        tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
        todo.extend(m for m in _imports(tree) if m.startswith("supervisord"))
    return seen


def test_core_modules_import_no_io() -> None:
    """No module of the core, nor any supervisord module it pulls in, imports an I/O, clock,
    thread or randomness module."""
    for name in _supervisord_closure():
        spec = importlib.util.find_spec(name)
        assert spec is not None
        assert spec.origin is not None
        tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
        bad = {m for m in _imports(tree) if m.split(".")[0] in FORBIDDEN}
        assert not bad, f"{name} imports {bad}"


def test_core_modules_use_no_clock() -> None:
    """No module of the safety package itself imports ``datetime``: time only comes in."""
    for path in _module_files():
        imports = _imports(ast.parse(path.read_text(encoding="utf-8")))
        assert not {m for m in imports if m.split(".")[0] in CLOCKS}, path.name


def test_core_modules_call_no_io_builtins() -> None:
    """No module of the core calls ``open``, ``print`` or another I/O builtin."""
    for path in _module_files():
        if path.name == TOOL:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        calls = {
            node.func.id
            for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
        }
        assert not calls & FORBIDDEN_CALLS, f"{path.name} calls {calls & FORBIDDEN_CALLS}"


def test_the_diagram_tool_does_io_only_inside_main_and_nobody_imports_it() -> None:
    """The diagram tool's file access lives only in ``main``, and no core module imports it."""
    tree = ast.parse((PACKAGE / TOOL).read_text(encoding="utf-8"))
    top_level = {
        m
        for node in tree.body
        if isinstance(node, ast.Import | ast.ImportFrom)
        for m in _imports(node)
    }
    assert not {m for m in top_level if m.split(".")[0] in FORBIDDEN}
    for path in _module_files():
        if path.name != TOOL:
            imports = _imports(ast.parse(path.read_text(encoding="utf-8")))
            assert "supervisord.safety.diagram" not in imports, path.name
