"""The daemon's log lines in a real journal: systemd-journald run for a journal namespace of its
own (as tests/record/test_record_journal.py does), srcsd's stderr connected to its stream
socket the way systemd connects a service's (the stream header of systemd's journald-stream
protocol and ``JOURNAL_STREAM``), and the PRIORITY of each entry read back with journalctl."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.daemon.test_srcsd import CONFIG

# In a private mount namespace whose /run and /var/log are fresh tmpfs: nothing the host sees.
JOURNALD_CHILD = textwrap.dedent(
    """
    set -eu
    mount -t tmpfs tmpfs /run
    mount -t tmpfs tmpfs /var/log
    "$JOURNALD" srcstest &
    journald=$!
    stdout=/run/systemd/journal.srcstest/stdout
    for _ in $(seq 100); do [ -S "$stdout" ] && break; sleep 0.1; done
    "$PYTHON" -m tests.daemon.test_journal_priority "$stdout" "$CONFIG" &
    daemon=$!
    for _ in $(seq 200); do
        journalctl --directory /var/log/journal/*.srcstest --no-pager -q 2>/dev/null |
            grep -q "cannot open" && break
        sleep 0.1
    done
    kill -TERM "$daemon"
    wait "$daemon" || true
    kill -TERM "$journald"
    wait "$journald" || true
    exec journalctl --directory /var/log/journal/*.srcstest --all -o json --no-pager \\
        SYSLOG_IDENTIFIER=srcsd
    """
)


def _exec_srcsd_on_the_stream(stream_path: str, config: str) -> None:
    """In the journald child: connect to the stream socket as systemd does for a service (a
    header naming the identifier, default priority 6 and level prefixes on), then exec srcsd
    with stdout and stderr on it and ``JOURNAL_STREAM`` naming it (systemd.exec(5))."""
    stream = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stream.connect(stream_path)
    # identifier, unit id, priority, level prefix, forward to syslog, kmsg, console
    stream.sendall(b"srcsd\n\n6\n1\n0\n0\n0\n")
    stat = os.fstat(stream.fileno())
    os.dup2(stream.fileno(), 1)
    os.dup2(stream.fileno(), 2)
    env = {**os.environ, "JOURNAL_STREAM": f"{stat.st_dev}:{stat.st_ino}"}
    srcsd = str(Path(sys.executable).with_name("srcsd"))
    os.execve(srcsd, [srcsd, "--config", config], env)  # noqa: S606 - our own program


def test_a_real_journal_files_each_line_at_its_priority(tmp_path: Path) -> None:
    """SR-7.6: srcsd's start line reaches a real journald at PRIORITY 6 (info) and its "cannot
    open" line at 4 (warning), so ``journalctl -p warning`` shows the warnings; no entry keeps
    the ``<N>`` prefix in its MESSAGE."""
    journald = shutil.which("systemd-journald") or "/lib/systemd/systemd-journald"
    unshare = shutil.which("unshare")
    if unshare is None or not Path(journald).exists() or shutil.which("journalctl") is None:
        pytest.skip("needs unshare(1), systemd-journald and journalctl")
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    root = Path(__file__).resolve().parents[2]
    result = subprocess.run(
        [unshare, "--mount", "--propagation", "private", "sh", "-c", JOURNALD_CHILD],
        capture_output=True,
        cwd=root,
        env={**os.environ, "JOURNALD": journald, "PYTHON": sys.executable, "CONFIG": str(config)},
        timeout=90,
        check=False,
    )
    if result.returncode != 0 and b"Operation not permitted" in result.stderr:
        pytest.skip("no permission for a private mount namespace (needs root)")
    assert result.returncode == 0, result.stderr.decode()
    entries = [json.loads(line) for line in result.stdout.decode().splitlines()]
    by_text = {str(entry["MESSAGE"]): str(entry["PRIORITY"]) for entry in entries}
    starting = [p for text, p in by_text.items() if "robot test-robot" in text]
    warnings = [p for text, p in by_text.items() if "cannot open" in text]
    assert starting == ["6"], by_text
    assert warnings, by_text
    assert set(warnings) == {"4"}, by_text
    assert not [text for text in by_text if text.startswith("<")], by_text
    assert {entry["_TRANSPORT"] for entry in entries} == {"stdout"}


if __name__ == "__main__":  # the journald child's daemon (the test above)
    _exec_srcsd_on_the_stream(sys.argv[1], sys.argv[2])
