"""The real ``srcsd`` process, started as systemd starts it: notifications on a real datagram
socket, a pseudo-terminal VSC, SIGTERM at the end."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from supervisord.protocol.codes import VscMode
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import LASTING_CONFIG, MINIMAL_CONFIG
from tests.daemon.peer import VscPeer

SRCSD = shutil.which("srcsd") or str(Path(__file__).parents[2] / ".venv/bin/srcsd")

CONFIG = MINIMAL_CONFIG
SERVED_CONFIG = LASTING_CONFIG
"""For a daemon whose VSC is a ``VscPeer`` this test process serves: the longest VSC timeout
(SR-2.2), since a busy machine may leave the test process late by hundreds of ms, and a
test that needs RUN (or just a quiet link) to last must not stop on that."""


def notifications(sock: socket.socket) -> list[str]:
    lines = []
    while True:
        try:
            lines += sock.recv(4096).decode().splitlines()
        except BlockingIOError:
            return lines


def wait(peer: VscPeer, done: Callable[[], bool], limit: float = 10.0) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, "timed out"
        peer.serve()
        time.sleep(0.005)


def test_notify_takeover_and_sigterm(tmp_path: Path) -> None:
    """SR-0.2, SR-6.5: READY=1 comes only once the output is off; WATCHDOG=1 keeps coming; a
    takeover runs the output; SIGTERM turns it off, flushes the record and exits 0. The VSC is
    served by this process: the longest VSC timeout (``SERVED_CONFIG``), as RUN must last
    until the SIGTERM."""
    (tmp_path / "robot.toml").write_text(SERVED_CONFIG)
    notify_path = tmp_path / "notify"
    with (
        socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as notify,
        PtyPort(tmp_path / "vsc") as port,
    ):
        notify.bind(str(notify_path))
        notify.setblocking(False)
        env = {**os.environ, "NOTIFY_SOCKET": str(notify_path), "WATCHDOG_USEC": "200000"}
        daemon = subprocess.Popen(
            [SRCSD, "--config", str(tmp_path / "robot.toml")],
            env=env,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            peer = VscPeer(port)
            seen: list[str] = []

            def reading(done: Callable[[], bool]) -> Callable[[], bool]:
                """``done``, reading the notifications meanwhile: the socket queues only a few
                datagrams (net.unix.max_dgram_qlen, 10 by default), and WATCHDOG=1 comes every
                100 ms, so a reader that pauses loses the STATUS lines that follow."""

                def check() -> bool:
                    seen.extend(notifications(notify))
                    return done()

                return check

            wait(peer, reading(lambda: "READY=1" in seen))
            assert (tmp_path / "drive").read_text() == "0\n"
            assert any(line.startswith("STATUS=STOPPED") for line in seen)
            # SR-5.6: the proof test of the VSC's watchdog comes before any RUN.
            record = tmp_path / "stops.jsonl"
            wait(
                peer,
                reading(lambda: record.exists() and '"kind":"prooftest"' in record.read_text()),
            )
            pause = time.monotonic() + 0.3  # clear for longer than the 100 ms re-arm hold
            wait(peer, reading(lambda: time.monotonic() > pause))
            peer.mode = VscMode.OPERATIONAL
            wait(peer, reading(lambda: (tmp_path / "drive").read_text() == "1\n"))
            # The output is set first, the status said after (SR-6.1).
            wait(peer, reading(lambda: "STATUS=RUN" in seen))
            assert seen.count("WATCHDOG=1") >= 2
            daemon.send_signal(signal.SIGTERM)
            assert daemon.wait(timeout=10) == 0
        finally:
            if daemon.poll() is None:
                daemon.kill()
            _, errors = daemon.communicate()
        assert (tmp_path / "drive").read_text() == "0\n"
        assert "STOPPING=1" in notifications(notify)
        records = [json.loads(line) for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
        assert records[0]["to"] == "STOPPED"
        assert records[-2]["to"] == "RUN"
        assert records[-2]["rearm"]["kind"] == "takeover"
        # The exit is a stop of its own, recorded last (SR-7.14).
        assert (records[-1]["from"], records[-1]["to"]) == ("RUN", "STOPPED")
        assert "shutdown:SIGTERM" in [cause["name"] for cause in records[-1]["causes"]]
        assert "Traceback" not in errors


def test_bad_config_refuses_to_start(tmp_path: Path) -> None:
    """A configuration error names file, key and fix, and the daemon exits 78 (EX_CONFIG) without
    starting."""
    bad = tmp_path / "bad.toml"
    bad.write_text(CONFIG.replace("hold_ms = 100", "hold_ms = 5"))
    done = subprocess.run(
        [SRCSD, "--config", str(bad)], capture_output=True, text=True, timeout=30, check=False
    )
    assert done.returncode == 78
    assert str(bad) in done.stderr
    assert "rearm.hold_ms" in done.stderr


def test_a_config_from_a_pipe_is_read_once(tmp_path: Path) -> None:
    """``srcsd --config <(...)``: the configuration is read once, so the mistakes listed are
    the pipe's own (a second read of a pipe finds it empty and would list a missing
    ``robot.name`` instead)."""
    bad = CONFIG.replace("hold_ms = 100", "hold_ms = 5").encode()
    read_end, write_end = os.pipe()
    os.write(write_end, bad)  # a config fits in the pipe's buffer
    os.close(write_end)
    try:
        done = subprocess.run(
            [SRCSD, "--config", f"/dev/fd/{read_end}"],
            pass_fds=(read_end,),
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
    finally:
        os.close(read_end)
    assert done.returncode == 78
    assert "rearm.hold_ms = 5" in done.stderr
    assert "robot.name" not in done.stderr


def run_briefly(config: Path) -> None:
    """Start srcsd with no VSC attached, let it record its start, stop it with SIGTERM."""
    record = config.parent / "stops.jsonl"
    before = record.read_text().count("\n") if record.exists() else 0
    daemon = subprocess.Popen([SRCSD, "--config", str(config)], stderr=subprocess.DEVNULL)
    end = time.monotonic() + 10
    while not (record.exists() and record.read_text().count("\n") > before):
        assert time.monotonic() < end
        time.sleep(0.01)
    daemon.send_signal(signal.SIGTERM)
    assert daemon.wait(timeout=10) == 0


def test_record_continues_across_restarts_and_srcsctl_log_reads_it(tmp_path: Path) -> None:
    """A restarted daemon continues the sequence numbers; srcsctl log lists, filters by cause
    and time, and prints JSON."""
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    run_briefly(config)
    first = (tmp_path / "stops.jsonl").read_text().count("\n")
    run_briefly(config)
    seqs = [json.loads(line)["seq"] for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
    assert seqs == list(range(1, len(seqs) + 1))
    assert len(seqs) > first

    srcsctl = str(Path(SRCSD).with_name("srcsctl"))
    listing = subprocess.run(
        [srcsctl, "log", "--config", str(config)], capture_output=True, text=True, check=True
    )
    lines = listing.stdout.splitlines()
    assert [line.split()[1] for line in lines] == [f"#{seq}" for seq in seqs]
    assert sum("raised startup*" in line for line in lines) == 2  # one startup record per start
    # One marker everywhere (docs/srcsctl.md): * = condition cleared, waiting for a re-arm.
    assert "startup*" in listing.stdout  # a pulse: raised and cleared at once
    assert "transport_fault*" not in listing.stdout  # no VSC: still active
    filtered = subprocess.run(
        [srcsctl, "log", "--file", str(tmp_path / "stops.jsonl"), "--cause", "transport", "--json"],
        capture_output=True,
        text=True,
        check=False,
    )
    # "transport" is not a cause name: a usage error listing them (SR-11.3), not an empty answer
    assert (filtered.returncode, filtered.stdout) == (2, "")
    assert "transport_fault" in filtered.stderr
    by_cause = subprocess.run(
        [
            srcsctl,
            "log",
            "--file",
            str(tmp_path / "stops.jsonl"),
            "--cause",
            "transport_fault",
            "--since",
            "1h",
            "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    objects = [json.loads(line) for line in by_cause.stdout.splitlines()]
    assert objects
    # The records about the cause: those whose changes name it (docs/srcsctl.md "log").
    assert all(any(c["name"] == "transport_fault" for c in o["changes"]) for o in objects)
    future = subprocess.run(
        [srcsctl, "log", "--file", str(tmp_path / "stops.jsonl"), "--since", "2999-01-01"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert future.stdout == "-- No entries --\n"  # as journalctl says it
    bad = subprocess.run(
        [srcsctl, "log", "--file", str(tmp_path / "stops.jsonl"), "--since", "last tuesday"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode == 2
    assert "not a time: 'last tuesday'" in bad.stderr


def test_the_digits_python_converts_are_bounded_whatever_the_environment_says() -> None:
    """SR-10.5: a request's number is converted in time quadratic in its digits; Python's own
    bound of 4,300 keeps one line's cost small, and ``PYTHONINTMAXSTRDIGITS=0`` (no bound)
    in the daemon's environment must not lift it."""
    code = (
        "import sys; from supervisord.cli import srcsd; srcsd.pin_int_digits(); "
        "print(sys.get_int_max_str_digits())"
    )
    env = {**os.environ, "PYTHONINTMAXSTRDIGITS": "0"}
    run = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert run.stdout.strip() == "4300"
