"""The child processes a command starts (the demo's simulator and supervisor, and the test
kit's): starting them and waiting until they are ready, ending them politely first and for
good if need be, and reading their logs."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Literal


def terminate(process: subprocess.Popen[bytes], timeout: float = 10.0) -> int:
    """SIGTERM (after SIGCONT, so that a stopped process can act on it), wait ``timeout``
    seconds, then SIGKILL. Returns the exit status: 0 for a clean stop, negative if killed."""
    if process.poll() is None:
        process.send_signal(signal.SIGCONT)
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


def kill(process: subprocess.Popen[bytes] | None) -> None:
    """SIGKILL and reap, if it still runs (SIGCONT first: a stopped process must die too)."""
    if process is not None and process.poll() is None:
        process.send_signal(signal.SIGCONT)
        process.kill()
        process.wait()


def log_tail(path: Path, tail: int | None = None) -> str:
    """The end of a child's log file (the last ``tail`` characters, or all); "" if none."""
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        return ""
    return text if tail is None else text[-tail:]


def spawn(
    command: Sequence[str], log: Path | None, env: Mapping[str, str] | None = None
) -> subprocess.Popen[bytes]:
    """Start ``command`` with no stdin and its output appended to ``log`` (discarded if None)."""
    with open(log or os.devnull, "ab") as out:
        return subprocess.Popen(  # noqa: S603 - the callers run our own interpreter and modules
            list(command), stdin=subprocess.DEVNULL, stdout=out, stderr=out, env=env
        )


def wait_started(
    process: subprocess.Popen[bytes],
    ready: Callable[[], bool],
    timeout: float,
    interval: float,
    serve: Callable[[], object] = lambda: None,
) -> Literal["ready", "exited", "timeout"]:
    """Poll a child just started until ``ready()`` (``"ready"``), until it exits
    (``"exited"``), or for ``timeout`` seconds, after which it is killed (``"timeout"``).
    ``serve`` runs between polls (a peer the child needs answered to get ready)."""
    end = time.monotonic() + timeout
    while True:
        if ready():
            return "ready"
        if process.poll() is not None:
            return "exited"
        if time.monotonic() > end:
            kill(process)
            return "timeout"
        serve()
        time.sleep(interval)
