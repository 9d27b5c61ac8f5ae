"""``srcsctl wait-ready``: the gate a robot's own services start behind (SR-8.10;
docs/srcsctl.md "Starting behind the supervisor").

Ready means the stop path works, not that the robot may move: the supervisor answers, the VSC
is heard, its key-85 watchdog is on and proven by a proof test (unless the configuration has no
proof test: CAN, HID, ``vsc.prooftest = "off"``), every output is held by the supervisor and
reads back what it was told, and no internal fault stands. The state is not asked for: a
supervisor that is STOPPED until the operator's takeover is ready, and one already in RUN (a
robot service restarted) is ready too.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Final, TextIO

from supervisord.client import ClientError, ConnectError, SupervisorClient

POLL_S: Final = 0.2
"""How often ``status`` is asked for while waiting."""
DEFAULT_TIMEOUT_S: Final = 60.0
"""Longer than a start with a proof test (about 2 s) by far; shorter than systemd's default
start timeout (90 s), so that the gate, not systemd, says what is missing."""

BLOCKING_CAUSES: Final[Mapping[str, str]] = {
    "vsc_link_lost": "the VSC is not heard",
    "transport_fault": "the link to the VSC has failed",
    "vsc_watchdog_off": "the VSC's key-85 watchdog is off",
    "output_fault": "an output does not read back what it was told",
    "internal": "the supervisor has an internal fault",
}
"""Active causes that mean the stop path does not work, and how each is said."""


def missing(status: Mapping[str, Any]) -> list[str]:
    """What keeps the supervisor whose ``status`` reply this is from being ready, in words;
    empty when it is ready."""
    gaps: list[str] = []
    link = status.get("daemon", {}).get("link", {})
    if not link.get("open"):
        gaps.append(f"the link to the VSC is not open ({link.get('description', 'no link')})")
    active = {cause.get("name") for cause in status.get("causes", []) if cause.get("active")}
    gaps += [text for name, text in BLOCKING_CAUSES.items() if name in active]
    proof = status.get("prooftest") or {}
    if proof.get("policy", "off") != "off" and proof.get("phase") != "passed":
        gaps.append(f"the proof test of the VSC's watchdog has not passed ({proof.get('phase')})")
    not_held = status.get("daemon", {}).get("outputs_not_acquired", [])
    if not_held:
        gaps.append(f"outputs not held by the supervisor: {', '.join(not_held)}")
    return gaps


def wait_ready(
    path: Path,
    timeout_s: float,
    out: TextIO,
    err: TextIO,
    *,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Ask ``status`` until the supervisor at ``path`` is ready (exit 0) or ``timeout_s``
    passed: then exit 1 naming what is missing, or 3 when no supervisor answered at all. A
    line goes to ``err`` whenever what is missing changes, so a unit's journal shows the
    wait."""
    deadline = clock() + timeout_s
    said: list[str] | None = None
    while True:
        gaps = _gaps(path)
        if gaps is not None and not gaps:
            print(f"wait-ready: ready ({path})", file=out)
            return 0
        if gaps != said and gaps is not None:
            print(f"wait-ready: waiting: {'; '.join(gaps)}", file=err)
        said = gaps
        if clock() >= deadline:
            break
        sleep(POLL_S)
    if said is None:
        print(f"wait-ready: no supervisor answers at {path} (is srcsd running?)", file=err)
        return 3
    print(f"wait-ready: not ready after {timeout_s:g} s: {'; '.join(said)}", file=err)
    return 1


def _gaps(path: Path) -> list[str] | None:
    """What is missing, or ``None`` when no supervisor answers (yet). A socket this user may
    not open raises: waiting would not change that."""
    try:
        with SupervisorClient.connect(path, timeout=2.0) as client:
            return missing(client.status())
    except ConnectError as error:
        if isinstance(error.__cause__, PermissionError):
            raise
        return None
    except ClientError:
        return None
