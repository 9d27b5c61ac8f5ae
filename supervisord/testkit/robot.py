"""Fault injection against the real ``srcsd``: a harness for the fault suite and for
integrators' own tests (``docs/faults.md``).

``Robot`` runs the real daemon as a process against ``srcs-sim`` (``SimProcess``) on a real
pseudo-terminal, or on a python-can ``udp_multicast`` bus for CAN, with simulated outputs that
mirror their level into files. It watches those files with inotify from the moment before the
daemon starts, reads the stop record, and talks to the client API with ``SupervisorClient``::

    with Robot(tmp_path) as robot:
        robot.arm()                                      # takeover: RUN, outputs on
        t0 = robot.now()
        robot.sim.control.fault(drop=1.0, only_types=[0x20])
        stop = robot.expect_stop(CauseKind.VSC_LINK_LOST, t0, deadline_s=robot.vsc_timeout_s)
        assert stop.record.to_state is State.STOPPED     # a typed record (StopRecord)
        robot.sim.control.fault()
        robot.recover(stop)                              # valid re-arm, RUN, status answers

Records are the typed ``StopRecord`` the API's clients read, parsed with the same
``read_record``; states and causes are ``supervisord.vocabulary`` members
(``record_lines`` is the file's JSON as written, for a test of the file's own form).

``expect_stop`` checks the first three promises of every scenario: every output off within
the rule's deadline plus ``ALLOWANCE_S``, the cause raised in a stop record, and (with
``recover``) no output on between the stop and the re-arm record. ``recover`` checks the
fourth: after a valid takeover the robot runs again and ``status`` answers.

The faults the simulator cannot make are made by the rest of the kit: client processes
that are killed, stopped or flood the socket (``clients.ClientProcess``), wall-clock jumps
(``faketime.FakeWallClock``, with Debian's libfaketime), a full disk under the record (a
size-limited tmpfs in a private mount namespace, ``namespaces.in_private_mount``), a private
network namespace for CAN (``namespaces.NetNamespace``). ``watcher.OutputWatcher`` follows
the output files (``inotify``); ``wait.wait_until`` is every "until".

Deadlines are coarse on purpose: this is a functional suite on a shared two-core machine.
The latency the rules ask for (SR-9) is measured by ``bench/``, not here.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Literal, TypeAlias

from supervisord.api.pushes import RecordPush
from supervisord.api.status import LoopStatus
from supervisord.client import ClientError, StatusReply, SupervisorClient
from supervisord.record.jsonl import StoredRecord, read_records
from supervisord.record.stop import RecordKind, StopRecord, read_record
from supervisord.safety.core import TAKEOVER_DWELL_NS
from supervisord.sim.process import SimControl, SimError, SimProcess
from supervisord.testkit.clients import ClientProcess
from supervisord.testkit.faketime import FakeWallClock
from supervisord.testkit.namespaces import NetNamespace, in_private_mount
from supervisord.testkit.wait import WAIT_S, FaultHarnessError, wait_until
from supervisord.testkit.watcher import OutputWatcher
from supervisord.tooling.children import kill, log_tail, terminate
from supervisord.vocabulary import Cause, CauseKind, CauseName, ChangeKind, Severity, State

# Scheduling allowance added to every rule's deadline. The machine has two cores and other
# test runs share it; a Python process can be descheduled for a few hundred milliseconds.
# The rules' own latencies (SR-9) are the benchmarks' job, not this suite's.
ALLOWANCE_S = float(os.environ.get("SRCS_FAULTS_ALLOWANCE_S", "0.75"))
SERIAL_BEAT_S = 0.05  # the VSC heartbeat period on serial (manual table 5: 20 Hz)
CAN_BEAT_S = 0.1  # on CAN (manual table 23: 10 Hz)
HOLD_MS = 100  # the shortest re-arm hold the config allows: quick scenarios


def _priority() -> list[str]:
    """``nice -n -5`` as root, a milder stand-in for the unit's scheduling (SCHED_FIFO 10 in
    units/srcsd@.service, with ``Nice=-5`` only as the fallback when a drop-in turns FIFO
    off): the simulated VSC stands for hardware that is never late. Without it a busy shared
    machine can hold either process back past the 250 ms overrun or the 200 ms link timeout,
    a stop the scenario did not inject. Real-time scheduling is not used here so that a test
    process spinning by mistake cannot starve the machine's other work."""
    nice = shutil.which("nice")
    return [nice, "-n", "-5"] if nice and os.geteuid() == 0 else []


@dataclass(frozen=True)
class OutputDef:
    name: str
    role: Literal["motion", "power"] = "motion"
    stuck_at: Literal["on", "off"] | None = None
    off_delay_ms: int = 0  # a power output's stop category 1 (SR-1.4)


CauseWanted: TypeAlias = "CauseKind | Cause | str"
"""A cause a scenario waits for: a kind (any subject: ``CauseKind.OUTPUT_FAULT``), one cause
(``Cause(CauseKind.OUTPUT_FAULT, "drive")``), or its name as the record writes it."""


def names_cause(name: CauseName, wanted: CauseWanted, prefix: bool = False) -> bool:
    """Whether the cause ``name`` is the one ``wanted`` (with ``prefix``, a text ``wanted``
    matches every name that starts with it)."""
    if isinstance(wanted, CauseKind):
        return name.kind is wanted
    if isinstance(wanted, Cause):
        return name == wanted
    return str(name).startswith(wanted) if prefix else str(name) == wanted


@dataclass
class Stop:
    """A stop the harness saw: the fault injected at ``t_fault``, every output off by
    ``t_off`` (monotonic s), and the stop record (typed, as the API's clients read it) that
    raised ``cause``."""

    cause: CauseName
    t_fault: float
    t_off: float
    record: StopRecord


DEFAULT_OUTPUTS = (OutputDef("drive", "motion"), OutputDef("power", "power"))


@dataclass
class Robot:
    """The real ``srcsd`` against ``srcs-sim``, in ``workdir`` (see the module docstring).

    ``clients``: required client names (``[[clients]]``, 500 ms timeout) run as
    ``ClientProcess``es from ``arm`` on; those also in ``progress_clients`` have ``progress =
    true`` and send a progress value (SR-8.16). ``rearm_hold_ms``: ``rearm.hold_ms``.
    ``record_max_bytes``: ``record.max_bytes``, which also bounds each flight window (SR-7.12).
    ``record_tmpfs_bytes``: put the record directory on
    a tmpfs of that size in a private mount namespace (the full-disk scenario; root only).
    ``clock``: a ``FakeWallClock`` for the daemon. ``extra_vsc`` adds ``[vsc]`` lines,
    ``extra_toml`` sections of its own after the others (e.g. ``[fleet]``)."""

    workdir: Path
    transport: Literal["serial", "can"] = "serial"
    outputs: Sequence[OutputDef] = DEFAULT_OUTPUTS
    clients: Sequence[str] = ()
    progress_clients: Sequence[str] = ()
    rearm_hold_ms: int = HOLD_MS
    record_max_bytes: int = 65536
    record_tmpfs_bytes: int | None = None
    clock: FakeWallClock | None = None
    local_reset: bool = False
    extra_vsc: str = ""
    extra_toml: str = ""
    sim_args: Sequence[str] = ()
    boot_delay: float = 1.0
    seed: int = 0
    sim: SimProcess = field(init=False)
    daemon: subprocess.Popen[bytes] | None = field(init=False, default=None)
    watcher: OutputWatcher | None = field(init=False, default=None)
    netns: NetNamespace | None = field(init=False, default=None)
    client_processes: dict[str, ClientProcess] = field(init=False, default_factory=dict)
    _helpers: list[ClientProcess] = field(init=False, default_factory=list)
    _starts: int = field(init=False, default=0)

    _channels = itertools.count(1)

    def __post_init__(self) -> None:
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.config_path = self.workdir / "robot.toml"
        self.socket_path = self.workdir / "api.sock"
        self.record_dir = self.workdir / "record"
        self.record_dir.mkdir(exist_ok=True)
        self.daemon_log = self.workdir / "srcsd.log"
        self.output_paths = {o.name: self.workdir / "out" / o.name for o in self.outputs}
        (self.workdir / "out").mkdir(exist_ok=True)
        if self.transport == "can":
            # Multicast only inside a network namespace of our own (docs/testing.md
            # "Network"): nothing leaves the machine, no other run hears it. A group of our
            # own per robot on top keeps apart the robots of one run.
            if not NetNamespace.available():
                raise RuntimeError("a CAN robot needs root and iproute2: docs/testing.md")
            self.netns = NetNamespace()
            index = next(self._channels)
            self.channel = f"239.74.{os.getpid() % 200 + 1}.{index % 250 + 1}"
            self.sim = SimProcess(
                self.workdir / "sim",
                can=f"udp_multicast:{self.channel}",
                seed=self.seed,
                boot_delay=self.boot_delay,
                args=self.sim_args,
            )
        else:
            self.channel = ""
            self.sim = SimProcess(
                self.workdir / "sim",
                eeprom="eeprom.json",
                seed=self.seed,
                boot_delay=self.boot_delay,
                args=self.sim_args,
            )

    # ------------------------------------------------------------- life cycle

    @property
    def vsc_timeout_s(self) -> float:
        """The rule's default link timeout (SR-2): 200 ms serial, 300 ms CAN."""
        return 0.3 if self.transport == "can" else 0.2

    @property
    def beat_s(self) -> float:
        """The VSC heartbeat period: a frame-raised stop waits at most this for its frame."""
        return CAN_BEAT_S if self.transport == "can" else SERIAL_BEAT_S

    def config_text(self) -> str:
        lines = ["[robot]", 'name = "fault-robot"', "[vsc]", f'transport = "{self.transport}"']
        if self.transport == "can":
            lines += ['interface = "udp_multicast"', f'channel = "{self.channel}"']
            lines += ["require_watchdog = false"]  # there is no key 85 on CAN (SR-5)
        else:
            assert self.sim.serial_path is not None
            lines += [f'port = "{self.sim.serial_path}"']
        lines += ["reopen_min_ms = 50", "reopen_max_ms = 400"]
        lines += [self.extra_vsc] if self.extra_vsc else []
        lines += ["[rearm]", f"hold_ms = {self.rearm_hold_ms}"]
        lines += ["local_reset = true"] if self.local_reset else []
        for name in self.clients:
            lines += ["[[clients]]", f'name = "{name}"', "timeout_ms = 500"]
            lines += ["progress = true"] if name in self.progress_clients else []
        for output in self.outputs:
            lines += ["[[outputs]]", f'name = "{output.name}"', 'kind = "sim"']
            lines += [f'role = "{output.role}"', f'path = "{self.output_paths[output.name]}"']
            if output.stuck_at is not None:
                lines += [f'stuck_at = "{output.stuck_at}"']
            if output.off_delay_ms:
                lines += [f"off_delay_ms = {output.off_delay_ms}"]
        lines += ["[record]", f'path = "{self.record_dir / "stops.jsonl"}"']
        lines += [f"max_bytes = {self.record_max_bytes}", "keep = 2", "journal = false"]
        lines += ["[api]", f'socket = "{self.socket_path}"']
        lines += [self.extra_toml] if self.extra_toml else []
        return "\n".join(lines) + "\n"

    def start(self) -> Robot:
        """The simulator (with its watchdog key 85 commissioned on serial), the watcher, then
        the daemon; returns once the daemon's API socket answers."""
        self.sim.command = [*_priority(), *self.sim.command]
        if self.netns is not None:
            self.netns.create()
            self.sim.command = [*self.netns.prefix(), *self.sim.command]
        self.sim.start()
        if self.transport == "serial":
            self.sim.control.key(85, 1)  # commissioned: the VSC watches our heartbeat (SR-5)
        self.config_path.write_text(self.config_text())
        self.watcher = OutputWatcher(list(self.output_paths.values()))
        self.start_daemon()
        return self

    def daemon_command(self) -> list[str]:
        command = [sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(self.config_path)]
        if self.record_tmpfs_bytes is not None:
            # A tmpfs of its own under the record, seen only by the daemon: a full disk that
            # leaves the rest of the machine alone, and goes away with the process.
            mount = f'mount -t tmpfs -o size={self.record_tmpfs_bytes} srcs-faults "$0"'
            command = in_private_mount(mount, self.record_dir, command)
        command = [*_priority(), *command]
        if self.netns is not None:
            command = [*self.netns.prefix(), *command]
        return command

    def start_daemon(self) -> None:
        assert self.watcher is not None
        with contextlib.suppress(FileNotFoundError):
            self.socket_path.unlink()  # the old socket of a killed daemon: wait for the new
        env = dict(os.environ)
        if self.clock is not None:
            env |= self.clock.env()
        self.watcher.daemon_started()
        with self.daemon_log.open("ab") as log:
            self.daemon = subprocess.Popen(  # noqa: S603 - our own interpreter and module
                self.daemon_command(), stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env
            )
        self._starts += 1
        daemon = self.daemon

        def up() -> bool:
            if daemon.poll() is not None:
                raise FaultHarnessError(f"srcsd exited with {daemon.returncode}: {self.log()}")
            return self.socket_path.exists() and self._answers()

        wait_until(up, 20.0, what="srcsd's API socket")

    def _answers(self) -> bool:
        try:
            self.status()
        except (ClientError, OSError):
            return False
        return True

    def stop_daemon(self) -> int:
        """SIGTERM and the exit status (0 for a clean stop)."""
        return 0 if self.daemon is None else terminate(self.daemon, 15)

    def kill_daemon(self) -> None:
        kill(self.daemon)

    def close(self) -> None:
        """Everything down, in reverse; never raises (a test's own failure shows first)."""
        for process in [*self.client_processes.values(), *self._helpers]:
            process.kill()
        self.stop_daemon()
        with contextlib.suppress(Exception):
            self.sim.stop()
        if self.watcher is not None:
            self.watcher.close()
            self.watcher = None
        if self.netns is not None:
            self.netns.delete()

    def finish(self) -> None:
        """The end of a scenario: the daemon is still up, ``status`` answers, SIGTERM turns
        every output off and exits 0, and its log holds no traceback."""
        assert self.daemon is not None
        assert self.daemon.poll() is None, f"srcsd died: {self.log()}"
        self.status()
        code = self.stop_daemon()
        assert code == 0, f"srcsd exited {code}: {self.log()}"
        for name in self.output_paths:
            if not self._stuck_on(name):
                assert self.output_file(name) is False, f"{name} left on after SIGTERM"
        assert "Traceback" not in self.log(), self.log()

    def __enter__(self) -> Robot:
        try:
            return self.start()
        except BaseException:
            self.close()
            raise

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        try:
            if kind is None:
                self.finish()
        finally:
            self.close()

    # ------------------------------------------------------------- looking

    @staticmethod
    def now() -> float:
        """The monotonic clock, the one the daemon's records carry (``mono_ns``)."""
        return time.monotonic()

    def log(self, tail: int = 4000) -> str:
        return log_tail(self.daemon_log, tail)

    def client(self, timeout: float = 5.0) -> SupervisorClient:
        return SupervisorClient.connect(self.socket_path, timeout=timeout)

    def status(self) -> StatusReply:
        with self.client() as api:
            return api.status()

    def active(self, status: StatusReply | None = None) -> set[str]:
        status = status or self.status()
        return set(status.report.active())

    def active_stops(self, status: StatusReply | None = None) -> set[str]:
        status = status or self.status()
        return {
            c.name.name for c in status.report.causes if c.active and c.severity is Severity.STOP
        }

    def output_file(self, name: str) -> bool | None:
        try:
            return self.output_paths[name].read_text() == "1\n"
        except FileNotFoundError:
            return None

    def _stuck_on(self, name: str) -> bool:
        return any(o.name == name and o.stuck_at == "on" for o in self.outputs)

    @property
    def record_path(self) -> Path:
        """The record file; inside the daemon's private mount namespace when it has one."""
        path = self.record_dir / "stops.jsonl"
        if self.record_tmpfs_bytes is not None and self.daemon is not None:
            return Path(f"/proc/{self.daemon.pid}/root") / path.relative_to("/")
        return path

    def records(self) -> list[StopRecord]:
        """Every record written so far, oldest first, typed: read with the store's own reader
        and the parser the API's clients use (``record.stop.read_record``), so a test holds
        what an integrator's client holds. A line that is no typed record raises
        ``WireError``: the daemon wrote a record its own clients cannot read."""
        return [read_record(line, f"{self.record_path} record") for line in self.record_lines()]

    def records_since(self, t: float) -> list[StopRecord]:
        """The records at or after ``t`` (monotonic s, as ``now``)."""
        t_ns = int(t * 1e9)
        return [r for r in self.records() if r.mono_ns >= t_ns]

    def record_lines(self) -> list[dict[str, Any]]:
        """Every record as the file holds it (JSON objects), oldest first: for a test of the
        file's own form; every other test reads ``records``."""
        return [
            dict(item.data)
            for item in read_records(self.record_path)
            if isinstance(item, StoredRecord)
        ]

    def refused_takeover(self) -> StopRecord:
        """Put the remote in Operational (from Local: what a takeover looks like) and return
        the ``rearm_refused`` record that answers it (SR-4.1, SR-4.2: a stop still active)."""
        t = self.now()
        self.vsc.mode("operational")
        refused: list[StopRecord] = wait_until(
            lambda: [r for r in self.records_since(t) if r.kind is RecordKind.REARM_REFUSED],
            what="the refused takeover",
        )
        return refused[0]

    # ------------------------------------------------------------- arming

    def start_clients(self) -> None:
        for name in self.clients:
            if name not in self.client_processes or not self.client_processes[name].alive():
                extra = ("--progress",) if name in self.progress_clients else ()
                self.client_processes[name] = self.run_client(name, extra=extra)

    def run_client(
        self, name: str, mode: str = "client", period: float = 0.1, extra: Sequence[str] = ()
    ) -> ClientProcess:
        log = self.workdir / f"client-{name or mode}-{len(self._helpers)}.log"
        process = ClientProcess(
            self.socket_path, mode, log, name=name, period=period, extra=extra
        ).start()
        if mode != "client" or name not in self.clients:
            self._helpers.append(process)
        return process

    def arm(self) -> StopRecord:
        """From start to RUN: required clients running, the VSC linked, a takeover; every
        output on. Returns the re-arm record."""
        self.start_clients()
        record = self.rearm()
        for output in self.outputs:
            if output.stuck_at is None:
                assert self.watcher is not None
                self.watcher.wait(output.name, True, 0.0)
        return record

    def rearm(self, attempts: int = 6) -> StopRecord:
        """A valid re-arm by the operator's takeover on the remote (SR-4): wait until
        no stop condition is active and the hold time has passed, make sure the VSC reports a
        mode other than Operational (a pause, if it is in Operational), then take over. Returns
        the record that ended STOPPED. A refused takeover (a condition came back) is tried
        again, up to ``attempts`` times."""
        control = self.sim.control
        for _ in range(attempts):
            wait_until(lambda: not self.active_stops(), what="every stop condition clear (SR-4.1)")
            sim = control.wait_for(
                lambda s: s["linked"] and not s["booting"] and s["estop"] == 0, timeout=WAIT_S
            )
            try:
                if sim["mode_name"] == "operational":
                    control.pause()
                elif sim["mode_name"] == "menu":
                    control.menu()
            except SimError:
                # The VSC left that mode since the snapshot: our stop's e-stop byte reached it
                # and it reverted to Local (manual §6.6), which is what the pause was for.
                continue
            # the hold time, a non-Operational heartbeat seen after the last stop (SR-4.2), and
            # heartbeats in it spanning the takeover dwell (docs/safety.md re-arm rule 4)
            hold_s = self.rearm_hold_ms / 1000
            time.sleep(max(hold_s, TAKEOVER_DWELL_NS / 1e9) + 2 * self.beat_s + 0.05)
            if self.active_stops():
                continue
            t = self.now()
            try:
                control.takeover()
            except SimError:
                continue  # the remote refused (an e-stop bit came back): wait and try again
            found = self._wait_rearm(t)
            if found is not None:
                return found
        raise FaultHarnessError(f"no valid re-arm in {attempts} takeovers; {self.status()}")

    def refused_rearm(self, reason: str, attempts: int = 3) -> StopRecord:
        """The operator's takeover as :meth:`rearm` makes it, where a rule the scenario set up
        refuses it: returns the ``rearm_refused`` record whose reason starts with ``reason``.
        A takeover the harness could not make, or one refused for another reason (a condition
        that came back on a busy machine), is tried again; a takeover that re-arms fails."""
        for _ in range(attempts):
            t = self.now()
            try:
                record = self.rearm(attempts=1)
            except FaultHarnessError:
                found = [
                    r
                    for r in self.records_since(t)
                    if r.kind is RecordKind.REARM_REFUSED and (r.reason or "").startswith(reason)
                ]
                if found:
                    return found[0]
                continue
            raise FaultHarnessError(f"re-armed where {reason!r} should refuse it: {record}")
        raise FaultHarnessError(f"no takeover refused for {reason!r} in {attempts} tries")

    def _wait_rearm(self, since: float) -> StopRecord | None:
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            for record in self.records_since(since - 0.05):
                if record.rearm is not None:
                    return record
                if record.kind is RecordKind.REARM_REFUSED:
                    return None
            time.sleep(0.02)
        return None

    # ------------------------------------------------------------- the four promises

    def expect_stop(
        self, cause: CauseWanted, t_fault: float, deadline_s: float, *, prefix: bool = False
    ) -> Stop:
        """Promise 1 and 2: every output off within ``deadline_s`` + ``ALLOWANCE_S`` of
        ``t_fault``, and a record at or after ``t_fault`` that raises ``cause`` (a kind: any
        of its subjects; text with ``prefix``: any cause starting with it) with the state
        STOPPED after it. The ``Stop`` names the cause the record raised."""
        t_off = self.expect_off(t_fault, deadline_s)
        record = wait_until(
            lambda: self.record_raising(cause, t_fault, prefix),
            what=f"a stop record raising {cause}",
        )
        assert record.to_state is State.STOPPED, record
        raised = self.raised_in(record, cause, prefix)
        assert raised is not None
        return Stop(raised, t_fault, t_off, record)

    def expect_off(self, t_fault: float, deadline_s: float) -> float:
        """Every output that was on at ``t_fault`` seen off within ``deadline_s`` +
        ``ALLOWANCE_S``; the time the last one was seen off."""
        assert self.watcher is not None
        t_off = t_fault
        limit = deadline_s + ALLOWANCE_S
        for name in self.output_paths:
            if self._stuck_on(name) or self.watcher.level_at(name, t_fault) is not True:
                continue  # off already when the fault came (a hold, or never switched on)
            level = self.watcher.wait(name, False, t_fault, timeout=limit + WAIT_S)
            took = level.t - t_fault
            assert took <= limit, (
                f"{name} off {took * 1000:.0f} ms after the fault; the rule allows "
                f"{deadline_s * 1000:.0f} ms (+{ALLOWANCE_S * 1000:.0f} ms scheduling)"
            )
            t_off = max(t_off, level.t)
        return t_off

    def record_raising(
        self, cause: CauseWanted, since: float, prefix: bool = False
    ) -> StopRecord | None:
        """The first record at or after ``since`` that raises ``cause``, if any."""
        for record in self.records_since(since):
            if self.raised_in(record, cause, prefix) is not None:
                return record
        return None

    @staticmethod
    def raised_in(record: StopRecord, cause: CauseWanted, prefix: bool = False) -> CauseName | None:
        """The cause ``record`` raises that is ``cause``, if it raises one."""
        for change in record.changes or ():
            if change.change is ChangeKind.RAISED and names_cause(change.name, cause, prefix):
                return change.name
        return None

    def recover(self, stop: Stop) -> StopRecord:
        """Promise 3 and 4: a valid re-arm (a takeover after the fault was cleared by the
        test), no output on between the stop and that re-arm record, every record between
        them STOPPED, then RUN with every output on and ``status`` answering."""
        rearm = self.rearm()
        self.assert_nothing_on(stop.t_fault, rearm)
        self.assert_serving(rearm)
        return rearm

    def assert_nothing_on(self, t_stop: float, rearm: StopRecord) -> None:
        """No output on between the stop and the re-arm (SR-1, SR-4): the watcher
        saw no "on" in that time, and the daemon never left STOPPED in its records."""
        assert self.watcher is not None
        t_rearm = rearm.mono_ns / 1e9
        stops = [n for n in self.output_paths if not self._stuck_on(n)]
        ons = [(n, lv) for n, lv in self.watcher.ons_between(t_stop, t_rearm) if n in stops]
        # An "on" seen just after the re-arm record may be the re-arm's own; one seen before
        # it is not.
        early = [(n, lv) for n, lv in ons if lv.t < t_rearm]
        assert not early, f"output on before a valid re-arm: {early}"
        between = [r for r in self.records_since(t_stop) if r.mono_ns < rearm.mono_ns]
        assert all(r.to_state is State.STOPPED for r in between), between
        for name in stops:
            first_on = self.watcher.first(name, True, t_stop)
            if first_on is not None:
                assert first_on.t >= t_rearm, (name, first_on, t_rearm)

    def assert_serving(self, rearm: StopRecord | None = None) -> StatusReply:
        """Alive and serving: the process runs, ``status`` answers RUN (or HOLD for a power
        output only), and every healthy output is on in the files and in the status."""
        assert self.daemon is not None
        assert self.daemon.poll() is None, self.log()
        assert self.watcher is not None
        after = rearm.mono_ns / 1e9 - 0.05 if rearm else 0.0
        for output in self.outputs:
            if output.stuck_at is None:
                self.watcher.wait(output.name, True, after)
        status = self.status()
        assert status.report.state is State.RUN, status
        assert all(status.report.outputs.values()), status
        return status

    # ------------------------------------------------------------- helpers for scenarios

    @property
    def vsc(self) -> SimControl:
        """The simulated VSC and remote (``docs/simulator.md``)."""
        return self.sim.control

    def healthy_outputs(self) -> list[str]:
        return [o.name for o in self.outputs if o.stuck_at is None]

    def stays_running(self, seconds: float) -> None:
        """For ``seconds``: no record leaves RUN, no output goes off, and the state is RUN at
        the end: a fault that must not stop the robot did not."""
        assert self.watcher is not None
        t = self.now()
        time.sleep(seconds)
        left = [r for r in self.records_since(t) if r.to_state is not State.RUN]
        assert not left, f"the robot left RUN: {left}"
        for name in self.healthy_outputs():
            off = self.watcher.first(name, False, t)
            assert off is None, f"{name} went off at +{(off.t - t) * 1000:.0f} ms"
        assert self.status().report.state is State.RUN

    def remote_estop_unrecorded(self, subscriber: SupervisorClient) -> Stop:
        """``remote_estop`` when the record file may not take the record (a full disk): the
        stop record is taken from the ``records`` pushes ``subscriber`` subscribed to."""
        t = self.now()
        self.vsc.estop()
        t_off = self.expect_off(t, self.beat_s)
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end:
            push = subscriber.next_event(timeout=0.5)
            if not isinstance(push, RecordPush) or push.record.mono_ns < t * 1e9:
                continue
            record = push.record
            changes = record.changes or ()
            if any(
                c.name.kind is CauseKind.VSC_ESTOP and c.change is ChangeKind.RAISED
                for c in changes
            ):
                assert record.to_state is State.STOPPED, record
                return Stop(Cause(CauseKind.VSC_ESTOP), t, t_off, record)
        raise FaultHarnessError("no stop record raising vsc_estop was pushed")

    def remote_estop(self) -> Stop:
        """The operator's e-stop button on the remote: the stop the VSC reports in its next
        heartbeat (SR-2.1 ``vsc_estop``), at once. The button stays pressed."""
        t = self.now()
        self.vsc.estop()
        return self.expect_stop("vsc_estop", t, self.beat_s)

    def wait_state(self, state: State, timeout: float = WAIT_S) -> StatusReply:
        """The status once the daemon is in ``state``."""
        found = wait_until(
            lambda: (s := self.status()).report.state is state and s,
            timeout,
            what=f"state {state}",
        )
        assert isinstance(found, StatusReply)
        return found

    def counters(self) -> LoopStatus:
        """The daemon loop's own counters (``status``'s ``daemon``, docs/api.md)."""
        return self.status().daemon.loop

    def fill_record_disk(self) -> int:
        """Fill the record's tmpfs up to the last byte; the bytes written."""
        assert self.record_tmpfs_bytes is not None
        assert self.daemon is not None
        filler = Path(f"/proc/{self.daemon.pid}/root") / self.record_dir.relative_to("/")
        written = 0
        fd = os.open(filler / "filler", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            for size in (65536, 4096, 1):  # whole pages first, then the last bytes
                with contextlib.suppress(OSError):
                    while True:
                        written += os.write(fd, b"\0" * size)
        finally:
            os.close(fd)
        return written

    def free_record_disk(self) -> None:
        assert self.daemon is not None
        filler = Path(f"/proc/{self.daemon.pid}/root") / self.record_dir.relative_to("/")
        (filler / "filler").unlink()
