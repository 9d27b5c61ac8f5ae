"""Ending the processes a test or the demo started: politely first, for good if need be."""

from __future__ import annotations

import signal
import subprocess


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
