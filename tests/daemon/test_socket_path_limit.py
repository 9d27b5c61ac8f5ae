"""The longest socket path the config accepts is one the real ``srcsd`` serves at (SR-8.1,
SR-8.14, SR-11.2): the server binds each socket under a staging name first, two dots and its
process ID longer than the path, so the config's limit leaves room for that name in a Unix
socket address. A check that passed a path the start then could not bind ("AF_UNIX path too
long", exit 1) would leave the robot without a supervisor while systemd restarts it."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from supervisord.api.framing import (
    PID_MAX_DIGITS,
    SOCKET_ADDRESS_MAX_BYTES,
    SOCKET_PATH_MAX_BYTES,
    staging_socket_path,
)
from supervisord.client import SupervisorClient
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import MINIMAL_CONFIG, DaemonError, SrcsdProcess

LARGEST_PID = 10**PID_MAX_DIGITS - 1
"""The largest process ID of ``PID_MAX_DIGITS`` digits, above any Linux ``pid_max``."""


def _at_the_limit(base: Path, name: str) -> Path:
    """A path ``base/DDD…/name`` of exactly ``SOCKET_PATH_MAX_BYTES`` bytes, its directory's
    name padded to the length (and the directory made: srcsd does not make a socket's)."""
    pad = SOCKET_PATH_MAX_BYTES - len(os.fsencode(base / "d" / name)) + 1
    assert pad >= 1, f"the test's directory {base} is too long for a socket path"
    path = base / ("d" * pad) / name
    path.parent.mkdir(exist_ok=True)
    assert len(os.fsencode(path)) == SOCKET_PATH_MAX_BYTES
    return path


def test_the_staging_name_of_a_path_at_the_limit_fits_a_socket_address() -> None:
    """SR-11.2: the name the server binds first, for a path at the limit and the largest
    process ID Linux can give (``pid_max`` is at most 4194304, 7 digits), fits ``sun_path``
    with its NUL; a byte more and it would not."""
    assert int(Path("/proc/sys/kernel/pid_max").read_text()) <= 4194304 < LARGEST_PID
    path = Path("/run/" + "s" * (SOCKET_PATH_MAX_BYTES - len("/run/")))
    assert len(os.fsencode(path)) == SOCKET_PATH_MAX_BYTES
    staging = staging_socket_path(path, LARGEST_PID)
    assert staging == Path(f"/run/.{path.name}.{LARGEST_PID}")
    assert len(os.fsencode(staging)) == SOCKET_ADDRESS_MAX_BYTES
    longer = staging_socket_path(Path(f"{path}s"), LARGEST_PID)
    assert len(os.fsencode(longer)) == SOCKET_ADDRESS_MAX_BYTES + 1


def test_the_daemon_serves_at_sockets_of_the_longest_path_the_config_accepts(
    tmp_path: Path,
) -> None:
    """SR-8.1, SR-8.14, SR-11.2: with ``api.socket`` and ``api.operator_socket`` each exactly
    ``SOCKET_PATH_MAX_BYTES`` long, the real daemon starts, answers ``status`` on both and
    leaves no staging name behind; SIGTERM stops it cleanly."""
    socket = _at_the_limit(tmp_path, "api.sock")
    operator = _at_the_limit(tmp_path, "opr.sock")
    config = tmp_path / "robot.toml"
    config.write_text(
        MINIMAL_CONFIG.replace('socket = "api.sock"\n', f"socket = {json.dumps(str(socket))}\n")
        + f"operator_socket = {json.dumps(str(operator))}\n"
    )
    log = tmp_path / "srcsd.log"
    with PtyPort(tmp_path / "vsc"):
        daemon = SrcsdProcess(config, log=log)
        try:
            daemon.start()
        except DaemonError as e:
            pytest.fail(f"{e}: {log.read_text()}")
        with daemon:
            assert daemon.socket == socket
            for path in (socket, operator):
                with SupervisorClient.connect(path) as client:
                    assert client.status().json()["state"] == "STOPPED"
            assert sorted(p.name for p in socket.parent.iterdir()) == ["api.sock", "opr.sock"]
    assert daemon.exit_status == 0, log.read_text()
    assert "Traceback" not in log.read_text()
