"""Signals sent to the running ``srcsd`` (docs/install.md "Signals"): every one that would end
the process has a meaning. The real daemon against the real simulator, in RUN with every
output on, so that "off" is something each signal has to do."""

from __future__ import annotations

import contextlib
import errno
import os
import resource
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from supervisord.client import SupervisorClient
from supervisord.daemon import signals
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.tooling.children import kill
from supervisord.vocabulary import Cause, CauseKind, State

# One of each kind signal(7) lists with the default action Term or Core that srcsd stops on,
# and the first and last real-time signal (the rest are the same to the kernel and to us).
STOPPING = (
    signal.SIGHUP,
    signal.SIGINT,
    signal.SIGQUIT,
    signal.SIGUSR1,
    signal.SIGUSR2,
    signal.SIGALRM,
    signal.SIGTERM,
    signal.Signals(16),  # SIGSTKFLT on Linux (the name is Python 3.11)
    signal.SIGVTALRM,
    signal.SIGPROF,
    signal.SIGIO,
    signal.SIGPWR,
    signal.SIGXCPU,  # the soft LimitRTTIME= (SR-6.7)
    signal.SIGRTMIN,
    signal.SIGRTMAX,
)


def test_each_stopping_signal_in_run_stops_as_sigterm_does(tmp_path: Path) -> None:
    """SR-6.6, SR-6.5, SR-7.5: for each signal above, the robot in RUN with every output on,
    a hold asked for just before (its record may still be queued): the signal turns every
    output off, the hold's record is in the file when the process has gone (the record was
    drained), the log names the signal, and the exit status is 0 for SIGTERM and SIGINT,
    128 + N for any other."""
    with Robot(tmp_path) as robot:
        for sig in STOPPING:
            if robot.daemon is None or robot.daemon.poll() is not None:
                robot.start_daemon()
            robot.arm()
            daemon = robot.daemon
            assert daemon is not None
            # Every output on before: its file read back off after the exit is the edge.
            assert all(robot.output_file(name) for name in robot.output_paths)
            t_hold = robot.now()
            with SupervisorClient.connect(robot.socket_path, name="held") as client:
                client.hold()
                daemon.send_signal(sig)
                code = daemon.wait(WAIT_S)
            what = f"{sig.name}: {robot.log()}"
            assert code == signals.exit_status(sig), what
            assert code == (0 if sig in (signal.SIGTERM, signal.SIGINT) else 128 + sig), what
            for name in robot.output_paths:
                assert robot.output_file(name) is False, f"{name} left on after {what}"
            held = Cause(CauseKind.CLIENT_HOLD, "held")
            holds = [r for r in robot.records_since(t_hold) if robot.raised_in(r, held)]
            assert holds, f"the hold's record is not in the file after {what}"
            assert f"{signals.name(sig)}: stopping, every output off" in robot.log(), what
            assert "Traceback" not in robot.log(), f"a traceback: {what}"
        robot.start_daemon()  # for the harness's own end: status, SIGTERM, exit 0


def test_sigpipe_and_sigxfsz_change_nothing(tmp_path: Path) -> None:
    """SR-6.6: SIGPIPE and SIGXFSZ are ignored (each failure they announce is met where it
    happens: a send's EPIPE, a write's EFBIG). Sent to the daemon in RUN, nothing stops,
    no output goes off, and it serves as before."""
    with Robot(tmp_path) as robot:
        robot.arm()
        assert robot.daemon is not None
        for sig in (signal.SIGPIPE, signal.SIGXFSZ):
            robot.daemon.send_signal(sig)
        robot.stays_running(0.5)
        assert robot.daemon.poll() is None


def test_every_signal_that_would_end_srcsd_is_caught_ignored_or_documented(
    tmp_path: Path,
) -> None:
    """SR-6.6: the running daemon's own dispositions (``/proc/PID/status``, as the kernel
    holds them): every signal of this system whose default ends the process is caught, or
    ignored (SIGPIPE, SIGXFSZ), or is one of the few left at the default on purpose (the
    watchdog's SIGABRT, SIGSYS, the faults; SIGXCPU is caught, SR-6.7); none of those is
    caught, and docs/install.md "Signals" names each of them."""
    with Robot(tmp_path) as robot:
        assert robot.daemon is not None
        masks = _signal_masks(robot.daemon.pid)
        caught, ignored = masks["SigCgt"], masks["SigIgn"]
        for sig in signal.valid_signals():
            if sig in signals.NOT_ENDING:
                continue
            name = signals.name(sig)
            if sig in signals.DEFAULT:
                assert sig not in caught, name
                assert sig not in ignored, name
            elif sig in signals.IGNORED:
                assert sig in ignored, name
            else:
                assert sig in caught, f"{name} would end srcsd without its shutdown"
        section = _install_signals_section()
        for left in (*signals.DEFAULT, *signals.IGNORED):
            assert f"`{signals.name(left)}`" in section, signals.name(left)


def _signal_masks(pid: int) -> dict[str, set[int]]:
    masks: dict[str, set[int]] = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, value = line.partition(":")
        if key in ("SigCgt", "SigIgn", "SigBlk"):
            bits = int(value.strip(), 16)
            masks[key] = {n + 1 for n in range(64) if bits >> n & 1}
    return masks


def _install_signals_section() -> str:
    text = (Path(__file__).parents[2] / "docs" / "install.md").read_text()
    return text.split("### Signals", 1)[1].split("\n## ", 1)[0].split("\n### ", 1)[0]


def test_a_signal_during_the_start_ends_it_cleanly(tmp_path: Path) -> None:
    """SR-6.6, docs/install.md "Signals": a stopping signal while ``srcsd`` is still starting
    ends the start with the exit status of a stop on that signal and a log line, not the
    kernel's default. The start is held at a known point without any timing: the config is
    a FIFO, and ``srcsd`` blocks reading it while this test holds the writing end open."""
    fifo = tmp_path / "robot.toml"
    os.mkfifo(fifo)
    log = tmp_path / "srcsd.log"
    with log.open("wb") as out:
        daemon = subprocess.Popen(
            [sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(fifo)],
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=out,
        )
    try:
        # Opening the writing end without blocking succeeds only once srcsd has the FIFO
        # open for reading: from then on it waits in its read for bytes that never come.
        writer = wait_until(lambda: _open_writer(fifo), what="srcsd reading its config")
        try:
            daemon.send_signal(signal.SIGHUP)
            code = daemon.wait(WAIT_S)
        finally:
            os.close(writer)
    finally:
        kill(daemon)
    text = log.read_text()
    assert code == 128 + signal.SIGHUP, text
    assert "SIGHUP: stopping before the start" in text
    assert "Traceback" not in text


def _open_writer(fifo: Path) -> int | None:
    try:
        return os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
    except OSError as error:
        if error.errno != errno.ENXIO:  # ENXIO: no reader yet
            raise
        return None


# ----------------------------------------------------------------------------- SIGXCPU

RTTIME_SOFT_US = 50_000
"""The soft RLIMIT_RTTIME the test gives the running daemon: 50 ms of CPU without blocking,
a twentieth of the unit's 1 s, so that ordinary work (a burst of requests) reaches it."""
RTTIME_HARD_US = 2_000_000
"""The unit's hard limit (units/srcsd@.service ``LimitRTTIME=1s:2s``)."""
FLOODERS = 4
FLOOD_BYTES = 1 << 20
FLOOD_LINE = b'{"op": "none"}\n'
"""Per connection: requests pipelined, about 70 000 of them, far more work than the soft
limit's CPU time (the daemon's stop ends it long before). An op that does not exist: each is
parsed and refused with a short reply, so a test reader held back by a busy machine cannot
overflow the daemon's output buffer (256 KiB) and be disconnected before the limit."""


def _fifo_allowed() -> bool:
    """Root on a kernel that gives a process SCHED_FIFO (CONFIG_RT_GROUP_SCHED may not)."""
    if os.geteuid() != 0:
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    except OSError:
        return False
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return True


def _flood(path: Path, stop: threading.Event) -> None:
    """One connection that pipelines refused requests and reads every reply, until the daemon
    closes it (its exit) or ``stop``."""
    requests = FLOOD_LINE * (FLOOD_BYTES // len(FLOOD_LINE))
    with contextlib.suppress(OSError), socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(str(path))
        sock.settimeout(WAIT_S)

        def drain() -> None:
            with contextlib.suppress(OSError):
                while not stop.is_set() and sock.recv(1 << 16):
                    pass

        reader = threading.Thread(target=drain, daemon=True)
        reader.start()
        sock.sendall(requests)
        reader.join(WAIT_S)


@pytest.mark.skipif(not _fifo_allowed(), reason="needs root and SCHED_FIFO")
def test_the_soft_rttime_limit_is_a_stop_the_daemon_makes(tmp_path: Path) -> None:
    """SR-6.7, SR-7.14: the running srcsd in RUN, its loop put in SCHED_FIFO 10 under a soft
    RLIMIT_RTTIME of 50 ms (the unit's policy, its limit lowered), then ordinary busy work:
    four clients pipeline requests (each refused: no such op) faster than the loop answers,
    so it never blocks.
    At the soft limit the kernel sends SIGXCPU; the loop's handler runs at the end of its turn
    and the daemon stops itself as on SIGTERM: every output off, the log names SIGXCPU, the
    last record is ``shutdown:SIGXCPU``, exit 128 + 24 (systemd restarts it, STOPPED). The
    bound of the real-time spin is the limit itself (and the hard limit, 2 s, behind it)."""
    with Robot(tmp_path) as robot:
        robot.arm()
        daemon = robot.daemon
        assert daemon is not None
        assert all(robot.output_file(name) for name in robot.output_paths)
        resource.prlimit(daemon.pid, resource.RLIMIT_RTTIME, (RTTIME_SOFT_US, RTTIME_HARD_US))
        stop = threading.Event()
        floods = [
            threading.Thread(target=_flood, args=(robot.socket_path, stop), daemon=True)
            for _ in range(FLOODERS)
        ]
        # The loop thread only (its thread id is the process id): the lanes stay as they are.
        os.sched_setscheduler(daemon.pid, os.SCHED_FIFO, os.sched_param(10))
        try:
            for flood in floods:
                flood.start()
            code = daemon.wait(WAIT_S * 2)
        finally:
            stop.set()
            for flood in floods:
                flood.join(WAIT_S)
        what = robot.log()
        assert code == signals.exit_status(signal.SIGXCPU) == 128 + signal.SIGXCPU, what
        for name in robot.output_paths:
            assert robot.output_file(name) is False, f"{name} left on after SIGXCPU: {what}"
        assert "SIGXCPU: stopping, every output off" in what, what
        last = robot.records()[-1]
        assert last.trigger == {"event": "shutdown", "reason": "SIGXCPU"}, (last, what)
        assert (last.from_state, last.to_state) == (State.RUN, State.STOPPED), last
        assert "Traceback" not in what, what
        robot.start_daemon()  # for the harness's own end: status, SIGTERM, exit 0
