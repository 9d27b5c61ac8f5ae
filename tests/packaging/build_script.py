"""packaging/build_deb.py loaded as a module: the tests read its constants (the launcher, the
copyright check) from the script itself, not from a copy."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


def build_deb() -> ModuleType:
    """packaging/build_deb.py as a module."""
    spec = importlib.util.spec_from_file_location("build_deb", ROOT / "packaging/build_deb.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
