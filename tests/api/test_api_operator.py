"""The operator socket (SR-8.14; docs/safety.md "The client socket cannot shut out a stop",
docs/api.md "The operator socket"): a second listening socket that only root and the
operators' group can reach, outside the client socket's slots and backlog, accepted first,
serving the operator's requests; and ``srcsctl``'s choice between the two sockets."""

from __future__ import annotations

import errno
import grp
import io
import os
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.api.framing import operator_socket_path
from supervisord.api.requests import Estop, Status
from supervisord.api.server import (
    Accepted,
    ApiServer,
    Received,
    ServerConfig,
    ServerError,
    core_event,
)
from supervisord.cli.control import connect, on_either, socket_paths
from supervisord.client import SupervisorClient
from tests.api.test_api_server import NOBODY, Loop, Peer, shared_dir  # noqa: F401 -- a fixture


def fill_backlog(path: Path) -> list[socket.socket]:
    """Connect to ``path`` without anyone accepting until the kernel's backlog is full (the
    next connect fails with ``EAGAIN``): what churning programs do to the client socket."""
    pending: list[socket.socket] = []
    while True:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
        try:
            sock.connect(str(path))
        except BlockingIOError:
            sock.close()
            return pending
        pending.append(sock)


@pytest.fixture
def both(tmp_path: Path) -> Iterator[Loop]:
    """A loop serving ``api.sock`` and ``api-operator.sock``, one ordinary slot, one e-stop
    slot."""
    the_loop = Loop(
        ServerConfig(
            tmp_path / "api.sock",
            operator_path=tmp_path / "api-operator.sock",
            max_clients=1,
            reserved_slots=1,
        )
    )
    yield the_loop
    the_loop.close()


def test_the_operator_is_served_with_every_slot_and_the_client_backlog_taken(
    tmp_path: Path, both: Loop
) -> None:
    """SR-8.14: with the ordinary slot and the e-stop slot held and the client socket's
    backlog full (a connect there fails with EAGAIN, the way churn failed ``srcsctl``), a
    connection on the operator socket is accepted and its status and estop are served, the
    estop as the core's local e-stop."""
    held = [Peer(tmp_path / "api.sock") for _ in range(2)]
    both.until(lambda: len(both.of_type(Accepted)) == 1)
    assert held[1].ask(both, {"op": "status"})["ok"] is True  # the e-stop slot is taken
    pending = fill_backlog(tmp_path / "api.sock")
    try:
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
        with pytest.raises(BlockingIOError):
            probe.connect(str(tmp_path / "api.sock"))
        probe.close()
        operator = Peer(tmp_path / "api-operator.sock")
        assert operator.ask(both, {"op": "status"})["ok"] is True
        assert operator.ask(both, {"op": "estop"})["ok"] is True
        (estop,) = [r for r in both.of_type(Received) if isinstance(r.request, Estop)]
        assert type(core_event(estop, 1)).__name__ == "LocalEstop"
        operator.close()
    finally:
        for sock in pending:
            sock.close()
        for peer in held:
            peer.close()


def test_the_operators_connection_is_accepted_before_the_churn_of_the_same_turn(
    tmp_path: Path, both: Loop
) -> None:
    """SR-8.14: when the client socket and the operator socket both have connections waiting,
    the operator's is accepted first in that turn, whichever listening socket the loop
    hands the server first; and the server names the operator socket as urgent."""
    assert both.server.urgent()  # the loop serves it before every other client descriptor
    churn = [Peer(tmp_path / "api.sock") for _ in range(5)]
    operator = Peer(tmp_path / "api-operator.sock")
    operator.send({"op": "status", "id": "op"})
    both.until(lambda: len(both.of_type(Accepted)) >= 2)
    first = both.of_type(Accepted)[0].client.connection
    both.until(lambda: operator.has(1))
    status = [r for r in both.of_type(Received) if isinstance(r.request, Status)]
    assert status[0].request.id == "op"
    assert status[0].client.connection == first
    for peer in [*churn, operator]:
        peer.close()


def test_the_operator_socket_refuses_a_robot_programs_requests(tmp_path: Path, both: Loop) -> None:
    """SR-8.14: on the operator socket hello, hold, release, subscribe and estop are served,
    heartbeat and command are answered bad_request and never reach the core (a robot
    program's requests belong on the client socket)."""
    operator = Peer(tmp_path / "api-operator.sock")
    try:
        served: tuple[dict[str, object], ...] = (
            {"op": "hello", "name": "srcsctl"},
            {"op": "hold"},
            {"op": "subscribe", "topics": ["state"]},
        )
        for op in served:
            assert operator.ask(both, op)["ok"] is True, op
        robots: tuple[dict[str, object], ...] = (
            {"op": "heartbeat"},
            {"op": "command", "nonzero": False},
        )
        for op in robots:
            reply = operator.ask(both, op)
            assert (reply["ok"], reply["code"]) == (False, "bad_request"), reply
        assert operator.ask(both, {"op": "release", "what": "hold"})["ok"] is True
        ops = [r.request.OP for r in both.of_type(Received)]
        assert "heartbeat" not in ops
        assert "command" not in ops
    finally:
        operator.close()


def test_the_operator_socket_has_e_stop_slots_of_its_own(tmp_path: Path) -> None:
    """SR-8.14, SR-8.17: past operator_max_clients an operator connection takes one of the
    operator socket's own reserved_slots e-stop slots: never reported to the core, served
    ``estop`` (the core's local e-stop) and ``status``, anything else ``too_many_clients``
    and closed; past its slots a connection is refused. The client socket's ordinary slot and
    e-stop slot are not touched."""
    loop = Loop(
        ServerConfig(
            tmp_path / "api.sock",
            operator_path=tmp_path / "op.sock",
            operator_max_clients=2,
            reserved_slots=1,
            max_clients=1,
        )
    )
    try:
        operators = [Peer(tmp_path / "op.sock") for _ in range(2)]
        loop.until(lambda: len(loop.of_type(Accepted)) == 2)
        slot = Peer(tmp_path / "op.sock")
        assert slot.ask(loop, {"op": "status"})["ok"] is True
        assert slot.ask(loop, {"op": "estop"})["ok"] is True
        (estop,) = [r for r in loop.of_type(Received) if isinstance(r.request, Estop)]
        assert type(core_event(estop, 1)).__name__ == "LocalEstop"
        assert len(loop.of_type(Accepted)) == 2  # the slot is no client of the core's
        refused = Peer(tmp_path / "op.sock")  # every slot is taken, by root: no eviction
        (reply,) = refused.read(loop)
        assert reply["code"] == "too_many_clients"
        assert "the operator socket takes at most 2 connections" in reply["error"]
        refused.wait_eof(loop)
        assert slot.ask(loop, {"op": "hello", "name": "nav"})["code"] == "too_many_clients"
        slot.wait_eof(loop)
        client, client_slot = Peer(tmp_path / "api.sock"), Peer(tmp_path / "api.sock")
        assert client.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
        assert client_slot.ask(loop, {"op": "estop"})["ok"] is True
        for peer in [*operators, slot, refused, client, client_slot]:
            peer.close()
    finally:
        loop.close()


def test_the_operator_socket_is_closed_to_the_client_sockets_group(
    shared_dir: Path,  # noqa: F811 -- the fixture of test_api_server
) -> None:
    """SR-8.14: the operator socket is mode 0600 without operator_group and 0660 with it,
    in that group; a program in the client socket's group (nobody in nogroup) connects to
    the client socket but is refused the operator socket. Closing removes both files."""
    nogroup = grp.getgrgid(NOBODY).gr_name
    client, operator = shared_dir / "api.sock", shared_dir / "api-operator.sock"
    server = ApiServer(ServerConfig(client, group=nogroup, operator_path=operator))
    try:
        assert operator.stat().st_mode & 0o777 == 0o600
        assert client.stat().st_gid == NOBODY
        outcome = {}
        for path in (client, operator):
            pid = os.fork()
            if pid == 0:
                code = 3
                try:
                    os.setgroups([])
                    os.setgid(NOBODY)
                    os.setuid(NOBODY)
                    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                        sock.connect(str(path))
                    code = 0
                except PermissionError:
                    code = errno.EACCES
                finally:
                    os._exit(code)
            _, status = os.waitpid(pid, 0)
            outcome[path.name] = os.waitstatus_to_exitcode(status)
        assert outcome == {"api.sock": 0, "api-operator.sock": errno.EACCES}
    finally:
        server.close()
    assert not client.exists()
    assert not operator.exists()
    grouped = ApiServer(ServerConfig(client, operator_path=operator, operator_group=nogroup))
    try:
        info = operator.stat()
        assert (info.st_mode & 0o777, info.st_gid) == (0o660, NOBODY)
    finally:
        grouped.close()


def test_a_start_whose_operator_socket_fails_leaves_no_client_socket(tmp_path: Path) -> None:
    """SR-8.14 with rule 4: an operator socket path that is not a socket fails the start,
    and the client socket already made is removed."""
    (tmp_path / "op.sock").write_text("a file, not a socket")
    with pytest.raises(ServerError, match="is not a socket"):
        ApiServer(ServerConfig(tmp_path / "api.sock", operator_path=tmp_path / "op.sock"))
    assert not (tmp_path / "api.sock").exists()


# -- srcsctl's choice -----------------------------------------------------------------------


def listening(path: Path) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    sock.listen(4)
    return sock


def test_srcsctl_uses_the_operator_socket_when_it_can_and_falls_back(tmp_path: Path) -> None:
    """SR-8.14: srcsctl's connection goes to the operator socket when it is there, and to
    the client socket when it is missing (an older srcsd); ``--socket`` names exactly one
    socket, a config or the default gives the one beside it (``-operator``)."""
    client, operator = tmp_path / "api.sock", tmp_path / "api-operator.sock"
    assert operator_socket_path(client) == operator
    assert socket_paths(None, str(client)) == (client, None)
    with listening(client):
        with listening(operator), connect(client, operator) as to_operator:
            assert to_operator._sock.getpeername() == str(operator)
        operator.unlink()
        with connect(client, operator) as fallback:
            assert fallback._sock.getpeername() == str(client)


def test_srcsctl_falls_back_when_the_operator_socket_is_not_for_this_user(
    shared_dir: Path,  # noqa: F811 -- the fixture of test_api_server
) -> None:
    """SR-8.14: a user outside the operators' group (nobody, refused a 0600 operator socket)
    still reaches the supervisor: srcsctl falls back to the client socket."""
    client, operator = shared_dir / "api.sock", shared_dir / "api-operator.sock"
    with listening(client), listening(operator):
        os.chmod(client, 0o666)  # noqa: S103 -- nobody must reach the client socket
        os.chmod(operator, 0o600)
        pid = os.fork()
        if pid == 0:
            code = 3
            try:
                os.setgroups([])
                os.setgid(NOBODY)
                os.setuid(NOBODY)
                with connect(client, operator, timeout=2.0) as fallback:
                    code = 0 if fallback._sock.getpeername() == str(client) else 1
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0


def test_srcsctl_falls_back_to_the_client_socket_after_the_operator_socket_refuses(
    tmp_path: Path,
) -> None:
    """SR-8.17: an operator socket whose connection and e-stop slot are held by admins (the
    test, root: no admin evicts another) takes srcsctl's connection, then refuses it with
    ``too_many_clients``; srcsctl runs its command again on the client socket, where the
    estop is served as the core's local e-stop, and says on stderr that it fell back."""
    client, operator = tmp_path / "api.sock", tmp_path / "api-operator.sock"
    loop = Loop(
        ServerConfig(client, operator_path=operator, operator_max_clients=1, reserved_slots=1)
    )
    held = [Peer(operator) for _ in range(2)]
    try:
        loop.until(lambda: len(loop.of_type(Accepted)) == 1)
        assert held[1].ask(loop, {"op": "status"})["ok"] is True  # the e-stop slot is taken
        err = io.StringIO()
        done: list[int] = []

        def estop(session: SupervisorClient) -> int:
            session.estop()
            return 0

        thread = threading.Thread(
            target=lambda: done.append(on_either(client, operator, estop, timeout=30.0, err=err))
        )
        thread.start()
        try:
            loop.until(lambda: not thread.is_alive(), turns=100_000)
        finally:
            thread.join()
        assert done == [0]
        assert "the operator socket is full" in err.getvalue()
        (estop_received,) = [r for r in loop.of_type(Received) if isinstance(r.request, Estop)]
        assert type(core_event(estop_received, 1)).__name__ == "LocalEstop"
    finally:
        for peer in held:
            peer.close()
        loop.close()
