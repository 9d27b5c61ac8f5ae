"""Whether srcsd can be started here in SCHED_FIFO as its unit starts it (SR-9.8): the one probe
that the tests of the real-time start (``test_realtime_start.py``) and of the unit-like start
(``test_service_manager_absent.py``) skip by, each naming what it needs besides."""

from __future__ import annotations

import functools
import os
import shutil
import subprocess

import pytest


@functools.cache
def fifo_refused(root_for: str, tools: tuple[str, ...]) -> str | None:
    """Why the start cannot be made here (``None``: it can): not root (``root_for`` says what
    root is needed for), one of ``tools`` missing (util-linux; ``chrt`` is always needed), or a
    kernel that gives no SCHED_FIFO (``chrt`` refused). Asked once per question: the probe
    runs ``chrt``."""
    if os.geteuid() != 0:
        return f"needs root: {root_for}"
    for tool in dict.fromkeys(("chrt", *tools)):
        if shutil.which(tool) is None:
            return f"needs {tool} (util-linux)"
    probe = subprocess.run(
        ["chrt", "-f", "10", "true"], capture_output=True, check=False, timeout=30
    )
    if probe.returncode != 0:
        return "this kernel gives no SCHED_FIFO here (CONFIG_RT_GROUP_SCHED without a budget)"
    return None


def needs_fifo(root_for: str, *tools: str) -> pytest.MarkDecorator:
    """A test's mark: skipped, with the reason, where :func:`fifo_refused` refuses."""
    why = fifo_refused(root_for, tools)
    return pytest.mark.skipif(why is not None, reason=str(why))
