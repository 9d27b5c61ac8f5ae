"""The descriptor-leak check the socket and file tests share (imported by their conftest)."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator

import pytest

from supervisord.tooling.polling import poll_until

LOOKUP_THREAD = "srcsd-names"
"""The API server's user-name lookup thread (``supervisord/api/names.py``): closing the server
never waits for it, and a lookup it is in (NSS reading /etc/passwd) holds a descriptor until
it returns."""
LOOKUP_WAIT_S = 5.0


@pytest.fixture(autouse=True)
def no_descriptor_left_open() -> Iterator[None]:
    """Fail any test that leaves a file descriptor open (a socket, selector, client or writer
    not closed). A user-name lookup the test started and that is still running is let finish
    first (a few seconds at most): its file is the lookup's, closed when it returns."""
    before = set(os.listdir("/proc/self/fd"))
    threads = set(threading.enumerate())
    yield
    started = [t for t in threading.enumerate() if t.name == LOOKUP_THREAD and t not in threads]
    poll_until(
        lambda: not any(t.is_alive() for t in started), bool, LOOKUP_WAIT_S, time.sleep, 0.01
    )
    leaked = set(os.listdir("/proc/self/fd")) - before
    assert not leaked, f"file descriptors left open: {sorted(leaked)}"
