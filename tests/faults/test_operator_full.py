"""The operator's e-stop gets through whatever the operator socket holds (SR-8.17, SR-8.4;
docs/safety.md "The client socket cannot shut out a stop"): the real ``srcsd`` in RUN against
``srcs-sim``, every connection and every e-stop slot of both its sockets held by idle
programs, and root's ``srcsctl estop`` run as the operator runs it (``--config``: the
operator socket first)."""

from __future__ import annotations

import grp
import os
import select
import socket
import time
from collections.abc import Callable
from pathlib import Path

from supervisord.api.server import DEFAULT_OPERATOR_MAX_CLIENTS, DEFAULT_RESERVED_SLOTS
from supervisord.vocabulary import State
from tests.faults.test_slots import (
    MAX_CLIENTS,
    NOBODY,
    SharedRobot,
    as_nobody,
    end,
    hog,
    shared_dir,  # noqa: F401 -- a fixture
    srcsctl,
)

OPERATOR_HELD = DEFAULT_OPERATOR_MAX_CLIENTS + DEFAULT_RESERVED_SLOTS
"""Every connection of the operator socket and every e-stop slot of its own (docs/api.md)."""
CLIENT_HELD = MAX_CLIENTS + DEFAULT_RESERVED_SLOTS
"""Every ordinary slot and every e-stop slot of the client socket."""
KEEP_S = 0.2
SETTLE_S = 1.5
"""Long enough for each hog to hold what it can: past the 1 s an idle e-stop slot lasts, so
the slots are held by connections the hogs made again (docs/api.md "Limits")."""


class OperatorsRobot(SharedRobot):
    """A :class:`SharedRobot` whose operator socket the group ``nogroup`` may open too
    (``[api] operator_group``): its hostile programs are members of both groups."""

    def config_text(self) -> str:
        nogroup = grp.getgrgid(NOBODY).gr_name
        return super().config_text() + f'operator_group = "{nogroup}"\n'

    @property
    def operator_path(self) -> Path:
        return self.socket_path.with_name("api-operator.sock")


def as_root(work: Callable[[], None]) -> int:
    """Fork a child that stays root (an admin) and runs ``work`` until killed."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            work()
            code = 0
        except BaseException:
            code = 2
        finally:
            os._exit(code)
    return pid


def keep(path: Path, count: int) -> Callable[[], None]:
    """Hold ``count`` connections, each asking ``status`` every :data:`KEEP_S` (so an e-stop
    slot among them is never idle for its 1 s), opening a new one whenever one is closed."""

    def work() -> None:
        held: dict[socket.socket, bytes] = {}
        while True:
            while len(held) < count:
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                try:
                    sock.connect(str(path))
                except OSError:
                    sock.close()
                    time.sleep(0.01)
                    continue
                held[sock] = b""
            for sock in list(held):
                try:
                    sock.sendall(b'{"op":"status"}\n')
                except OSError:
                    del held[sock]
                    sock.close()
            end_at = time.monotonic() + KEEP_S
            while held and (left := end_at - time.monotonic()) > 0:
                ready, _, _ = select.select(list(held), [], [], left)
                for sock in ready:
                    try:
                        data = sock.recv(65536)
                    except OSError:
                        data = b""
                    if not data or b"too_many_clients" in data:
                        del held[sock]
                        sock.close()

    return work


def estop_through(robot: OperatorsRobot, pids: list[int]) -> str:
    """With the programs ``pids`` holding what they hold, root's ``srcsctl estop --config``
    succeeds and the robot is STOPPED by the operator's ``local_estop``, root's; then the
    programs end, the e-stop is released and a takeover runs the robot again."""
    try:
        time.sleep(SETTLE_S)
        status = srcsctl(robot.config_path, "status", where="--config")
        print("srcsctl status with both sockets held:", status.returncode, status.stderr.strip())
        assert robot.status().report.state is State.RUN  # the hogs alone stopped nothing
        t0 = robot.now()
        estop = srcsctl(robot.config_path, "estop", where="--config")
        took = robot.now() - t0
        print(f"srcsctl estop with both sockets held: {took:.2f} s, interpreter start included")
        print("its stderr:", estop.stderr.strip())
        assert estop.returncode == 0, estop.stderr
        assert "estop (local): done; the supervisor is STOPPED" in estop.stdout
        stop = robot.expect_stop("local_estop", t0, took)
        assert stop.record.trigger["caller"]["uid"] == 0
    finally:
        end(pids)
    release = srcsctl(robot.config_path, "release", where="--config")
    assert release.returncode == 0, release.stderr
    robot.recover(stop)
    return estop.stderr


def test_root_estop_gets_through_with_every_slot_of_both_sockets_held_by_a_member(
    shared_dir: Path,  # noqa: F811 -- the fixture
) -> None:
    """SR-8.17: a member of both sockets' groups (nobody in nogroup) holds the operator
    socket's 8 connections and its 4 e-stop slots, and the client socket's 16 and 4, each
    opened again as soon as it is closed. ``srcsctl estop`` as root takes one of the operator
    socket's e-stop slots (an admin's connection evicts a non-admin's) and the robot stops,
    recorded as root's ``local_estop``. Before SR-8.17 the ninth operator connection was
    refused and srcsctl stopped there: exit 1, the robot left in RUN."""
    robot = OperatorsRobot(shared_dir / "robot")
    with robot:
        robot.arm()
        assert robot.operator_path.stat().st_gid == NOBODY
        pids = [
            as_nobody(hog(robot.operator_path, OPERATOR_HELD)),
            as_nobody(hog(robot.socket_path, CLIENT_HELD)),
        ]
        estop_through(robot, pids)


def test_root_estop_falls_back_to_the_client_socket_when_admins_fill_the_operator_socket(
    shared_dir: Path,  # noqa: F811 -- the fixture
) -> None:
    """SR-8.17: admins' programs (root's, a script's stuck ``srcsctl status`` loop) hold the
    operator socket's connections and e-stop slots (each asking ``status``, so none is
    idle), which no admin's connection may evict,
    so the operator socket refuses root's ``srcsctl estop`` (``too_many_clients``); nobody
    holds every slot of the client socket. ``srcsctl estop`` falls back to the client socket
    after that refusal, takes an e-stop slot there from nobody, and the robot stops. Before
    SR-8.17 srcsctl fell back only when the operator socket could not be opened: exit 1."""
    robot = OperatorsRobot(shared_dir / "robot")
    with robot:
        robot.arm()
        pids = [
            as_root(keep(robot.operator_path, OPERATOR_HELD)),
            as_nobody(hog(robot.socket_path, CLIENT_HELD)),
        ]
        said = estop_through(robot, pids)
        assert "the operator socket is full" in said, said
