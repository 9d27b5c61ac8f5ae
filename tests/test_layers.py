"""The package's layers: the product never leans on its test kit, the daemon not on tooling.

``supervisord/testkit/`` is for tests, the product's and integrators'; it may import the
product, never the reverse, so that what ships to a robot works without it and a change to the
kit cannot change the supervisor. ``supervisord/tooling/`` serves the programs that run other
programs (the demo, the simulator's runner, the kit, the benches); the daemon's own packages
never import it.
"""

from __future__ import annotations

import ast
import json
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Final

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "supervisord"
KIT = "supervisord.testkit"


def _module(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(source: str, module: str, is_package: bool = False) -> Iterator[tuple[int, str]]:
    """Every module ``source`` (the text of ``module``) names: its imports, relative ones
    resolved, and string constants that spell a module of the package (``python -m``
    commands, ``importlib``)."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                parent = ".".join([*base, node.module] if node.module else base)
            else:
                parent = node.module or ""
            yield node.lineno, parent
            for alias in node.names:
                yield node.lineno, f"{parent}.{alias.name}"
        elif isinstance(node, ast.Constant) and str(node.value).startswith("supervisord."):
            yield node.lineno, str(node.value).split()[0]


def _file_imports(path: Path) -> Iterator[tuple[int, str]]:
    return _imports(path.read_text(), _module(path), path.name == "__init__.py")


def _leans_on_kit(name: str) -> bool:
    return name == KIT or name.startswith(KIT + ".")


def product_files() -> list[Path]:
    kit = PACKAGE / "testkit"
    return sorted(p for p in PACKAGE.rglob("*.py") if kit not in p.parents)


def test_nothing_outside_the_test_kit_imports_it() -> None:
    """No module of ``supervisord/`` outside ``supervisord/testkit/`` imports the test kit,
    directly, relatively or by name in a string."""
    files = product_files()
    assert len(files) > 50  # the walk found the package
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {name}"
        for path in files
        for line, name in _file_imports(path)
        if _leans_on_kit(name)
    ]
    assert found == []


def test_the_walk_sees_every_kind_of_import() -> None:
    """The check above would catch each way of naming the kit: ``import``, ``from ... import``,
    a relative import from a sibling package and a ``python -m`` string; and only the kit."""
    lines = {
        "import supervisord.testkit.robot": True,
        "from supervisord.testkit.wait import wait_until": True,
        "from supervisord import testkit": True,
        "from ..testkit import robot": True,
        "from ..testkit.robot import Robot": True,
        "from . import testkit": False,  # supervisord.sim.testkit: not the kit
        "from ..sim import pty": False,
        "import supervisord.testkits": False,
        "COMMAND = ['python', '-m', 'supervisord.testkit.clients']": True,
        "COMMAND = ['python', '-m', 'supervisord.cli.srcsd']": False,
    }
    for source, leans in lines.items():
        names = [name for _, name in _imports(source, "supervisord.sim.sample")]
        assert any(_leans_on_kit(n) for n in names) is leans, (source, names)


DAEMON = ("api", "config", "daemon", "links", "outputs", "protocol", "record", "safety")
"""The packages ``srcsd`` is made of."""
TOOLING = "supervisord.tooling"


def test_the_daemon_imports_no_tooling() -> None:
    """No module of the daemon's packages imports ``supervisord/tooling/`` (child processes,
    polling): it is the demo's and the tests', not the supervisor's."""
    files = [path for package in DAEMON for path in sorted((PACKAGE / package).rglob("*.py"))]
    assert len(files) > 50
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {name}"
        for path in files
        for line, name in _file_imports(path)
        if name == TOOLING or name.startswith(TOOLING + ".")
    ]
    assert found == []
    assert not (PACKAGE / "children.py").exists()
    assert not (PACKAGE / "polling.py").exists()


CLOCKS = frozenset(
    f"{name}{suffix}"
    for name in ("monotonic", "time", "perf_counter", "clock_gettime", "process_time")
    for suffix in ("", "_ns")
)
"""The ``time`` module's clocks."""
ONE_CLOCK = ("api", "daemon")
"""The packages whose every deadline runs on the loop's injected clock (SR-2.11)."""


def clock_reads(source: str) -> list[int]:
    """The lines of ``source`` that read one of :data:`CLOCKS`: ``time.monotonic``, or a
    name imported from ``time``."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and node.attr in CLOCKS:
            if isinstance(node.value, ast.Name) and node.value.id == "time":
                lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.module == "time":
            lines += [node.lineno for alias in node.names if alias.name in CLOCKS]
    return lines


def test_the_loops_world_reads_no_clock_of_its_own() -> None:
    """No module under ``supervisord/api`` or ``supervisord/daemon`` reads a clock: the loop
    hands its injected clock's time to everything it drives, so a test that drives the clock
    drives all of it (the sink's threads wait on real time in ``supervisord/lane.py``, at the
    exit only). The check sees both spellings of a read."""
    files = [path for package in ONE_CLOCK for path in sorted((PACKAGE / package).rglob("*.py"))]
    assert len(files) > 10
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}"
        for path in files
        for line in clock_reads(path.read_text())
    ]
    assert found == []
    assert clock_reads("import time\nnow = time.monotonic_ns()\n") == [2]
    assert clock_reads("from time import perf_counter, sleep\n") == [1]
    assert clock_reads("import time\ntime.sleep(1)\n") == []


# -- the layers the entry points load, and the direction of every import -------------------

ENTRY_POINTS = ("supervisord.cli.srcsctl", "supervisord.cli.exporter", "supervisord.cli.ros2")
"""``srcsctl``, ``srcs-exporter`` and ``srcs-ros2`` (pyproject.toml's scripts): clients of
the socket, which decide nothing the safety core decides."""
SAFETY = "supervisord.safety"
LOADED = "import json, sys; import {module}; print(json.dumps(sorted(sys.modules)))"


@pytest.mark.parametrize("module", ENTRY_POINTS)
def test_the_clients_entry_points_load_no_module_of_the_safety_core(module: str) -> None:
    """SR-8.8: importing ``srcsctl``'s, ``srcs-exporter``'s or ``srcs-ros2``'s entry module,
    in a fresh interpreter, loads no module of ``supervisord/safety``: the operator's
    commands and the clients stand on the client library, not on the core they talk to
    (what a command needs of the record or the config is imported when it runs)."""
    result = subprocess.run(
        [sys.executable, "-c", LOADED.format(module=module)],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
        cwd=PACKAGE.parent,
    )
    loaded = json.loads(result.stdout)
    assert module in loaded
    assert [n for n in loaded if n == SAFETY or n.startswith(SAFETY + ".")] == []


PROOFTEST_RECORD: Final = {
    "seq": 7,
    "mono_ns": 7_000_000_000,
    "utc": "2026-03-01T12:00:07.000000+00:00",
    "kind": "prooftest",
    "from": "STOPPED",
    "to": "STOPPED",
    "causes": [
        {
            "name": "vsc_watchdog_untested",
            "severity": "stop",
            "active": True,
            "latched": True,
            "raised_ns": 1,
            "cleared_ns": None,
            "details": {"reason": "late"},
        }
    ],
    "changes": [{"name": "vsc_watchdog_untested", "change": "updated"}],
    "trigger": {"event": "tick"},
    "prooftest": {
        "result": "failed",
        "failure": "late",
        "trip_ms": 910,
        "cleared": None,
        "cleared_ns": None,
        "cleared_ms": None,
    },
}
"""A failed proof test's record, as the daemon writes it: its line names the failure in words."""
PRINTED = (
    "import json, sys; from supervisord.cli.srcsctl import main\n"
    "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
    "print(json.dumps(sorted(sys.modules)), file=sys.stderr)"
)


@pytest.mark.parametrize("cause", ["vsc_watchdog_untested", "client_lost:planner"])
def test_printing_the_record_loads_no_module_of_the_safety_core(tmp_path: Path, cause: str) -> None:
    """SR-8.8: ``srcsctl log`` printing a proof test's record (its verdict in words) and
    filtering by ``--cause`` loads no module of ``supervisord/safety``: the words and the
    limits it prints are the shared vocabulary's and the record's, not the core's."""
    path = tmp_path / "stops.jsonl"
    path.write_text(json.dumps(PROOFTEST_RECORD) + "\n")
    result = subprocess.run(
        [sys.executable, "-c", PRINTED, "log", "--file", str(path), "--cause", cause, "--causes"],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
        cwd=PACKAGE.parent,
    )
    if cause == "vsc_watchdog_untested":  # the line was printed: the verdict was read
        assert "proof test FAILED: the VSC reported the user-timeout e-stop late" in result.stdout
    loaded = json.loads(result.stderr.splitlines()[-1])
    assert "supervisord.cli.log" in loaded
    assert [n for n in loaded if n == SAFETY or n.startswith(SAFETY + ".")] == []


EXAMPLE_CONFIG: Final = PACKAGE.parent / "config" / "example-serial-gpio.toml"
"""A robot's real config, as the package ships it: its socket and record moved by the tests."""
RAN: Final = (
    "import json, sys; from {module} import main\n"
    "try:\n    code = main(sys.argv[1:])\nexcept SystemExit as stop:\n    code = stop.code\n"
    "print(json.dumps([code, sorted(sys.modules)]), file=sys.stderr)"
)


def _robot_config(tmp_path: Path) -> Path:
    """The shipped example with its socket (where no daemon listens) and its record (one
    proof test's record) in ``tmp_path``."""
    text = EXAMPLE_CONFIG.read_text()
    assert '"/run/srcsd/api.sock"' in text
    assert '"/var/lib/srcsd/stops.jsonl"' in text
    config = tmp_path / "robot.toml"
    config.write_text(
        text.replace('"/run/srcsd/api.sock"', f'"{tmp_path / "api.sock"}"').replace(
            '"/var/lib/srcsd/stops.jsonl"', f'"{tmp_path / "stops.jsonl"}"'
        )
    )
    (tmp_path / "stops.jsonl").write_text(json.dumps(PROOFTEST_RECORD) + "\n")
    return config


def _run(module: str, *argv: str) -> tuple[int, str, list[str]]:
    """``module``'s ``main(argv)`` in a fresh interpreter: its exit status, what it printed
    on stderr and the modules it had loaded when it returned."""
    result = subprocess.run(
        [sys.executable, "-c", RAN.format(module=module), *argv],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
        cwd=PACKAGE.parent,
    )
    *said, last = result.stderr.splitlines()
    code, loaded = json.loads(last)
    return code, "\n".join([result.stdout, *said]), loaded


@pytest.mark.parametrize(
    ("command", "status", "said"),
    [
        ("status", 3, "cannot connect to {tmp}/api.sock"),  # the config's: no daemon there
        ("log", 0, "proof test FAILED"),  # the config's record, read and printed
    ],
)
def test_srcsctl_reading_a_robots_config_loads_no_module_of_the_safety_core(
    tmp_path: Path, command: str, status: int, said: str
) -> None:
    """SR-8.8: ``srcsctl --config FILE status`` (the socket) and ``log`` (the record) read a
    robot's real config with the clients' reader and load no module of ``supervisord/safety``
    while they run: the daemon, not the client, validates the safety sections."""
    config = _robot_config(tmp_path)
    code, printed, loaded = _run("supervisord.cli.srcsctl", "--config", str(config), command)
    assert (code, said.format(tmp=tmp_path) in printed) == (status, True), printed
    assert [n for n in loaded if n == SAFETY or n.startswith(SAFETY + ".")] == []
    assert "supervisord.config.client" in loaded


def test_the_exporter_reading_a_robots_config_loads_no_module_of_the_safety_core(
    tmp_path: Path,
) -> None:
    """SR-8.8: ``srcs-exporter --config FILE`` reads a robot's real config with the clients'
    reader and loads no module of ``supervisord/safety``; it is stopped after reading it by
    a port already taken on loopback (exit 1, its failure to listen)."""
    config = _robot_config(tmp_path)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, printed, loaded = _run(
            "supervisord.cli.exporter", "--config", str(config), "--listen", f"127.0.0.1:{port}"
        )
    assert (code, f"cannot listen on 127.0.0.1:{port}" in printed) == (1, True), printed
    assert [n for n in loaded if n == SAFETY or n.startswith(SAFETY + ".")] == []
    assert "supervisord.config.client" in loaded


def test_the_configuration_imports_nothing_of_the_daemon() -> None:
    """No module of ``supervisord/config`` imports ``supervisord/daemon``: the daemon is built
    from the configuration, so what the configuration needs lives in it or below it."""
    files = sorted((PACKAGE / "config").rglob("*.py"))
    assert len(files) > 5
    found = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {name}"
        for path in files
        for line, name in _file_imports(path)
        if name == "supervisord.daemon" or name.startswith("supervisord.daemon.")
    ]
    assert found == []


def _module_graph(roots: tuple[Path, ...]) -> dict[str, set[str]]:
    """Every module under ``roots`` and the modules of the same tree it imports (anywhere in
    the file: a function's import is an import too), each name resolved to its module."""
    paths = {_module_of(path): path for root in roots for path in sorted(root.rglob("*.py"))}
    graph: dict[str, set[str]] = {}
    for module, path in paths.items():
        names = {name for _, name in _imports(path.read_text(), module, path.name == "__init__.py")}
        graph[module] = {
            target
            for name in names
            if (target := _known(name, paths)) is not None and target != module
        }
    return graph


def _module_of(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _known(name: str, modules: dict[str, Path]) -> str | None:
    """``name`` (a module, or a name inside one) as a module of the tree, if it is one."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The circles of ``graph``: each strongly connected set of two modules or more (a
    package's ``__init__`` that imports its own modules is left out: it is their face)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for target in graph.get(node, ()):
            if target.startswith(node + "."):
                continue  # a package's face naming its own modules
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            members = []
            while True:
                member = stack.pop()
                members.append(member)
                if member == node:
                    break
            if len(members) > 1:
                circles.append(sorted(members))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return circles


def test_no_module_imports_itself_through_others() -> None:
    """No import circle among the modules of ``supervisord/`` and ``verify/``: every import
    runs one way, so each module can be read, tested and changed knowing only what is below
    it (``verify/mutate.py`` and ``verify/equivalent.py`` once imported each other)."""
    graph = _module_graph((PACKAGE, PACKAGE.parent / "verify"))
    assert len(graph) > 100
    assert import_circles(graph) == []
    assert import_circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert import_circles({"p": {"p.x"}, "p.x": {"p"}}) == []
