"""``srcsctl demo``: watch VSC traffic decoded live.

A scripted VSC (``supervisord.testkit.traffic.demo_script``) writes its bytes in real time
into a pseudo-terminal; the decoder reads the other end as it would read ``/dev/ttyACM0``
and the view shows what it understood. (The supervisor and the full simulator take this
command over once they exist.)
"""

from __future__ import annotations

import os
import sys
import time
import tty
from typing import IO

from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import FrameDecoder, Rejection
from supervisord.protocol.messages import Joystick, VscHeartbeat
from supervisord.testkit.traffic import demo_script


def _mode_name(heartbeat: VscHeartbeat | None) -> str:
    if heartbeat is None:
        return "-"
    known = VscMode.parse(heartbeat.mode)
    return known.name if known else f"unknown {heartbeat.mode:#04x}"


def render(
    heartbeat: VscHeartbeat | None, joystick: Joystick | None, counts: dict[str, int]
) -> str:
    estop = "-"
    if heartbeat is not None:
        sources = sorted(source.value for source in heartbeat.estop_sources)
        estop = f"E-STOP ({', '.join(sources)})" if heartbeat.estop else "clear"
    sticks = " ".join(
        f"{name}={axis.value if axis.value is not None else 'invalid':>5}"
        for name, axis in zip(Joystick.AXES, joystick.axes if joystick else (), strict=False)
    )
    tallies = " ".join(f"{name}={count}" for name, count in sorted(counts.items()))
    return f"mode {_mode_name(heartbeat):11} e-stop {estop:16} | {sticks} | {tallies}"


def run_demo(out: IO[str], speed: float = 1.0) -> int:
    master, slave = os.openpty()
    tty.setraw(slave)  # as a serial port is opened: no line discipline between the bytes
    decoder = FrameDecoder()
    heartbeat: VscHeartbeat | None = None
    joystick: Joystick | None = None
    counts: dict[str, int] = {}
    start = time.monotonic()
    last_mode = ""
    try:
        for at, data in demo_script():
            delay = start + at / speed - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            os.write(master, data)
            for event in decoder.feed(os.read(slave, 4096) if data else b""):
                name = event.reason.value if isinstance(event, Rejection) else type(event).__name__
                counts[name] = counts.get(name, 0) + 1
                if isinstance(event, VscHeartbeat):
                    heartbeat = event
                elif isinstance(event, Joystick):
                    joystick = event
            line = render(heartbeat, joystick, counts)
            if _mode_name(heartbeat) != last_mode:
                last_mode = _mode_name(heartbeat)
                out.write(f"\r[{at:5.1f} s] {line}\n")
            elif out.isatty():
                out.write(f"\r[{at:5.1f} s] {line}")
            out.flush()
    except KeyboardInterrupt:
        pass
    finally:
        os.close(master)
        os.close(slave)
    out.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(run_demo(sys.stdout))
