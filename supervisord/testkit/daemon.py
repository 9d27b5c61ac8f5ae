"""Run the real ``srcsd`` from tests, as a user or systemd would start it.

    with SrcsdProcess(tmp_path / "robot.toml") as daemon:   # waits for the API socket
        ...
    assert daemon.exit_status == 0                         # SIGTERM on leaving: a clean stop

The process is ``sys.executable -m supervisord.cli.srcsd --config FILE``, so it runs from a
virtual environment whether or not the entry point is installed. Leaving the ``with`` block
sends SIGTERM and waits (SR-6: outputs off, record flushed, exit 0); a daemon
that does not stop within the timeout is killed and its status is then negative.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from supervisord.config import load_config
from supervisord.errors import SrcsError
from supervisord.safety.config import CLIENT_TIMEOUT_RANGE_MS, VSC_TIMEOUT_MS
from supervisord.tooling.children import kill, spawn, terminate, wait_started

if TYPE_CHECKING:
    from typing_extensions import Self

MINIMAL_CONFIG = """\
[robot]
name = "test-robot"
[vsc]
transport = "serial"
port = "vsc"
[rearm]
hold_ms = 100
[[outputs]]
name = "drive"
kind = "sim"
path = "drive"
[record]
path = "stops.jsonl"
journal = false
[api]
socket = "api.sock"
"""
"""A robot in one directory: the VSC's pty at ``vsc``, one simulated motion output mirrored
to ``drive``, the record ``stops.jsonl``, the socket ``api.sock``, a 100 ms re-arm hold."""

LONGEST_VSC_TIMEOUT_MS = VSC_TIMEOUT_MS.high
"""``vsc.timeout_ms`` at its largest (SR-2.2: 1000 ms). A test or bench that needs the robot
in RUN for a while, with the VSC (or a client) fed by its own process, takes its deadlines
from that need: on a busy two-core machine such a process is late by a few hundred ms at
times, which at the default 200 ms is a real ``vsc_link_lost`` (the daemon stops, as it
should) and not what the test is about (docs/testing.md "Under load")."""

LONGEST_CLIENT_TIMEOUT_MS = CLIENT_TIMEOUT_RANGE_MS[1]
"""``clients[i].timeout_ms`` at its largest (SR-8: 10 s), for the same reason."""

LASTING_CONFIG = MINIMAL_CONFIG.replace(
    "[vsc]\n", f"[vsc]\ntimeout_ms = {LONGEST_VSC_TIMEOUT_MS}\n", 1
)
"""``MINIMAL_CONFIG`` with the longest VSC timeout: a robot that stays in RUN however late
the process feeding its VSC is, up to a second."""


class DaemonError(SrcsError):
    """``srcsd`` exited early or never opened its API socket."""


class SrcsdProcess:
    """``srcsd --config config``; ``socket`` is the config's ``[api] socket``."""

    def __init__(
        self,
        config: str | Path,
        *,
        env: Mapping[str, str] | None = None,
        log: Path | None = None,
        ready_timeout: float = 15.0,
        prefix: Sequence[str] = (),
    ) -> None:
        self.config = Path(config)
        # A command that execs the daemon in the surroundings a test gives it (``chrt -f 10``,
        # ``prlimit``, ``setpriv``): each execs the next, so the daemon keeps the PID started.
        self.prefix = tuple(prefix)
        self.socket = load_config(self.config).api.socket
        self.env = dict(env) if env is not None else None
        self.log = log
        self.ready_timeout = ready_timeout
        self.process: subprocess.Popen[bytes] | None = None
        self.exit_status: int | None = None

    def start(self, *, serve: Callable[[], object] = lambda: None) -> Self:
        """Start it and wait until its API socket exists; ``serve`` runs while waiting (e.g.
        a test's own VSC peer, which must answer for the daemon to get anywhere)."""
        self.process = spawn(
            [
                *self.prefix,
                sys.executable,
                "-m",
                "supervisord.cli.srcsd",
                "--config",
                str(self.config),
            ],
            self.log,
            self.env,
        )
        started = wait_started(self.process, self.socket.exists, self.ready_timeout, 0.005, serve)
        if started == "exited":
            raise DaemonError(f"srcsd exited with {self.process.returncode}")
        if started == "timeout":
            raise DaemonError(f"srcsd did not open {self.socket} in {self.ready_timeout} s")
        return self

    @property
    def pid(self) -> int:
        assert self.process is not None
        return self.process.pid

    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM, then wait; the exit status (negative: it had to be killed)."""
        assert self.process is not None
        self.exit_status = terminate(self.process, timeout)
        return self.exit_status

    def kill(self) -> None:
        kill(self.process)

    def __enter__(self) -> Self:
        return self if self.process is not None else self.start()

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()
