"""``srcsctl fleet replay ROBOT SEQ``: a stop's flight recorder window replayed at the fleet's
collector, against the robot's records as the collector holds them (SR-13.12; docs/fleet.md
"A stop's evidence at the collector").

The window is the journal entry the robot sent after the window's file
(:mod:`supervisord.record.flight_journal`: ``MESSAGE_ID`` ``FLIGHT_WINDOW_MESSAGE_ID``, the
robot's ``_HOSTNAME``, ``SRCS_SEQ``); the records are the robot's record entries, each
carrying its record whole (``SRCS_RECORD``). Both are read with journalctl, the robot told by
its host name and its sender as ``srcsctl fleet`` names it (``HOST@ADDRESS``, SR-13.8). They
are laid out as the robot keeps them, a record file and its window beside it, in a private
temporary directory, and ``srcsctl replay``'s own code runs on them
(:func:`supervisord.cli.replay.run_replay`): the same steps, verdicts, exit statuses,
``--plot`` and ``--mcap``; where its words name the temporary files, they name the
collector's copy instead.

This command loads the safety core (the replay runs it); ``srcsctl fleet``'s other answers load
none (SR-13.6): ``supervisord/cli/fleet.py`` imports this module for this command alone.
"""

from __future__ import annotations

import io
import json
import subprocess
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import IO, Any, Final

from supervisord.cli.fleet_journal import command, journalctl, label, robot_name
from supervisord.cli.fleet_senders import Senders
from supervisord.cli.replay import run_replay
from supervisord.cli.terminal_text import printable
from supervisord.journal_ids import FLIGHT_WINDOW_MESSAGE_ID
from supervisord.record.flight import flight_dir, window_path
from supervisord.record.flight_journal import WindowEntryError, window_bytes

EXIT_FAILED: Final = 1
EXIT_BAD_INPUT: Final = 2
_WINDOW_FIELDS: Final = (
    "SRCS_SEQ",
    "SRCS_FLIGHT_ENCODING",
    "SRCS_FLIGHT_BYTES",
    "SRCS_FLIGHT_SHA256",
    "SRCS_FLIGHT",
)


class _Refused(Exception):
    """Why there is nothing to replay, in words (raw: escaped where printed), and the status."""

    def __init__(self, text: str, status: int = EXIT_BAD_INPUT) -> None:
        super().__init__(text)
        self.status = status


def parse_robot(text: str) -> tuple[str, str | None]:
    """``HOST@ADDRESS`` as ``srcsctl fleet`` names a robot, or ``HOST`` alone: the host name and
    the sender (``None``: any, when only one sent that host name). Raises ``ValueError``."""
    host, at, sender = text.partition("@")
    robot_name(host)
    if at and not sender:
        raise ValueError(f"{text[:80]!r}: no address after '@' (HOST@ADDRESS, as fleet names it)")
    return host, sender if at else None


def run_fleet_replay(
    source: list[str],
    robot: str,
    seq: str,
    out: IO[str],
    errors: IO[str],
    *,
    show_all: bool = False,
    plot: Path | None = None,
    mcap: Path | None = None,
) -> int:
    """Replay record ``seq``'s window of ``robot`` from the collector's journal ``source``
    (journalctl's ``--directory=DIR`` or ``--file=PATH`` options). The exit status is
    ``srcsctl replay``'s; 2 also when the collector holds no such window, 1 when journalctl
    fails."""
    try:
        host, sender = parse_robot(robot)
        if not seq.isdigit() or int(seq) < 1:
            raise _Refused(f"{seq[:40]!r} is not a record's sequence number")
        senders = Senders([journalctl(), *source])
        window = _window(source, host, sender, int(seq), senders)
        records, without = _records(source, host, window.sender, senders)
    except ValueError as error:
        return _say(errors, str(error), EXIT_BAD_INPUT)
    except _Refused as error:
        return _say(errors, str(error), error.status)
    named = label(host, window.sender)
    if without:
        out.write(
            f"note: {without} of {named}'s records at the collector carry no SRCS_RECORD (an "
            "srcsd that did not send it): they are not compared\n"
        )
    with tempfile.TemporaryDirectory(prefix="srcsctl-fleet-replay-") as folder:
        record = Path(folder) / "stops.jsonl"
        record.write_text("".join(json.dumps(r, separators=(",", ":")) + "\n" for r in records))
        flight_dir(record).mkdir()
        window_file = window_path(record, int(seq))
        window_file.write_bytes(window.data)
        names = {
            str(window_file): f"{named}'s window of #{seq} at the collector",
            str(record): f"{named}'s records at the collector",
        }
        return run_replay(
            str(seq),
            record,
            _Relabel(out, names),
            _Relabel(errors, names),
            show_all=show_all,
            mcap=mcap,
            plot=plot,
        )


class _Window:
    def __init__(self, data: bytes, sender: str | None) -> None:
        self.data, self.sender = data, sender


def _window(
    source: list[str], host: str, sender: str | None, seq: int, senders: Senders
) -> _Window:
    """The newest window entry of record ``seq`` from ``host`` (at ``sender``), decoded."""
    line = [
        *_base(source),
        f"--output-fields={','.join(_WINDOW_FIELDS)}",
        f"MESSAGE_ID={FLIGHT_WINDOW_MESSAGE_ID.hex}",
        f"_HOSTNAME={host}",
        f"SRCS_SEQ={seq}",
    ]
    found = list(_from(_json_lines(line), senders, host, sender))
    if not found:
        raise _Refused(_no_window(source, host, sender, seq, senders))
    entry, from_sender = found[-1]  # sent again after an outage: the same bytes
    try:
        return _Window(window_bytes({k: _text(entry, k) for k in _WINDOW_FIELDS}), from_sender)
    except WindowEntryError as error:
        where = label(host, from_sender)
        raise _Refused(f"the window of record {seq} from {where} is not whole: {error}") from None


def _no_window(source: list[str], host: str, sender: str | None, seq: int, senders: Senders) -> str:
    """Why there is no window: none of this robot at all, or the nearest records that have one."""
    line = [
        *_base(source),
        "--output-fields=SRCS_SEQ",
        f"MESSAGE_ID={FLIGHT_WINDOW_MESSAGE_ID.hex}",
        f"_HOSTNAME={host}",
    ]
    kept = sorted(
        {
            int(text)
            for entry, _ in _from(_json_lines(line), senders, host, sender)
            if (text := _text(entry, "SRCS_SEQ")) is not None and text.isdigit()
        }
    )
    robot = label(host, sender)
    below = [n for n in kept if n < seq][-1:]
    above = [n for n in kept if n > seq][:1]
    if not kept:
        near = f"the collector holds no window of {robot}"
    else:
        near = "the nearest windows of it: " + ", ".join(f"#{n}" for n in below + above)
    return (
        f"no window of record {seq} from {robot} at the collector: windows are sent for stops "
        f"only, after the record, and arrive with the robot's next upload; {near}"
    )


def _records(
    source: list[str], host: str, sender: str | None, senders: Senders
) -> tuple[list[Mapping[str, Any]], int]:
    """The robot's records as its entries carry them whole (``SRCS_RECORD``), in the journal's
    order (each robot's own), and how many entries carry none."""
    records: list[Mapping[str, Any]] = []
    without = 0
    for entry, _ in _from(_json_lines(command(source, robot=host)), senders, host, sender):
        text = _text(entry, "SRCS_RECORD")
        try:
            record = json.loads(text) if text is not None else None
        except (ValueError, RecursionError):
            record = None
        if isinstance(record, dict):
            records.append(record)
        else:
            without += 1
    return records, without


def _base(source: list[str]) -> list[str]:
    return [journalctl(), *source, "--output=json", "--no-pager", "--all", "--quiet"]


def _json_lines(line: list[str]) -> list[Any]:
    try:
        done = subprocess.run(line, capture_output=True, text=True, check=False)  # noqa: S603
    except OSError as error:
        raise _Refused(f"{line[0]}: {error.strerror or error}", EXIT_FAILED) from None
    if done.returncode != 0:
        said = done.stderr.strip().splitlines()
        why = said[-1] if said else f"exit {done.returncode}"
        raise _Refused(f"journalctl: {why}", EXIT_FAILED)
    found = []
    for text in done.stdout.splitlines():
        try:
            found.append(json.loads(text))
        except (ValueError, RecursionError):
            continue  # not an entry; the records' own reader says so (srcsctl fleet)
    return found


def _from(
    entries: list[Any], senders: Senders, host: str, sender: str | None
) -> Iterator[tuple[Mapping[str, Any], str | None]]:
    """The entries of the robot: each with its sender; with ``sender`` ``None``, of the one
    sender that sent ``host`` (two senders of one host name are two robots, SR-13.8: the
    command names which)."""
    chosen = [
        (entry, senders.of(str(entry.get("__CURSOR", ""))))
        for entry in entries
        if isinstance(entry, dict)
    ]
    if sender is not None:
        yield from ((entry, found) for entry, found in chosen if found == sender)
        return
    heard = sorted({str(found) for _, found in chosen if found is not None})
    if len(heard) > 1:
        robots = ", ".join(label(host, s) for s in heard)
        raise _Refused(f"host name {host} came from {len(heard)} senders: name one of {robots}")
    yield from chosen


def _text(entry: Mapping[str, Any], field: str) -> str | None:
    """A field as text: journalctl writes a repeated field as a list (the last is taken); a
    value journalctl gives as bytes is none of this command's (ASCII) fields: ``None``."""
    value = entry.get(field)
    if isinstance(value, list) and value and isinstance(value[-1], str):
        value = value[-1]
    return value if isinstance(value, str) else None


def _say(errors: IO[str], text: str, status: int) -> int:
    """``text`` on ``errors``, escaped: it may hold a sender's words (SR-13.7)."""
    print(f"srcsctl fleet replay: {printable(text)}", file=errors)
    return status


class _Relabel(io.StringIO):
    """``stream``, with each temporary path of ``names`` written as what it stands for: the
    replay's words name its files, which here are the collector's copy. Nothing is kept."""

    def __init__(self, stream: IO[str], names: Mapping[str, str]) -> None:
        super().__init__()
        self.stream = stream
        self.names = sorted(names.items(), key=lambda item: -len(item[0]))  # longest first

    def write(self, text: str) -> int:
        for path, name in self.names:
            text = text.replace(path, name)
        self.stream.write(text)
        return len(text)

    def flush(self) -> None:
        self.stream.flush()
