"""The descriptor-leak check the socket and file tests share (imported by their conftest)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


@pytest.fixture(autouse=True)
def no_descriptor_left_open() -> Iterator[None]:
    """Fail any test that leaves a file descriptor open (a socket, selector, client or writer
    not closed)."""
    before = set(os.listdir("/proc/self/fd"))
    yield
    leaked = set(os.listdir("/proc/self/fd")) - before
    assert not leaked, f"file descriptors left open: {sorted(leaked)}"
