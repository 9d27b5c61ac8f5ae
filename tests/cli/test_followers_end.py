"""Every follower of ``srcsctl`` ends on Ctrl-C as the others do (SR-8.9): ``decode --can
--follow`` on a live bus and ``log -f``, each started with SIGINT ignored (a script's
background job, where Python installs no handler of its own) and signalled once it runs.

``decode --raw --follow`` and ``decode -`` of a pipe are in tests/protocol/test_decode_interrupt.py,
``watch`` in tests/daemon/test_srcsctl.py."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import can
import pytest

from supervisord.cli import capture
from supervisord.protocol.j1939 import CanId
from tests.protocol.test_decode_capture import BUFFERED, HEARTBEAT, LINE_WAIT_S, read_line
from tests.protocol.test_decode_cli import SRCSCTL

END_WAIT_S = 30.0  # coarse: a follower ends within one wait of its loop


def _ignoring_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell does for a script's `cmd &`


@pytest.mark.usefixtures("private_network")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_following_a_can_bus_ends_on_the_signal_when_started_with_sigint_ignored(
    sig: signal.Signals,
) -> None:
    """SR-8.9: ``decode --can --follow`` on a live bus, started with SIGINT ignored, ends on
    SIGINT or SIGTERM with exit 0 and no traceback once it is decoding."""
    channel = "239.74.163.10"
    with (
        subprocess.Popen(
            [SRCSCTL, "decode", "--can", "--follow", "--interface", "udp_multicast", channel],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=BUFFERED,
            preexec_fn=_ignoring_sigint,  # noqa: PLW1509 - only a signal disposition
        ) as process,
        capture.open_bus("udp_multicast", channel) as vsc,
    ):
        try:
            first, deadline = b"", time.monotonic() + LINE_WAIT_S
            while not first and time.monotonic() < deadline:
                vsc.send(can.Message(arbitration_id=CanId.HEARTBEAT, data=HEARTBEAT))
                first = read_line(process.stdout, timeout=0.5)
            process.send_signal(sig)
            status = process.wait(timeout=END_WAIT_S)
            errors = process.stderr.read() if process.stderr else b""
        finally:
            if process.poll() is None:
                process.kill()
    assert json.loads(first)["type"] == "vsc_heartbeat"
    assert (status, errors) == (0, b"")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_log_follow_ends_on_the_signal_when_started_with_sigint_ignored(
    tmp_path: Path, sig: signal.Signals
) -> None:
    """SR-8.9: ``log -f`` waiting for a record file that is not there yet, started with
    SIGINT ignored, ends on SIGINT or SIGTERM with exit 0 and no traceback once it follows
    (its inotify watch is set)."""
    with subprocess.Popen(
        [SRCSCTL, "log", "--file", str(tmp_path / "stops.jsonl"), "-f"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        preexec_fn=_ignoring_sigint,  # noqa: PLW1509 - only a signal disposition
    ) as process:
        try:
            fds = Path(f"/proc/{process.pid}/fdinfo")
            deadline = time.monotonic() + LINE_WAIT_S
            while not any("inotify wd:" in _read(info) for info in fds.iterdir()):
                assert time.monotonic() < deadline, "never followed"
                time.sleep(0.05)
            process.send_signal(sig)
            status = process.wait(timeout=END_WAIT_S)
            errors = process.stderr.read() if process.stderr else b""
        finally:
            if process.poll() is None:
                process.kill()
    assert (status, errors) == (0, b"")


def _read(info: Path) -> str:
    try:
        return info.read_text()
    except OSError:  # a descriptor closed while we looked
        return ""
