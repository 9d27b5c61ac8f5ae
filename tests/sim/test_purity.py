"""The simulator's model and fault plan are pure: no I/O, no clock, no threads."""

from __future__ import annotations

from pathlib import Path

import pytest

import supervisord.sim
from tests.protocol.test_purity import FORBIDDEN_CALLS, violations

PURE = ("model.py", "faults.py")
ALLOWED_EXTRA = {"collections", "heapq", "math", "random"}


@pytest.mark.parametrize("name", PURE)
def test_pure_modules_do_no_io(name: str) -> None:
    source = (Path(supervisord.sim.__file__).parent / name).read_text()
    found = [
        problem
        for problem in violations(source)
        if not any(problem.endswith(f"imports {module}") for module in ALLOWED_EXTRA)
        and "imports supervisord." not in problem
    ]
    assert found == []
    assert "open" in FORBIDDEN_CALLS


def test_pure_modules_import_only_pure_supervisord_modules() -> None:
    for name in PURE:
        source = (Path(supervisord.sim.__file__).parent / name).read_text()
        for line in source.splitlines():
            if line.startswith(("from supervisord", "import supervisord")):
                module = line.split()[1]
                assert module.startswith(
                    ("supervisord.protocol", "supervisord.errors", "supervisord.sim.")
                ), line
                assert module not in ("supervisord.sim.engine", "supervisord.sim.serial_side")
