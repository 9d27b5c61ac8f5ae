"""``srcsctl decode`` ends on Ctrl-C and SIGTERM however it was started (SR-8.9).

A script's background job starts with SIGINT ignored, and Python then installs no handler of
its own: a decode reading a pipe that stays open ignored Ctrl-C for ever (a full test run
started that way timed out in ``test_ctrl_c_ends_a_live_pipe_quietly``). Each case here
starts decode with SIGINT ignored, deterministically, and waits for it to be decoding (its
first line out) before the signal.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from supervisord.protocol.framing import encode_frame
from supervisord.protocol.messages import VscHeartbeat
from tests.protocol.test_decode_capture import BUFFERED, LINE_WAIT_S, read_line
from tests.protocol.test_decode_cli import SRCSCTL

END_WAIT_S = 30.0  # coarse: decode ends within one read (a pipe's EINTR, a port's 0.5 s poll)


def _ignoring_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell does for a script's `cmd &`


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["sigint", "sigterm"])
def test_a_live_pipe_ends_on_the_signal_when_started_with_sigint_ignored(
    sig: signal.Signals,
) -> None:
    """SR-8.9: ``decode --can -`` on a pipe that stays open, started with SIGINT ignored,
    ends on SIGINT or SIGTERM with exit 0, no traceback, after the line decoded so far."""
    with subprocess.Popen(
        [SRCSCTL, "decode", "--can", "-"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
        preexec_fn=_ignoring_sigint,  # noqa: PLW1509 - only a signal disposition
    ) as process:
        try:
            assert process.stdin is not None
            process.stdin.write(b"0CFDE801#0400010000000000\n")
            process.stdin.flush()
            first = read_line(process.stdout)
            process.send_signal(sig)
            status = process.wait(timeout=END_WAIT_S)
            errors = process.stderr.read() if process.stderr else b""
        finally:
            if process.poll() is None:
                process.kill()
    assert json.loads(first)["type"] == "vsc_heartbeat"
    assert (status, errors) == (0, b"")


def test_following_a_port_ends_on_ctrl_c_when_started_with_sigint_ignored(
    pty_pair: tuple[int, str],
) -> None:
    """SR-8.9: ``decode --raw --follow PORT``, started with SIGINT ignored, ends on SIGINT
    with exit 0 once it is decoding."""
    master, path = pty_pair
    with subprocess.Popen(
        [SRCSCTL, "decode", "--raw", "--follow", path],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
        preexec_fn=_ignoring_sigint,  # noqa: PLW1509 - only a signal disposition
    ) as process:
        try:
            first, deadline = b"", time.monotonic() + LINE_WAIT_S
            while not first and time.monotonic() < deadline:
                os.write(master, encode_frame(VscHeartbeat(4, 0, 1)))
                first = read_line(process.stdout, timeout=0.5)
            process.send_signal(signal.SIGINT)
            status = process.wait(timeout=END_WAIT_S)
            errors = process.stderr.read() if process.stderr else b""
        finally:
            if process.poll() is None:
                process.kill()
    assert json.loads(first)["type"] == "vsc_heartbeat"
    assert (status, errors) == (0, b"")
