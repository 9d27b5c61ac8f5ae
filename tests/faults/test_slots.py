"""The client socket cannot shut out a stop, nor lend a required client's name (SR-8.4, SR-8.6;
``docs/safety.md`` "The client socket cannot shut out a stop" and "Clients bound to a
user"): the real ``srcsd`` against ``srcs-sim``, with hostile programs that are members of the
socket's group (they run as ``nobody``, in the group ``nogroup`` the socket belongs to)."""

from __future__ import annotations

import contextlib
import grp
import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.record.stop import RecordKind, StopRecord
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until

NOBODY = 65534
MAX_CLIENTS = 16  # api.max_clients default (docs/configuration.md)
CHURNERS = 4
REPO = Path(__file__).parents[2]


class SharedRobot(Robot):
    """A Robot whose socket members of ``nogroup`` may reach (``[api] group``), with its
    required clients bound to root (``[[clients]] user``), as the test runs them."""

    def config_text(self) -> str:
        text = super().config_text()
        for name in self.clients:
            text = text.replace(f'name = "{name}"\n', f'name = "{name}"\nuser = "root"\n')
        return text + f'group = "{grp.getgrgid(NOBODY).gr_name}"\n'


@pytest.fixture
def shared_dir() -> Iterator[Path]:
    """A work directory other users can pass through (pytest's own tmp_path is root's only);
    kept when the test fails, for its logs."""
    folder = Path(tempfile.mkdtemp(prefix="srcs-slots-"))
    os.chmod(folder, 0o711)  # noqa: S103 -- nobody must reach the socket inside
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def as_nobody(work: Callable[[], None], *, idle: bool = True) -> int:
    """Fork a child that becomes nobody (group nogroup, no other groups) and runs ``work``
    until it is killed; returns its pid. (Fork, not exec: the interpreter lives where nobody
    cannot read it.) With ``idle`` false it keeps this process's priority, the operator's
    ``srcsctl``'s (SR-8.14). With ``idle`` the child runs at ``SCHED_IDLE``: on a robot the
    daemon runs SCHED_FIFO, above every program, which the harness cannot give it; a nice
    value alone (10 below the daemon, ``BELOW_THE_DAEMON``) left five programs that connect
    as fast as they can ahead of its accepts on two cores kept busy by ``--stress`` (in the
    one run that tried it; at the daemon's own priority, in the run before it, too; both runs
    raised the whole suite above the kernel's worker threads, which docs/testing.md "Under
    load" since found starves the suite's pseudo-terminals, so that may have been part of
    it). Idle priority also puts them below the operator's ``srcsctl``, which on a robot they
    are not: that case is the operator socket's (SR-8.14; docs/safety.md "The client socket
    cannot shut out a stop")."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            if idle:
                os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
            os.setgroups([])
            os.setgid(NOBODY)
            os.setuid(NOBODY)
            work()
            code = 0
        except BaseException:
            code = 2
        finally:
            os._exit(code)
    return pid


def end(pids: list[int]) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
        with contextlib.suppress(ChildProcessError):
            os.waitpid(pid, 0)


def hog(path: Path, count: int) -> Callable[[], None]:
    """Hold ``count`` idle connections for ever, opening a new one whenever one is closed:
    a program that keeps every ordinary slot (and any e-stop slot it can get) taken."""

    def work() -> None:
        held: list[socket.socket] = []
        while True:
            while len(held) < count:
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                try:
                    sock.connect(str(path))
                except OSError:
                    sock.close()
                    time.sleep(0.01)
                    continue
                held.append(sock)
            ready, _, _ = select.select(held, [], [], 0.05)
            for sock in ready:
                with contextlib.suppress(OSError):
                    sock.recv(4096)  # too_many_clients, or the end: either way, try again
                held.remove(sock)
                sock.close()

    return work


def churn(path: Path) -> Callable[[], None]:
    """Connect and disconnect as fast as possible, ignoring every error."""

    def work() -> None:
        while True:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
            with contextlib.suppress(OSError):
                sock.connect(str(path))
            sock.close()

    return work


def srcsctl(path: Path, *args: str, where: str = "--socket") -> subprocess.CompletedProcess[str]:
    """The real ``srcsctl`` command, as the operator runs it (here as root): ``--socket`` the
    client socket only, ``--config`` the robot's config (the operator socket first)."""
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsctl", *args, where, str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
        check=False,
    )


def test_operator_estop_gets_through_every_slot_held_and_churn(shared_dir: Path) -> None:
    """SR-2.6 ``local_estop``, SR-8 limits: a program in the socket's group holds every ordinary
    slot (16 idle connections, re-opened when closed) while four others connect and
    disconnect as fast as they can. ``srcsctl status`` answers every time, and ``srcsctl
    estop`` succeeds at once: every output goes off and the stop is recorded. Once the
    programs end, the e-stop is released and a takeover runs the robot again."""
    with SharedRobot(shared_dir / "robot") as robot:
        robot.arm()
        path = robot.socket_path
        pids = [as_nobody(hog(path, MAX_CLIENTS))]
        try:
            time.sleep(0.5)  # the hog has taken every ordinary slot
            pids += [as_nobody(churn(path)) for _ in range(CHURNERS)]
            time.sleep(0.5)
            t = robot.now()
            statuses = [srcsctl(path, "status") for _ in range(10)]
            failed = [s.stderr for s in statuses if s.returncode != 0]
            assert not failed, failed
            print(f"10 srcsctl status under churn: {robot.now() - t:.2f} s")
            # Not asserted here: whether the churn alone stopped the robot (it can, on two
            # busy cores, with the code before this change too); printed for the record.
            print("stops raised during the churn:", [r.changes for r in robot.records_since(t)])
            t0 = robot.now()
            estop = srcsctl(path, "estop")
            took = robot.now() - t0
            print(f"srcsctl estop under churn: {took:.2f} s, interpreter start included")
            assert estop.returncode == 0, estop.stderr
            assert "estop (local): done; the supervisor is STOPPED" in estop.stdout
            # Outputs are set before the reply is sent (SR-6): off by the time the
            # command says done. Its run time here is mostly its interpreter starting on two
            # cores the churners keep busy; the daemon's own latency is the benches' job.
            stop = robot.expect_stop("local_estop", t0, took)
            assert stop.record.trigger["caller"]["uid"] == 0
        finally:
            end(pids)
        release = srcsctl(path, "release")
        assert release.returncode == 0, release.stderr
        robot.recover(stop)


def test_operator_gets_through_churn_at_the_operators_own_priority(shared_dir: Path) -> None:
    """SR-8.14: as the test above, but the four churners run at the operator's own priority
    (on a robot, programs need not be below the operator), where a full client backlog
    failed ``srcsctl status`` (1 to 3 of 10): ``srcsctl`` with the robot's config goes
    through the operator socket, which no program of the socket's group can reach, and
    ``status`` answers every time, ``estop`` succeeds at once and is recorded as root's."""
    with SharedRobot(shared_dir / "robot") as robot:
        robot.arm()
        path, config = robot.socket_path, robot.config_path
        operator = path.with_name("api-operator.sock")
        assert operator.stat().st_mode & 0o777 == 0o600  # root and the daemon's user only
        pids = [as_nobody(hog(path, MAX_CLIENTS))]
        try:
            time.sleep(0.5)  # the hog has taken every ordinary slot
            pids += [as_nobody(churn(path), idle=False) for _ in range(CHURNERS)]
            time.sleep(0.5)
            t = robot.now()
            statuses = [srcsctl(config, "status", where="--config") for _ in range(10)]
            failed = [s.stderr for s in statuses if s.returncode != 0]
            assert not failed, failed
            print(
                f"10 srcsctl status under churn at the operator's priority: {robot.now() - t:.2f} s"
            )
            t0 = robot.now()
            estop = srcsctl(config, "estop", where="--config")
            took = robot.now() - t0
            assert estop.returncode == 0, estop.stderr
            assert "estop (local): done; the supervisor is STOPPED" in estop.stdout
            stop = robot.expect_stop("local_estop", t0, took)
            assert stop.record.trigger["caller"]["uid"] == 0
        finally:
            end(pids)
        release = srcsctl(config, "release", where="--config")
        assert release.returncode == 0, release.stderr
        robot.recover(stop)


def say_hello_as(path: Path, name: str, out: int) -> Callable[[], None]:
    """Say hello as ``name``, then send three heartbeats 100 ms apart; write every reply to
    ``out``, then wait to be killed."""

    def work() -> None:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.connect(str(path))
            with sock.makefile("rwb") as stream:
                for request in ({"op": "hello", "name": name}, *[{"op": "heartbeat"}] * 3):
                    stream.write(json.dumps(request).encode() + b"\n")
                    stream.flush()
                    os.write(out, stream.readline())
                    time.sleep(0.1)
            os.close(out)
            time.sleep(3600)

    return work


def test_hello_as_a_bound_client_from_another_user_is_refused_and_recorded(
    shared_dir: Path,
) -> None:
    """SR-8, ``client_lost:NAME``: the required client ``nav`` is bound to root and dies (off at
    once). A program of another user says hello as ``nav`` and sends heartbeats: the hello is
    refused (``not_allowed``) and recorded (kind ``hello_refused``, naming the caller), the
    heartbeats are ``not_hello``, and ``client_lost:nav`` stays active. The real ``nav``
    comes back and a takeover runs the robot again."""
    with SharedRobot(shared_dir / "robot", clients=("nav",)) as robot:
        robot.arm()
        t0 = robot.now()
        robot.client_processes["nav"].kill()
        stop = robot.expect_stop("client_lost:nav", t0, 0.0)
        read_end, write_end = os.pipe()
        pid = as_nobody(say_hello_as(robot.socket_path, "nav", write_end))
        os.close(write_end)
        try:
            with os.fdopen(read_end, "rb") as stream:
                replies: list[dict[str, Any]] = [json.loads(line) for line in stream]
        finally:
            end([pid])
        hello, *beats = replies
        assert (hello["ok"], hello["code"]) == (False, "not_allowed"), hello
        assert [b["code"] for b in beats] == ["not_hello"] * 3, beats
        refused: list[StopRecord] = wait_until(
            lambda: [r for r in robot.records_since(t0) if r.kind is RecordKind.HELLO_REFUSED],
            what="the refused hello's record",
        )
        assert refused[0].trigger["name"] == "nav"
        assert refused[0].trigger["caller"]["uid"] == NOBODY
        assert "client_lost:nav" in robot.active_stops()
        robot.start_clients()
        robot.recover(stop)
