"""The demo's live view: pure functions from what the simulator and the supervisor report to
lines of text (``srcsctl demo``).

Top first, what the operator needs: the one thing to do next (:func:`next_step`), the latest
notes (a refused takeover and its reason among them), how to reach this demo with
``srcsctl``; then the remote, the supervisor, the record and the LCD. Each line is cut to the
terminal's width, so that a redraw never wraps: the notes and the causes are folded onto
more lines (they carry the reasons), the rest is cut (``srcsctl --demo log`` has each record
in full).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from typing import Any, Final

from supervisord.api.status import StateReport
from supervisord.cli.record_text import MARK_MEANS, mark, record_line
from supervisord.cli.times import clock_of
from supervisord.record.stop import StopRecord
from supervisord.vocabulary import CauseKind, Severity, State

KEYS: Final = (
    "keys: [t] take over  [e] remote e-stop on/off  [p] pause  [l] cut/restore the link  "
    "[s] move the sticks  [q] quit"
)
AXES: Final = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")
RECORDS_SHOWN: Final = 6
NOTES_SHOWN: Final = 4
WAITING: Final[Mapping[CauseKind, str]] = {
    CauseKind.VSC_WATCHDOG_UNTESTED: "the supervisor is proving the VSC's watchdog (about 1 s)",
    CauseKind.VSC_WATCHDOG_OFF: "the supervisor is reading the VSC's watchdog setting (key 85)",
    CauseKind.VSC_LINK_LOST: "the VSC's heartbeats are not coming in yet",
    CauseKind.TRANSPORT_FAULT: "the link to the VSC is not open yet",
    CauseKind.STARTUP: "the supervisor is starting",
}
"""Stop conditions that clear by themselves, and what the operator is waiting for."""


def next_step(
    sim: Mapping[str, Any],
    status: StateReport | None,
    *,
    now_ns: int | None = None,
    hold_ms: int = 0,
) -> str:
    """The one thing to do now, or what is being waited for. ``now_ns`` is the monotonic
    clock the daemon stamps its causes with (one machine, one clock) and ``hold_ms`` the
    re-arm hold: a takeover before every stop condition has been clear that long is refused
    (SR-4), so until then the step is to wait."""
    if status is None:
        return "wait: the supervisor is not answering yet"
    if not sim.get("plugged"):
        return "the link is cut: press [l] to restore it"
    if sim.get("remote_estop"):
        return "the remote's e-stop is pressed: press [e] to release it"
    state = status.state
    if state is State.RUN:
        return "RUN, the outputs are on: try [e] e-stop, [p] pause or [l] cut the link"
    if state is State.HOLD:
        return "HOLD (motion off, power on): press [t] to take over and resume"
    causes = status.causes
    active = [c for c in causes if c.active and c.severity is Severity.STOP]
    if active:
        waited = [c.kind for c in active if isinstance(c.kind, CauseKind) and c.kind in WAITING]
        why = WAITING[waited[0]] if waited else None
        return f"wait: {why or ', '.join(str(c.name) for c in active) + ' still active'}"
    cleared = [c.cleared_ns for c in causes if c.latched and c.cleared_ns is not None]
    if now_ns is not None and cleared and now_ns < max(cleared) + hold_ms * 1_000_000:
        return f"wait: the stop conditions must stay clear for {hold_ms} ms (the re-arm hold)"
    return "press [t] to take over: the supervisor goes to RUN and the outputs come on"


def screen(
    sim: Mapping[str, Any],
    status: StateReport | None,
    records: Sequence[StopRecord],
    lcd: str,
    notes: Sequence[str],
    *,
    reach: str = "",
    width: int = 0,
    now_ns: int | None = None,
    hold_ms: int = 0,
) -> list[str]:
    """The whole screen, top to bottom; ``reach`` says how ``srcsctl`` finds this demo;
    each line at most ``width`` characters (0: as long as it is); ``now_ns`` and ``hold_ms``
    as :func:`next_step` takes them."""
    lines = ["SRCS safety supervisor - live demo (srcs-sim + srcsd)", ""]
    step = next_step(sim, status, now_ns=now_ns, hold_ms=hold_ms)
    lines += fold(f"NEXT: {step}", width, "      ")
    for note in notes[-NOTES_SHOWN:]:
        lines += fold(f"> {note}", width, "  ")
    lines.append("")
    lines += remote_lines(sim)
    lines.append("")
    lines += [out for line in supervisor_lines(status) for out in fold(line, width, " " * 20)]
    lines.append("")
    lines.append("stop record (newest last; local time):")
    recent = records[-RECORDS_SHOWN:]
    lines += [f"  {demo_record_line(r)}" for r in recent] or ["  (none yet)"]
    lines.append("")
    lines.append("the remote's LCD:")
    lines += [f"  {row}" for row in lcd.splitlines()]
    lines.append("")
    if reach:
        lines.append(reach)
    lines.append(KEYS)
    return [cut(line, width) for line in lines]


def fold(line: str, width: int, indent: str) -> list[str]:
    """``line`` on as many lines of at most ``width`` as it needs, the later ones indented."""
    if width <= 0 or len(line) <= width:
        return [line]
    return textwrap.wrap(line, width, subsequent_indent=indent, break_on_hyphens=False)


def cut(line: str, width: int) -> str:
    """``line`` in at most ``width`` characters (``...`` where it was cut; 0: whole)."""
    if width <= 0 or len(line) <= width:
        return line
    return line[: max(0, width - 3)] + "..."


def remote_lines(sim: Mapping[str, Any]) -> list[str]:
    estop = ", ".join(sim.get("estop_bits") or []) or "none"
    link = "plugged" if sim.get("plugged") else "UNPLUGGED"
    if sim.get("booting"):
        link += " (booting)"
    axes = sim.get("axes") or {}
    sticks = "  ".join(f"{name} {axes.get(name, 0):+4d}" for name in AXES)
    buttons = ", ".join(sim.get("buttons") or []) or "-"
    return [
        f"remote    mode {str(sim.get('mode_name', '?')).upper():12} e-stop bits: {estop}",
        f"          VSC link {link}; key 85 = {sim.get('key85')}",
        f"sticks    {sticks}",
        f"buttons   {buttons}",
    ]


def supervisor_lines(status: StateReport | None) -> list[str]:
    if status is None:
        return ["supervisor  (not answering)"]
    causes = ", ".join(mark(c.name, held=c.held) for c in status.causes) or "none"
    levels = "   ".join(f"{name} {'ON ' if on else 'off'}" for name, on in status.outputs.items())
    lines = [f"supervisor  state {status.state}", f"            causes: {causes}"]
    if any(c.held for c in status.causes):
        lines.append(f"            {MARK_MEANS}")
    return [
        *lines,
        f"outputs     {levels}",
        f"            heartbeat to the VSC: e-stop byte {status.heartbeat_estop}",
    ]


def demo_record_line(record: StopRecord) -> str:
    """A record as ``watch`` shows it: the local time of day, then what happened."""
    return record_line(record, clock_of(record.utc))
