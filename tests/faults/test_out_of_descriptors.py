"""Out of descriptors, the loop does not spin (SR-10.4; docs/api.md "Limits"): the real
``srcsd`` in RUN against ``srcs-sim``, run under a descriptor limit of 48 (``prlimit``), and
more clients than descriptors. ``accept`` fails with ``EMFILE`` and leaves each connection in
the backlog, so the listening socket stays readable: before SR-10.4 the loop woke for it at
once, every turn, at 99 % of a core (and under the unit's ``LimitRTTIME`` a spin is a kill
within a second)."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import time
from pathlib import Path

import pytest

from supervisord.testkit.robot import Robot
from supervisord.vocabulary import State
from tests.faults.test_slots import srcsctl

NOFILE = 48
"""The descriptor limit the daemon runs under: the issue's, below what the clients open."""
CLIENTS = 80
"""Connections opened at once: more than the daemon has descriptors (``max_clients`` is
raised to 128, so none is refused for that and every one it accepts is held)."""
MEASURE_S = 3.0
"""Wall time over which the daemon's CPU time is read (from ``/proc/PID/stat``)."""
MOST_CPU = 0.3
"""The share of one core the daemon may use meanwhile: a spin is ~1.0, the daemon in RUN
with nothing to do ~0.02 (docs/performance.md, SR-9.4); far from both on a busy machine."""
PRLIMIT = shutil.which("prlimit")


class FewDescriptorsRobot(Robot):
    """A :class:`Robot` whose daemon runs with at most :data:`NOFILE` descriptors and takes
    128 clients (so descriptors, not ``max_clients``, run out)."""

    def config_text(self) -> str:
        return super().config_text() + "max_clients = 128\n"

    def daemon_command(self) -> list[str]:
        assert PRLIMIT is not None
        return [PRLIMIT, f"--nofile={NOFILE}:{NOFILE}", *super().daemon_command()]


def cpu_seconds(pid: int) -> float:
    """``utime + stime`` of ``pid``, in seconds (proc(5): fields 14 and 15)."""
    stat = Path(f"/proc/{pid}/stat").read_text()
    fields = stat[stat.rindex(")") + 2 :].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(PRLIMIT is None, reason="prlimit (util-linux) lowers the daemon's limit")
def test_more_clients_than_descriptors_neither_spins_the_loop_nor_stops_accepting(
    tmp_path: Path,
) -> None:
    """SR-10.4: with the daemon in RUN under a limit of 48 descriptors, 80 clients connect
    and stay. Over 3 s the daemon uses less than 30 % of a core (a spin is ~99 %), its log
    says the failed accept once, and the robot is still in RUN. Once the clients go, the
    daemon accepts again: ``srcsctl estop`` on the client socket stops the robot, recorded as
    root's ``local_estop``, and after its release a takeover runs the robot again."""
    robot = FewDescriptorsRobot(tmp_path / "robot")
    with robot:
        robot.arm()
        assert robot.daemon is not None
        pid = robot.daemon.pid
        held: list[socket.socket] = []
        try:
            for _ in range(CLIENTS):
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
                sock.connect(str(robot.socket_path))  # the backlog (512) takes every one
                held.append(sock)
            time.sleep(1.0)  # the daemon has accepted what it can and met EMFILE
            open_fds = len(list(Path(f"/proc/{pid}/fd").iterdir()))
            cpu0, wall0 = cpu_seconds(pid), time.monotonic()
            time.sleep(MEASURE_S)
            used = (cpu_seconds(pid) - cpu0) / (time.monotonic() - wall0)
            print(f"srcsd under {NOFILE} descriptors ({open_fds} open), {CLIENTS} clients:")
            print(f"  {used:.1%} of a core over {MEASURE_S:g} s")
            assert open_fds >= NOFILE - 1, f"descriptors did not run out ({open_fds} open)"
            assert used < MOST_CPU, f"the loop spins: {used:.0%} of a core"
            said = robot.log().count("cannot accept API connections")
            assert said == 1, robot.log()
        finally:
            for sock in held:
                with contextlib.suppress(OSError):
                    sock.close()
        assert robot.status().report.state is State.RUN
        t0 = robot.now()
        estop = srcsctl(robot.socket_path, "estop")
        took = robot.now() - t0
        assert estop.returncode == 0, estop.stderr
        stop = robot.expect_stop("local_estop", t0, took)
        assert stop.record.trigger["caller"]["uid"] == 0
        release = srcsctl(robot.socket_path, "release")
        assert release.returncode == 0, release.stderr
        robot.recover(stop)
