"""The daemon's log lines in a real journal: systemd-journald run for a journal namespace of its
own (tests/journald.py), srcsd's stderr connected to its stream
socket the way systemd connects a service's (the stream header of systemd's journald-stream
protocol and ``JOURNAL_STREAM``), and the PRIORITY of each entry read back with journalctl."""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path

from tests.daemon.test_srcsd import CONFIG
from tests.journald import journal_entries

# Beside the private journald (tests/journald.py): srcsd until it has said "cannot open".
RUN_SRCSD = """
"$PYTHON" -m tests.daemon.test_journal_priority "$STDOUT" "$CONFIG" &
daemon=$!
for _ in $(seq 200); do
    journalctl --directory "$JOURNAL" --no-pager -q 2>/dev/null | grep -q "cannot open" && break
    sleep 0.1
done
kill -TERM "$daemon"
wait "$daemon" || true
"""


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
    config = tmp_path / "robot.toml"
    config.write_text(CONFIG)
    entries = journal_entries(RUN_SRCSD, {"CONFIG": str(config)})
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
