"""The daemon's threads are made one way (SR-9.7, SR-9.8): :func:`supervisord.threads.start`
names each for the kernel and leaves real time in it. The real daemon's threads under
SCHED_FIFO: tests/daemon/test_realtime_start.py."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from supervisord import threads

PACKAGE = Path(__file__).resolve().parent.parent / "supervisord"

NOT_SRCSD = {
    "supervisord/threads.py": "the one maker",
    "supervisord/cli/exporter.py": "srcs-exporter, a process of its own at ordinary priority",
}
"""Files that may start a thread without :func:`threads.start`, and why."""
NOT_SRCSD_DIRS = ("supervisord/testkit/", "supervisord/ros2/", "supervisord/sim/")
"""The test kit, the ROS 2 bridge and the simulator: never in srcsd's process."""

MAKES_A_THREAD = re.compile(r"\b(Thread|Timer|ThreadPoolExecutor|start_new_thread)\(")


def test_every_thread_of_the_daemon_is_started_by_threads_start() -> None:
    """SR-9.7, SR-9.8: no module srcsd runs makes a thread of its own: each goes through
    :func:`threads.start`, which names it and leaves real time."""
    root = PACKAGE.parent
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(root).as_posix()
        if name in NOT_SRCSD or name.startswith(NOT_SRCSD_DIRS):
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if MAKES_A_THREAD.search(line) and not line.lstrip().startswith("#"):
                found.append(f"{name}:{number}: {line.strip()}")
    assert found == []


def test_a_started_thread_has_its_name_in_the_kernel() -> None:
    """SR-9.7: the thread's own ``comm``, which a trace shows, is its name."""
    seen: list[str] = []
    done = threading.Event()

    def read() -> None:
        tid = threading.get_native_id()
        seen.append(Path(f"/proc/self/task/{tid}/comm").read_text().strip())
        done.set()

    threads.start(read, "srcsd-probe").join(30)
    assert done.is_set()
    assert seen == ["srcsd-probe"]


def test_a_name_the_kernel_would_cut_is_refused() -> None:
    """SR-9.7: a name longer than 15 bytes would be cut in a trace: refused at the start."""
    with pytest.raises(ValueError, match="longer than 15 bytes"):
        threads.start(lambda: None, "srcsd-a-long-name")


LOWERED = """
import os, threading
from supervisord import threads
seen = []
threads.start(lambda: seen.append(os.sched_getscheduler(0)), "srcsd-probe").join(30)
print(os.sched_getscheduler(0), seen[0])
"""


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root: SCHED_FIFO")
def test_a_started_thread_leaves_real_time_and_its_creator_keeps_it() -> None:
    """SR-9.8: in a SCHED_FIFO process, a thread made by :func:`threads.start` runs
    SCHED_OTHER (``sched_setscheduler`` with pid 0 is the calling thread's), and the thread
    that made it stays FIFO."""
    probe = subprocess.run(
        ["chrt", "-f", "10", sys.executable, "-c", LOWERED],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    if probe.returncode != 0 and "chrt" in probe.stderr:
        pytest.skip(f"no SCHED_FIFO here: {probe.stderr.strip()}")
    assert probe.stdout.split() == [str(os.SCHED_FIFO), str(os.SCHED_OTHER)], probe.stderr
