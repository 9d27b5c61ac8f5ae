"""``srcs-sim`` as a child of another program: ``SimProcess`` runs it as a real subprocess,
``SimControl`` speaks its control API (``docs/simulator.md``). ``srcsctl demo`` drives the
simulator with them, and so do the tests and integrators' own tests.

    with SimProcess(tmp_path) as sim:          # serial pty at tmp_path / "vsc"
        sim.control.key(85, 1)                 # commission the VSC's watchdog
        start_my_robot(port=sim.serial_path)
        sim.control.wait_for(lambda s: s["user_heartbeat_age"] is not None)
        sim.control.takeover()
        sim.control.estop()

The process is started with ``sys.executable -m supervisord.cli.sim``, so it runs from a
virtual environment whether or not the ``srcs-sim`` entry point is installed. Start-up
waits until the control socket answers; a simulator that exits or never answers raises
``SimError`` with the end of its log.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from supervisord.errors import SrcsError
from supervisord.tooling.children import kill, log_tail, spawn, terminate, wait_started
from supervisord.tooling.polling import poll_until

Reply = dict[str, Any]  # one JSON reply of the control socket


class SimError(SrcsError):
    """The simulator did not start, stopped answering, or refused a request."""


class SimControl:
    """A client of the control socket: one connection, one reply per request.

    ``request`` returns the reply of a request that succeeded and raises ``SimError`` with
    the simulator's error text otherwise; ``call`` returns any reply as it came."""

    def __init__(self, path: str | Path, timeout: float = 5.0) -> None:
        self.path = Path(path)
        self.timeout = timeout
        self._sock: socket.socket | None = None
        self._buffer = b""

    def _connect(self) -> socket.socket:
        if self._sock is None:
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.settimeout(self.timeout)
            try:
                sock.connect(str(self.path))
            except OSError:
                sock.close()
                raise
            self._sock, self._buffer = sock, b""
        return self._sock

    def call(self, cmd: str, **fields: Any) -> Reply:
        """Send ``{"cmd": cmd, **fields}`` and return the reply, ``ok`` true or false."""
        line = json.dumps({"cmd": cmd, **fields}).encode() + b"\n"
        try:
            sock = self._connect()
            sock.sendall(line)
            while b"\n" not in self._buffer:
                chunk = sock.recv(65536)
                if not chunk:
                    raise ConnectionError("the simulator closed the control connection")
                self._buffer += chunk
        except OSError as error:
            self.close()
            raise SimError(f"control socket {self.path}: {error}") from error
        reply, _, self._buffer = self._buffer.partition(b"\n")
        decoded: Reply = json.loads(reply)
        return decoded

    def request(self, cmd: str, **fields: Any) -> Reply:
        reply = self.call(cmd, **fields)
        if not reply.get("ok"):
            raise SimError(str(reply.get("error")))  # the simulator's text names the request
        return reply

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    # -- one method per request (docs/simulator.md) ----------------------------------------

    def state(self) -> Reply:
        return self.request("state")

    def lcd(self) -> str:
        return str(self.request("lcd")["lcd"])

    def estop(self) -> Reply:
        return self.request("estop")

    def release(self) -> Reply:
        return self.request("release")

    def pause(self, reason: str = "button") -> Reply:
        return self.request("pause", reason=reason)

    def takeover(self) -> Reply:
        return self.request("takeover")

    def menu(self) -> Reply:
        return self.request("menu")

    def mode(self, mode: str | int) -> Reply:
        return self.request("mode", mode=mode)

    def power(self, on: bool) -> Reply:
        return self.request("power", on=on)

    def wired_estop(self, active: bool) -> Reply:
        return self.request("wired_estop", active=active)

    def axes(self, **values: int) -> Reply:
        return self.request("axes", **values)

    def buttons(self, *pressed: str) -> Reply:
        return self.request("buttons", pressed=list(pressed))

    def key(self, key: int, value: int | None = None) -> int:
        fields: dict[str, int] = {"key": key} if value is None else {"key": key, "value": value}
        return int(self.request("key", **fields)["value"])

    def unplug(self) -> Reply:
        return self.request("unplug")

    def replug(self) -> Reply:
        return self.request("replug")

    def reboot(self, delay: float | None = None, unplug: bool | None = None) -> Reply:
        fields: dict[str, Any] = {}
        if delay is not None:
            fields["delay"] = delay
        if unplug is not None:
            fields["unplug"] = unplug
        return self.request("reboot", **fields)

    def fault(self, **plan: Any) -> Reply:
        """Set a fault plan (``FaultPlan`` field names); no fields clears it."""
        if not plan:
            return self.request("fault", clear=True)
        return self.request("fault", plan=plan)

    def silence(self, on: bool = True) -> Reply:
        return self.request("silence", on=on)

    def bus_off(self, on: bool = True) -> Reply:
        return self.request("bus_off", on=on)

    def wait_for(
        self, condition: Callable[[Reply], bool], timeout: float = 10.0, poll: float = 0.02
    ) -> Reply:
        """Poll ``state`` until ``condition`` holds; ``SimError`` with the last state if not."""
        held, state = poll_until(self.state, condition, timeout, time.sleep, poll)
        if not held:
            summary = {k: state.get(k) for k in ("mode_name", "estop", "user_heartbeat_age")}
            raise SimError(f"timed out after {timeout} s waiting; state: {summary}")
        return state

    def __enter__(self) -> SimControl:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()


class SimProcess:
    """``srcs-sim`` as a subprocess in ``workdir``.

    ``serial`` is the pty symlink (relative paths are under ``workdir``; default
    ``workdir/vsc``); ``can`` (``"udp_multicast:239.74.163.2"``) serves CAN instead, ``tty``
    the serial protocol on an existing device (``--tty``, e.g. a USB gadget's
    ``/dev/ttyGS0``; ``serial_path`` is then ``None``), ``hid`` HID mode on a HID function's
    device end (``--hid``, e.g. ``/dev/hidg0``). The
    control socket is ``workdir/sim.sock``, the log (stderr) ``workdir/sim.log``.
    ``eeprom`` keeps message control and key 85 across restarts. ``args`` are extra
    command-line arguments (``--newer-firmware``, ``--remote-off``...)."""

    def __init__(
        self,
        workdir: str | Path,
        *,
        serial: str | Path | None = "vsc",
        can: str | None = None,
        tty: str | Path | None = None,
        hid: str | Path | None = None,
        eeprom: str | Path | None = None,
        seed: int = 0,
        boot_delay: float | None = None,
        link_delay: float | None = None,
        args: Sequence[str] = (),
        ready_timeout: float = 15.0,
    ) -> None:
        self.workdir = Path(workdir)
        self.can = can
        self.device = tty or hid  # a device the simulator opens, owned by someone else
        on_pty = can is None and self.device is None
        self.serial_path = self.workdir / (serial or "vsc") if on_pty else None
        self.control_path = self.workdir / "sim.sock"
        self.log_path = self.workdir / "sim.log"
        self.eeprom_path = None if eeprom is None else self.workdir / eeprom
        self.ready_timeout = ready_timeout
        command = [sys.executable, "-m", "supervisord.cli.sim", "--control", str(self.control_path)]
        if can:
            command += ["--can", can]
        elif tty is not None:
            command += ["--tty", str(tty)]
        elif hid is not None:
            command += ["--hid", str(hid)]
        else:
            command += ["--serial", str(self.serial_path)]
        if self.eeprom_path is not None:
            command += ["--eeprom", str(self.eeprom_path)]
        command += ["--seed", str(seed)]
        if boot_delay is not None:
            command += ["--boot-delay", str(boot_delay)]
        if link_delay is not None:
            command += ["--link-delay", str(link_delay)]
        self.command = [*command, *args]
        self.process: subprocess.Popen[bytes] | None = None
        self.control = SimControl(self.control_path)

    def start(self) -> SimProcess:
        """Start it and wait until its control socket answers."""
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.process = spawn(self.command, self.log_path)
        started = wait_started(self.process, self._answers, self.ready_timeout, 0.02)
        if started == "exited":
            raise SimError(f"srcs-sim exited with {self.process.returncode}: {self.log()}")
        if started == "timeout":
            self.kill()
            raise SimError(f"srcs-sim did not answer in {self.ready_timeout} s: {self.log()}")
        return self

    def _answers(self) -> bool:
        if not self.control_path.exists():
            return False
        try:
            self.control.state()
        except SimError:
            return False
        return True

    def log(self, tail: int = 2000) -> str:
        """The end of the simulator's output."""
        return log_tail(self.log_path, tail)

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM, then wait; the exit status (0 for a clean stop)."""
        self.control.close()
        return 0 if self.process is None else terminate(self.process, timeout)

    def kill(self) -> None:
        self.control.close()
        kill(self.process)

    def __enter__(self) -> SimProcess:
        return self.start()

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()
