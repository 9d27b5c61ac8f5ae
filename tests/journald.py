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
exec journalctl --directory "$JOURNAL" --all -o json --no-pager SYSLOG_IDENTIFIER={identifier}
"""


def journal_entries(
    body: str, env: dict[str, str] | None = None, identifier: str = "srcsd"
) -> list[dict[str, object]]:
    """Run the shell snippet ``body`` beside a private journald (``$PYTHON`` is this
    interpreter, the working directory the repository) and return srcsd's entries (those of
    ``identifier``) as ``journalctl -o json`` gives them. Skips without root or without
    journald."""
    journald = shutil.which("systemd-journald") or "/lib/systemd/systemd-journald"
    unshare = shutil.which("unshare")
    if unshare is None or not Path(journald).exists() or shutil.which("journalctl") is None:
        pytest.skip("needs unshare(1), systemd-journald and journalctl")
    script = _AROUND.format(namespace=NAMESPACE, body=body, identifier=identifier)
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


# A robot of a fleet (tests/cli/test_fleet.py): a host name of its own (a private UTS
# namespace), journald's default socket where srcsd's sink looks for it, and srcsd's records
# handed back in journal export format, as systemd-journal-upload sends them to a collector,
# each stop's flight recorder window with them (SYSLOG_IDENTIFIER srcsd-flight, SR-13.12).
# $START_JOURNALD starts (or, for a clock set back, restarts) journald under $CLOCK.
_ROBOT = """
set -eu
mount -t tmpfs tmpfs /run
mount -t tmpfs tmpfs /var/log
hostname "$ROBOT"
start_journald() {{
    $1 "$JOURNALD" {namespace} &
    journald=$!
    for _ in $(seq 100); do
        JOURNAL=$(echo /var/log/journal/*.{namespace})
        [ -S "$SOCKET" ] && [ -d "$JOURNAL" ] && break
        sleep 0.1
    done
}}
stop_journald() {{
    kill -TERM "$journald"
    wait "$journald" || true
    rm -f "$SOCKET"
}}
SOCKET=/run/systemd/journal.{namespace}/socket
mkdir -p /run/systemd/journal
ln -s "$SOCKET" /run/systemd/journal/socket
{body}
stop_journald
exec journalctl --directory "$JOURNAL" --all -o export --no-pager SYSLOG_IDENTIFIER=srcsd \
    SYSLOG_IDENTIFIER=srcsd-flight
"""


def robot_export(robot: str, body: str, env: dict[str, str] | None = None) -> bytes:
    """Run the shell snippet ``body`` as robot ``robot`` (its host name) beside a private
    journald (``start_journald CLOCK`` and ``stop_journald`` in the snippet; srcsd's sink
    finds it at the default socket) and return srcsd's entries in journal export format
    (systemd-journal-upload's wire format). Skips without root or without journald."""
    journald = shutil.which("systemd-journald") or "/lib/systemd/systemd-journald"
    unshare = shutil.which("unshare")
    if unshare is None or not Path(journald).exists() or shutil.which("journalctl") is None:
        pytest.skip("needs unshare(1), systemd-journald and journalctl")
    script = _ROBOT.format(namespace=NAMESPACE, body=body)
    result = subprocess.run(
        [unshare, "--mount", "--uts", "--propagation", "private", "sh", "-c", script],
        capture_output=True,
        cwd=ROOT,
        env={**os.environ, **(env or {}), "JOURNALD": journald, "ROBOT": robot},
        timeout=90,
        check=False,
    )
    if result.returncode != 0 and b"Operation not permitted" in result.stderr:
        pytest.skip("no permission for private mount and UTS namespaces (needs root)")
    assert result.returncode == 0, result.stderr.decode()
    return result.stdout


def collect(export: bytes, journal: Path) -> None:
    """Write ``export`` (journal export format) into the collector's file ``journal``
    (``remote-HOST.journal``) with the real systemd-journal-remote, as it does for each
    upload it takes in."""
    remote = shutil.which("systemd-journal-remote") or "/lib/systemd/systemd-journal-remote"
    if not Path(remote).exists():
        pytest.skip("needs systemd-journal-remote (Debian package systemd-journal-remote)")
    result = subprocess.run(
        [remote, f"--output={journal}", "-"], input=export, capture_output=True, check=False
    )
    assert result.returncode == 0, result.stderr.decode()


def clock_behind(seconds: int) -> str:
    """A command prefix that runs a program with its wall clock ``seconds`` behind (Debian's
    libfaketime; the monotonic clock left alone, as supervisord.testkit.faketime does)."""
    from supervisord.testkit.faketime import libfaketime  # noqa: PLC0415

    library = libfaketime()
    if library is None:
        pytest.skip("needs libfaketime (Debian package faketime)")
    return (
        f"env LD_PRELOAD={library} FAKETIME=-{seconds} DONT_FAKE_MONOTONIC=1 "
        "FAKETIME_DONT_FAKE_MONOTONIC=1 FAKETIME_FORCE_MONOTONIC_FIX=0"
    )
