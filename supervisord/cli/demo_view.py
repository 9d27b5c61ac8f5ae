"""The demo's live view: pure functions from what the simulator and the supervisor report to
lines of text (``srcsctl demo``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

KEYS: Final = (
    "keys: [e] remote e-stop on/off  [p] pause  [t] take over  [l] cut/restore the link  "
    "[s] move the sticks  [q] quit"
)
AXES: Final = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")


def screen(
    sim: Mapping[str, Any],
    status: Mapping[str, Any] | None,
    records: Sequence[Mapping[str, Any]],
    lcd: str,
    notes: Sequence[str],
) -> list[str]:
    """The whole screen, top to bottom."""
    lines = ["SRCS safety supervisor - live demo (srcs-sim + srcsd)", ""]
    lines += remote_lines(sim)
    lines.append("")
    lines += supervisor_lines(status)
    lines.append("")
    lines.append("stop record (newest last):")
    lines += [f"  {record_line(r)}" for r in records[-6:]] or ["  (none yet)"]
    lines.append("")
    lines.append("the remote's LCD:")
    lines += [f"  {row}" for row in lcd.splitlines()]
    lines.append("")
    lines += [f"> {note}" for note in notes[-4:]]
    lines.append(KEYS)
    return lines


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


def supervisor_lines(status: Mapping[str, Any] | None) -> list[str]:
    if status is None:
        return ["supervisor  (not answering)"]
    causes = status.get("causes") or []
    shown = [
        f"{c['name']}{'' if c.get('active') else ' (cleared, latched)'}"
        for c in causes
        if isinstance(c, Mapping)
    ]
    outputs = status.get("outputs") or {}
    levels = "   ".join(f"{name} {'ON ' if on else 'off'}" for name, on in outputs.items())
    return [
        f"supervisor  state {status.get('state')}",
        f"            causes: {', '.join(shown) or 'none'}",
        f"outputs     {levels}",
        f"            heartbeat to the VSC: e-stop byte {status.get('heartbeat_estop')}",
    ]


def record_line(record: Mapping[str, Any]) -> str:
    utc = str(record.get("utc", ""))[11:23]
    names = ", ".join(c.get("name", "?") for c in record.get("causes") or []) or "none"
    reason = f" - {record['reason']}" if record.get("reason") else ""
    return (
        f"#{record.get('seq')} {utc} {record.get('from')} -> {record.get('to')} "
        f"[{record.get('kind')}] causes: {names}{reason}"
    )
