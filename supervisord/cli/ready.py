"""``srcsctl wait-ready``: wait until the supervisor is ready (SR-8.10; what that means is
``supervisord/api/readiness.py``, for integrators docs/srcsctl.md "Starting behind the
supervisor")."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Final, TextIO

from supervisord.api.readiness import (
    DEFAULT_SRCSCTL,
    for_run,
    for_takeover,
    missing,
    takeover_said,
)
from supervisord.api.replies import StatusReply
from supervisord.client import ClientError, ConnectError, SupervisorClient

POLL_S: Final = 0.2
"""How often ``status`` is asked for while waiting."""
DEFAULT_TIMEOUT_S: Final = 60.0
"""Longer than a start with a proof test (about 2 s) by far; shorter than systemd's default
start timeout (90 s), so that the gate, not systemd, says what is missing."""


def wait_ready(
    path: Path,
    timeout_s: float,
    out: TextIO,
    err: TextIO,
    *,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
    rearmable: bool = False,
    srcsctl: str = DEFAULT_SRCSCTL,
) -> int:
    """Ask ``status`` until the supervisor at ``path`` is ready (exit 0) or ``timeout_s``
    passed: then exit 1 naming what is missing, or 3 when no supervisor answered at all. A
    line goes to ``err`` whenever what is missing changes, so a unit's journal shows the
    wait. The ready line says when a takeover will be accepted; with ``rearmable`` it waits
    for that too (SR-8.10: a takeover then is accepted, the operator's act aside). Each part
    missing is said with its fix, a command named as ``srcsctl`` reaches this daemon (SR-8.18)."""
    deadline = clock() + timeout_s
    said: list[str] | None = None
    while True:
        status = _status(path)
        gaps, also = (None, "") if status is None else _judged(status, rearmable, srcsctl)
        if status is not None and gaps is not None and not gaps:
            print(f"wait-ready: ready ({path}){takeover_said(status)}{also}", file=out)
            return 0
        if gaps is not None and [*gaps, also] != said:
            print(f"wait-ready: waiting for: {'; '.join(gaps)}{also}", file=err)
        said = None if gaps is None else [*gaps, also]
        if clock() >= deadline:
            break
        sleep(POLL_S)
    if said is None:
        print(f"wait-ready: no supervisor answers at {path} (is srcsd running?)", file=err)
        return 3
    print(
        f"wait-ready: not ready after {timeout_s:g} s: {'; '.join(said[:-1])}{said[-1]}", file=err
    )
    return 1


def _status(path: Path) -> StatusReply | None:
    """The supervisor's ``status``, or ``None`` when no supervisor answers (yet). A socket
    this user may not open raises: waiting would not change that."""
    try:
        with SupervisorClient.connect(path, timeout=2.0) as client:
            return client.status()
    except ConnectError as error:
        if isinstance(error.__cause__, PermissionError):
            raise
        return None
    except ClientError:
        return None


def _judged(status: StatusReply, rearmable: bool, srcsctl: str) -> tuple[list[str], str]:
    """What is missing for ready (with ``rearmable``, for a takeover to be accepted too), and
    what else RUN still needs said as a tail (SR-8.15: a required client, which the gate does
    not wait for: its service may be behind it)."""
    gaps = missing(status, srcsctl)
    if rearmable:
        gaps += for_takeover(status)
    also = [] if rearmable else for_run(status)  # rearmable: a client in the way is a gap
    return gaps, f"; also missing for RUN, not for ready: {', '.join(also)}" if also else ""
