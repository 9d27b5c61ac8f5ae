"""TOML: the standard library's ``tomllib`` (Python 3.11), or on 3.10 the ``tomli`` package it
came from (the same code and names; a dependency only below 3.11, pyproject.toml)."""

from __future__ import annotations

import sys

if sys.version_info >= (3, 11):
    from tomllib import TOMLDecodeError, load, loads
else:  # Ubuntu 22.04's Python 3.10 (docs/install.md "Platforms")
    from tomli import TOMLDecodeError, load, loads

__all__ = ["TOMLDecodeError", "load", "loads"]
