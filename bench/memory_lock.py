"""What the memory lock costs and what it locks (SR-9.6): the real srcsd against the simulated
VSC, started with ``[realtime] lock_memory`` ``"on"`` and ``"off"``, as root under
``chrt -R -f 10`` when it can (the unit's scheduling), read from ``/proc/PID/status`` after a
few seconds of the VSC's traffic.

Run: ``.venv/bin/python -m bench.memory_lock [seconds]``. Prints, for each start, ``VmSize``
(the address space), ``VmLck`` (what RLIMIT_MEMLOCK is judged against: the unit's
``LimitMEMLOCK=`` must stay well above it), ``VmRSS`` and ``VmHWM`` (resident: SR-9.4's
budget), the threads and the main thread's stack. docs/performance.md "The memory lock"
records the result.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from supervisord.sim.process import SimProcess
from supervisord.testkit.daemon import MINIMAL_CONFIG, SrcsdProcess

FIELDS = ("VmSize", "VmLck", "VmRSS", "VmHWM")


def _prefix() -> list[str]:
    """``chrt -R -f 10`` when this machine gives it (root, a kernel without an RT budget)."""
    if os.geteuid() != 0:
        return []
    chrt = shutil.which("chrt")
    if chrt is None:
        return []
    probe = subprocess.run(  # noqa: S603 -- util-linux chrt found on PATH
        [chrt, "-R", "-f", "10", "true"], capture_output=True, check=False
    )
    return [chrt, "-R", "-f", "10"] if probe.returncode == 0 else []


def _kb(status: str, field: str) -> int:
    match = re.search(rf"^{field}:\s+(\d+) kB$", status, re.M)
    return int(match.group(1)) if match else -1


def _stack_kb(pid: int) -> int:
    lines = Path(f"/proc/{pid}/smaps").read_text().splitlines()
    for at, line in enumerate(lines):
        if line.endswith("[stack]"):
            return int(lines[at + 1].split()[1])
    return -1


def measure(mode: str, seconds: float) -> dict[str, int]:
    """One start with ``lock_memory = mode``, read after ``seconds``."""
    with tempfile.TemporaryDirectory() as temp:
        where = Path(temp)
        (where / "robot.toml").write_text(MINIMAL_CONFIG + f'[realtime]\nlock_memory = "{mode}"\n')
        with SimProcess(where, serial="vsc") as sim:
            sim.control.key(85, 1)
            with SrcsdProcess(where / "robot.toml", log=where / "log", prefix=_prefix()) as daemon:
                time.sleep(seconds)
                status = Path(f"/proc/{daemon.pid}/status").read_text()
                found = {field: _kb(status, field) for field in FIELDS}
                found["threads"] = len(os.listdir(f"/proc/{daemon.pid}/task"))
                found["stack"] = _stack_kb(daemon.pid)
    return found


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 5.0
    prefix = " ".join(Path(p).name if "/" in p else p for p in _prefix()) or "no chrt"
    print(f"srcsd after {seconds:g} s of the VSC's traffic; {prefix}")
    for mode in ("on", "off"):
        found = measure(mode, seconds)
        kib = ", ".join(f"{field} {found[field] / 1024:.1f} MiB" for field in FIELDS)
        print(
            f"lock_memory = {mode:3}: {kib}; {found['threads']} threads, stack {found['stack']} KiB"
        )


if __name__ == "__main__":
    main()
