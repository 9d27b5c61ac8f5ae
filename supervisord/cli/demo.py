"""``srcsctl demo``: the supervisor against the simulated VSC, with a live view.

It starts ``srcs-sim`` on a pseudo-terminal and the real ``srcsd`` with ``demo.toml`` (this
module's neighbour) in a private run directory, commissions the simulated VSC through the API
(as an integrator would with ``srcsctl commission``), and shows the remote, the supervisor, the
outputs, the stop record and the remote's LCD, redrawn ten times a second. Keys press the
remote's e-stop, pause, take over and cut the link. Without a terminal (or with ``--auto``) it
plays a short story instead: take over, e-stop, re-arm, cut the link, re-arm, pause, resume.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import termios
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Final, TextIO

from supervisord.api.framing import ApiError
from supervisord.api.pushes import RecordPush
from supervisord.api.status import StateReport
from supervisord.cli.demo_find import CONFIG, PREFIX, RUN
from supervisord.cli.demo_view import demo_record_line, screen
from supervisord.cli.record_text import happening
from supervisord.client import ClientError, SupervisorClient
from supervisord.config import load_config
from supervisord.errors import ConfigError, SrcsError
from supervisord.record.jsonl import StoredRecord, read_records
from supervisord.record.stop import RecordKind, StopRecord, read_written
from supervisord.safety.core import TAKEOVER_DWELL_NS
from supervisord.sim.process import SimError, SimProcess
from supervisord.tooling.children import terminate
from supervisord.vocabulary import Severity, State

# Package data next to this module, so that an installed wheel or the Debian package runs the
# demo without the repository.
DEMO_CONFIG: Final = Path(__file__).resolve().with_name("demo.toml")
FRAME_S: Final = 0.1
TAKEOVER_TRIES: Final = 3
"""The story's takeovers: a refused one is shown with its reason, then tried again."""


class DemoError(SrcsError):
    """The demo could not start or lost one of its processes."""


class Demo:
    """The simulator and the supervisor in ``run_dir``, and the client that watches them."""

    def __init__(self, run_dir: Path, config: Path, out: TextIO, speed: float) -> None:
        self.run_dir = run_dir
        self.out = out
        self.speed = speed
        self.notes: list[str] = []
        self.records: list[StopRecord] = []
        self._seqs: set[int] = set()
        self.status: StateReport | None = None
        (run_dir / RUN).mkdir(parents=True, exist_ok=True)
        self.config = run_dir / CONFIG  # where srcsctl --demo finds it (demo_find)
        shutil.copyfile(config, self.config)
        loaded = load_config(self.config)  # validated before anything starts
        self.socket = loaded.api.socket
        self.record_path = loaded.record.path
        self.hold_s = loaded.safety.rearm_hold_ms / 1000
        self.sim = SimProcess(run_dir / RUN, serial="vsc", eeprom="eeprom.json")
        self.daemon: subprocess.Popen[bytes] | None = None
        self.client: SupervisorClient | None = None
        self._sticks_at: float | None = None

    # -- life cycle --------------------------------------------------------------------

    def start(self) -> None:
        self.note("starting srcs-sim (the VSC and its remote) and srcsd (the supervisor)")
        self.sim.start()
        with (self.run_dir / "srcsd.log").open("ab") as log:
            self.daemon = subprocess.Popen(  # noqa: S603 - our own interpreter and module
                [sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(self.config)],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=log,
            )
        end = time.monotonic() + 15
        while self.client is None:
            self._check_alive()
            with contextlib.suppress(ClientError):
                self.client = SupervisorClient.connect(self.socket, timeout=10)
            if time.monotonic() > end:
                raise DemoError(f"srcsd did not open {self.socket}: see {self.run_dir}/srcsd.log")
            time.sleep(0.05)
        self.client.subscribe("records")
        # The records of the start came before the subscription: read them from the file
        # (each is there before its push, docs/record.md), so the numbers start at #1.
        for item in read_records(self.record_path):
            record = read_written(item.data) if isinstance(item, StoredRecord) else None
            if record is not None:  # its own daemon's: every line is a typed record
                self._add_record(record)
        self.note(f"srcsctl finds this demo: srcsctl --demo status (socket {self.socket})")
        self.refresh()

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        if self.daemon is not None:
            terminate(self.daemon)  # SIGTERM: outputs off, record flushed, exit 0
        self.sim.stop()

    def _check_alive(self) -> None:
        if self.daemon is not None and self.daemon.poll() is not None:
            raise DemoError(
                f"srcsd exited ({self.daemon.returncode}): see {self.run_dir}/srcsd.log"
            )

    # -- what is shown -----------------------------------------------------------------

    def note(self, text: str) -> None:
        self.notes.append(text)

    def refresh(self) -> None:
        """Ask both processes how they are; keep the stop records that were pushed."""
        assert self.client is not None
        self._check_alive()
        self.status = self.client.status().report
        while (push := self.client.next_event(timeout=0)) is not None:
            if isinstance(push, RecordPush):
                self._add_record(push.record)  # the typed record the file's line is
        if self._sticks_at is not None:  # a slow circle on the left stick, while asked
            phase = time.monotonic() - self._sticks_at
            x, y = int(600 * math.cos(phase)), int(600 * math.sin(phase))
            self.sim.control.axes(left_x=x, left_y=y)

    def _active(self) -> set[str]:
        assert self.client is not None
        return set(self.client.status().report.active())

    def _add_record(self, record: StopRecord) -> None:
        if record.seq in self._seqs:
            return  # read from the file and pushed as well
        self._seqs.add(record.seq)
        self.records.append(record)
        self.on_record(record)

    def on_record(self, record: StopRecord) -> None:
        """A re-arm and a refused one are said where the operator looks: in the notes."""
        if record.kind is RecordKind.REARM_REFUSED:
            self.note(happening(record))
        elif record.rearm is not None and record.to_state is State.RUN:
            self.note(f"{happening(record)}: RUN, the outputs are on")

    def view(self, width: int = 0) -> list[str]:
        sim = self.sim.control.state()
        return screen(
            sim,
            self.status,
            self.records,
            self.sim.control.lcd(),
            self.notes,
            reach=f"srcsctl --demo status|watch|log talks to this demo (socket {self.socket})",
            width=width,
            now_ns=time.monotonic_ns(),  # the daemon's clock: CLOCK_MONOTONIC of this machine
            hold_ms=round(self.hold_s * 1000),
        )

    @property
    def state(self) -> State | None:
        return self.status.state if self.status else None

    # -- the remote's controls -----------------------------------------------------------

    def commission(self) -> None:
        assert self.client is not None
        self.note("commissioning the VSC's key-85 watchdog (srcsctl commission)")
        try:
            reply = self.client.commission()
        except ApiError as error:
            self.note(f"commission: {error.code}: {error.message}")
            return
        self.note(f"commissioned: key 85 reads {reply.key85}")

    def toggle_estop(self) -> None:
        if self.sim.control.state().get("remote_estop"):
            self.sim.control.release()
            self.note("remote e-stop released: take over [t] to re-arm")
        else:
            self.sim.control.estop()
            self.note("remote e-stop pressed")

    def pause(self) -> None:
        self.sim.control.pause()
        self.note("remote paused: take over [t] to resume")

    def takeover(self) -> None:
        if str(self.sim.control.state().get("mode_name")).lower() == "operational":
            # Already Operational (e.g. a takeover the supervisor refused as too early): a
            # new takeover starts from Pause, as an operator would do it on the remote, once
            # the supervisor has seen the Pause in VSC heartbeats (20 Hz) spanning the
            # takeover dwell (docs/safety.md, re-arming rule 4).
            self.sim.control.pause()
            end = time.monotonic() + 1.0
            while time.monotonic() < end and "vsc_mode:pause" not in self._active():
                time.sleep(0.02)
            time.sleep(TAKEOVER_DWELL_NS / 1e9 + 0.1)  # the dwell, and one heartbeat more
        self.sim.control.takeover()
        self.note("takeover pressed on the remote: the supervisor decides (see the record)")

    def toggle_link(self) -> None:
        if self.sim.control.state().get("plugged"):
            self.sim.control.unplug()
            self.note("VSC unplugged: the link is cut")
        else:
            self.sim.control.replug()
            self.note(
                "VSC plugged in again: a new start; the supervisor proves the VSC's watchdog "
                "again before a takeover"
            )

    def toggle_sticks(self) -> None:
        if self._sticks_at is None:
            self._sticks_at = time.monotonic()
            self.note("moving the left stick (the VSC zeroes it outside Operational)")
        else:
            self._sticks_at = None
            self.sim.control.axes(left_x=0, left_y=0)
            self.note("sticks back to centre")


# -- the two ways to run it ----------------------------------------------------------------


def run_demo(
    out: TextIO, *, speed: float = 1.0, auto: bool | None = None, config: Path | None = None
) -> int:
    """Run the demo; interactive when stdin and stdout are terminals, unless ``auto``."""
    interactive = sys.stdin.isatty() and out.isatty() if auto is None else not auto
    # SIGTERM (or a closed terminal) ends the demo like Ctrl-C: its simulator and supervisor
    # are stopped and its directory removed, never left running.
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _interrupt)
    with tempfile.TemporaryDirectory(prefix=PREFIX) as run_dir:
        try:
            demo: Demo = (Demo if interactive else StoryDemo)(
                Path(run_dir), config or DEMO_CONFIG, out, speed
            )
        except (ConfigError, OSError) as error:
            print(f"srcsctl demo: {error}", file=sys.stderr)
            return 2
        try:
            demo.start()
            demo.commission()
            return _story(demo) if isinstance(demo, StoryDemo) else _interactive(demo)
        except (SrcsError, OSError) as error:
            print(f"srcsctl demo: {error}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            return 0
        finally:
            demo.close()


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def _raw_terminal() -> Iterator[None]:
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    sys.stdout.write("\x1b[?25l")  # hide the cursor while redrawing
    try:
        yield
    finally:
        # At once, not once the output has drained: a terminal that stopped reading would
        # hold the exit for ever.
        termios.tcsetattr(fd, termios.TCSANOW, saved)
        sys.stdout.write("\x1b[?25h\n")


def _interactive(demo: Demo) -> int:
    actions: dict[str, Callable[[], None]] = {
        "e": demo.toggle_estop,
        "p": demo.pause,
        "t": demo.takeover,
        "l": demo.toggle_link,
        "s": demo.toggle_sticks,
    }
    with _raw_terminal():
        while True:
            demo.refresh()
            width = shutil.get_terminal_size().columns
            demo.out.write("\x1b[H\x1b[2J" + "\n".join(demo.view(width)) + "\n")
            demo.out.flush()
            ready, _, _ = select.select([sys.stdin], [], [], FRAME_S)
            if ready:
                key = os.read(sys.stdin.fileno(), 1).decode(errors="replace").lower()
                if key in ("q", "\x03", "\x04"):
                    return 0
                if key in actions:
                    try:
                        actions[key]()
                    except SimError as refused:  # e.g. a takeover with the sticks off centre
                        demo.note(f"the remote refused: {refused}")


class StoryDemo(Demo):
    """The demo without a terminal: a scripted story, printed line by line."""

    def note(self, text: str) -> None:
        super().note(text)
        print(f"[demo] {text}", file=self.out, flush=True)

    def _active(self) -> set[str]:
        assert self.client is not None
        return set(self.client.status().report.active())

    def on_record(self, record: StopRecord) -> None:
        print(f"  record {demo_record_line(record)}", file=self.out, flush=True)
        super().on_record(record)

    def takeover(self) -> None:
        """A takeover, and its answer: RUN, or a refusal shown with its reason and tried
        again once the stop conditions have settled (SR-4)."""
        for _ in range(TAKEOVER_TRIES):
            seen = len(self.records)
            super().takeover()
            end = time.monotonic() + 3.0
            while time.monotonic() < end:
                self.refresh()
                fresh = self.records[seen:]
                if any(r.kind is RecordKind.REARM_REFUSED for r in fresh):
                    break
                if self._recorded(State.RUN):
                    return
                time.sleep(0.02)
            self.settle()
        raise DemoError(f"the supervisor refused {TAKEOVER_TRIES} takeovers")

    def wait(self, seconds: float) -> None:
        end = time.monotonic() + seconds / self.speed
        while time.monotonic() < end:
            self.refresh()
            time.sleep(0.02)

    def settle(self, limit: float = 10.0) -> None:
        """Wait until no stop condition is active, then for the re-arm hold time (SR-4)."""
        end = time.monotonic() + limit

        def stop_active() -> bool:
            causes = self.status.causes if self.status else ()
            return any(c.active and c.severity is Severity.STOP for c in causes)

        while stop_active():
            if time.monotonic() > end:
                raise DemoError(f"stop conditions stayed active: {self.status}")
            self.wait(0.02)
        end = time.monotonic() + self.hold_s + 0.1
        while time.monotonic() < end:
            self.refresh()
            time.sleep(0.02)

    def _recorded(self, state: State) -> bool:
        """Whether the supervisor is in ``state`` and the record of the change into it is in:
        the status can show a change before its record's push arrives, and the story is told
        in the order it happened (the record, then the next act)."""
        recorded = bool(self.records) and self.records[-1].to_state is state
        return self.state is state and recorded

    def expect(self, state: State, limit: float = 10.0) -> None:
        end = time.monotonic() + limit
        while True:
            self.refresh()
            if self._recorded(state):
                outputs = self.status.outputs if self.status else {}
                levels = ", ".join(f"{k} {'ON' if v else 'off'}" for k, v in outputs.items())
                print(f"  supervisor: {state}; outputs {levels}", file=self.out, flush=True)
                return
            if time.monotonic() > end:
                raise DemoError(f"the supervisor stayed {self.state or '?'}, expected {state}")
            time.sleep(0.02)


def _story(demo: StoryDemo) -> int:
    demo.expect(State.STOPPED)
    demo.settle()
    demo.takeover()
    demo.expect(State.RUN)
    demo.toggle_sticks()
    demo.wait(1.5)
    demo.toggle_estop()
    demo.expect(State.STOPPED)
    demo.toggle_sticks()  # a takeover needs the sticks neutral (the manual's rule)
    demo.wait(0.5)
    demo.toggle_estop()
    demo.settle()
    demo.takeover()
    demo.expect(State.RUN)
    demo.toggle_link()
    demo.expect(State.STOPPED)
    demo.wait(0.5)
    demo.toggle_link()
    demo.settle()
    demo.takeover()
    demo.expect(State.RUN)
    demo.pause()
    demo.wait(1.0)
    demo.settle()
    demo.takeover()
    demo.expect(State.RUN)
    demo.note("done: `srcsctl demo` in a terminal lets you press the keys yourself")
    return 0
