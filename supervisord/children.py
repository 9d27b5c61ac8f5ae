"""The child processes a command starts (the demo's simulator and supervisor, and the test
kit's): ending them politely first and for good if need be, and reading their logs."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path


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
