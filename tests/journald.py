"""A real systemd-journald for a test: run as a plain process for a journal namespace of its own
(systemd-journald.service(8)), in a private mount namespace whose /run and /var/log are fresh
tmpfs, so it writes nowhere the host can see. The test's shell snippet runs while it does
(``$SOCKET`` is its native socket, ``$STDOUT`` its stream socket, ``$JOURNAL`` the directory
journalctl reads); then journald stops and the entries are read back with journalctl."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

NAMESPACE = "srcstest"
ROOT = Path(__file__).resolve().parents[1]

_AROUND = """
set -eu
mount -t tmpfs tmpfs /run
mount -t tmpfs tmpfs /var/log
"$JOURNALD" {namespace} &
journald=$!
SOCKET=/run/systemd/journal.{namespace}/socket
STDOUT=/run/systemd/journal.{namespace}/stdout
# The sockets and the journal's directory, which journald makes on its own time (seen
# missing on a loaded machine right after the sockets appeared).
for _ in $(seq 100); do
    JOURNAL=$(echo /var/log/journal/*.{namespace})
    [ -S "$SOCKET" ] && [ -S "$STDOUT" ] && [ -d "$JOURNAL" ] && break
    sleep 0.1
done
{body}
kill -TERM "$journald"
wait "$journald" || true
exec journalctl --directory "$JOURNAL" --all -o json --no-pager SYSLOG_IDENTIFIER=srcsd
"""


def journal_entries(body: str, env: dict[str, str] | None = None) -> list[dict[str, object]]:
    """Run the shell snippet ``body`` beside a private journald (``$PYTHON`` is this
    interpreter, the working directory the repository) and return srcsd's entries as
    ``journalctl -o json`` gives them. Skips without root or without journald."""
    journald = shutil.which("systemd-journald") or "/lib/systemd/systemd-journald"
    unshare = shutil.which("unshare")
    if unshare is None or not Path(journald).exists() or shutil.which("journalctl") is None:
        pytest.skip("needs unshare(1), systemd-journald and journalctl")
    script = _AROUND.format(namespace=NAMESPACE, body=body)
    result = subprocess.run(
        [unshare, "--mount", "--propagation", "private", "sh", "-c", script],
        capture_output=True,
        cwd=ROOT,
        env={**os.environ, **(env or {}), "JOURNALD": journald, "PYTHON": sys.executable},
        timeout=90,
        check=False,
    )
    if result.returncode != 0 and b"Operation not permitted" in result.stderr:
        pytest.skip("no permission for a private mount namespace (needs root)")
    assert result.returncode == 0, result.stderr.decode()
    return [json.loads(line) for line in result.stdout.decode().splitlines()]
