"""``srcsctl fleet``: on a fleet's collector, which robots stopped and why (SR-13.4).

The collector's journal (systemd-journal-remote's directory, ``/var/log/journal/remote``) is
read with journalctl, selected by the record kinds' MESSAGE_IDs and the robot's
``_HOSTNAME`` (:mod:`fleet_journal`), and each entry is printed as ``srcsctl log`` prints a
record (:mod:`record_print`), after the robot's name. ``log``'s habits: ``--since`` and
``--until`` in the same forms, ``--cause``, ``-o``, ``-n``, ``-r``, ``-f``, ``-q``, the exit
statuses. ``--summary``: one line per robot instead.

A robot is its host name and its sender's address together (SR-13.8): the host name is the
uploader's word, the address the collector's (:mod:`fleet_senders`); one host name from two
senders is two robots, and a warning says so. Every text of an entry is another machine's and
is escaped before it is printed (SR-13.7, :mod:`terminal_text`); JSON escapes it itself.

Order: journalctl's, which keeps each robot's records in the order its journal wrote them
(the order of its ``seq``) and interleaves robots by their own clocks; nothing here sorts by a
wall clock (SR-13.5). A record the collector holds twice (sent again after an outage) is
shown once (SR-13.1). Nothing here imports the safety core (SR-13.6): each entry is read as
the typed stop record, and ``--cause``'s names are the shared vocabulary's.
"""

from __future__ import annotations

import argparse
import datetime as dt
import errno
import json
import os
import select
import subprocess
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Final

from supervisord.cli import fleet_console, log_options
from supervisord.cli.access import advice
from supervisord.cli.cause_names import CauseFilter
from supervisord.cli.fleet_journal import (
    DEFAULT_DIRECTORY,
    Entry,
    NoJournalctl,
    command,
    entry,
    journalctl,
    label,
    robot_name,
)
from supervisord.cli.fleet_senders import Senders
from supervisord.cli.interrupt import interruptible
from supervisord.cli.log_options import FOLLOW_LAST
from supervisord.cli.record_print import JSON_OUTPUTS, NO_ENTRIES, RecordPrinter
from supervisord.cli.tally_text import tally_json, tally_line
from supervisord.cli.terminal_text import printable
from supervisord.cli.times import BadTime, parse_time
from supervisord.record.counted import Tally, changes
from supervisord.record.stop import StopRecord

EXIT_FAILED: Final = 1
EXIT_BAD_INPUT: Final = 2


def _robot(text: str) -> str:
    try:
        return robot_name(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def add_arguments(fleet: argparse.ArgumentParser) -> None:
    """``srcsctl fleet``'s options (docs/srcsctl.md "fleet")."""
    where = fleet.add_mutually_exclusive_group()
    where.add_argument(
        "-D",
        "--directory",
        metavar="DIR",
        help=f"the collector's journal directory (default: {DEFAULT_DIRECTORY})",
    )
    where.add_argument(
        "--file",
        metavar="PATH",
        action="append",
        help="a journal file instead (a robot's copied file); may be given again",
    )
    fleet.add_argument(
        "--robot", dest="host", metavar="NAME", type=_robot, help="only this robot (its host name)"
    )
    log_options.add_time_range(fleet)
    log_options.add_cause_filters(fleet)
    fleet.add_argument(
        "--summary",
        action="store_true",
        help="one line per robot: its stops (the last one's time and trigger), start-ups, "
        'proof tests and re-arms, apart (docs/record.md "What counts as a stop")',
    )
    log_options.add_output(fleet)
    log_options.add_follow_and_display(fleet, follows="as the collector gets it")
    _add_replay(fleet)


def _add_replay(fleet: argparse.ArgumentParser) -> None:
    """``srcsctl fleet replay ROBOT SEQ``: a stop's window at the collector (SR-13.12). Its own
    destinations: a subcommand's defaults would overwrite ``fleet``'s own options."""
    actions = fleet.add_subparsers(dest="fleet_command", metavar="{replay,stop,status,keepalive}")
    replay = actions.add_parser(
        "replay",
        help="replay a robot's stop from its flight recorder window as the collector holds it",
        description="Replay the flight recorder window a robot sent for its stop record SEQ "
        "against its records as the collector holds them, as 'srcsctl replay' does on the "
        "robot (srcsctl(1), docs/fleet.md). ROBOT: as 'srcsctl fleet' names it, HOST@ADDRESS, "
        "or its host name alone when one sender sent it.",
    )
    replay.add_argument("replay_robot", metavar="ROBOT")
    replay.add_argument("replay_seq", metavar="SEQ")
    where = replay.add_mutually_exclusive_group()
    where.add_argument("-D", "--directory", dest="replay_directory", metavar="DIR")
    where.add_argument("--file", dest="replay_file", metavar="PATH", action="append")
    replay.add_argument(
        "--all",
        dest="replay_all",
        action="store_true",
        help="a line for every input, not only those that decide",
    )
    replay.add_argument("--mcap", metavar="OUT", help="as srcsctl replay --mcap")
    replay.add_argument("--plot", metavar="OUT.svg", help="as srcsctl replay --plot")
    # The fleet's console (SR-13.15): its own module, which reads no journal.
    fleet_console.add_subcommands(actions)


def run(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    """``srcsctl fleet`` with the options :func:`add_arguments` parsed."""
    if getattr(args, "fleet_command", None) == "replay":
        return _replay(args, out, errors)
    if getattr(args, "fleet_command", None) == "stop":
        return fleet_console.run_stop(args, out, errors)
    if getattr(args, "fleet_command", None) == "status":
        return fleet_console.run_status(args, out, errors)
    if getattr(args, "fleet_command", None) == "keepalive":
        return fleet_console.run_keepalive(args, out, errors)
    output = "json" if args.json and not args.output else args.output or "short"
    return run_fleet(
        out,
        errors,
        directory=Path(args.directory) if args.directory else None,
        files=[Path(f) for f in args.file or []],
        robot=args.host,
        since=args.since,
        until=args.until,
        cause=args.cause,
        cause_present=args.cause_present,
        output=output,
        utc=args.utc,
        last=args.lines,
        follow=args.follow,
        reverse=args.reverse,
        causes=args.causes,
        quiet=args.quiet,
        summary=args.summary,
    )


def _replay(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    """``srcsctl fleet replay``: the only answer of ``fleet`` that loads the safety core (the
    replay runs it), imported here and nowhere else (SR-13.6)."""
    from supervisord.cli.fleet_replay import run_fleet_replay  # noqa: PLC0415

    directory = args.replay_directory or args.directory
    files = [Path(f) for f in [*(args.file or []), *(args.replay_file or [])]]
    source, status = _source(Path(directory) if directory else None, files, errors)
    if status:
        return status
    return run_fleet_replay(
        source,
        args.replay_robot,
        args.replay_seq,
        out,
        errors,
        show_all=args.replay_all,
        plot=Path(args.plot) if args.plot else None,
        mcap=Path(args.mcap) if args.mcap else None,
    )


def run_fleet(
    out: IO[str],
    errors: IO[str],
    *,
    directory: Path | None = None,
    files: list[Path] | None = None,
    robot: str | None = None,
    since: str | None = None,
    until: str | None = None,
    cause: CauseFilter | None = None,
    cause_present: CauseFilter | None = None,
    output: str = "short",
    utc: bool = False,
    last: int | None = None,
    follow: bool = False,
    reverse: bool = False,
    causes: bool = False,
    quiet: bool = False,
    summary: bool = False,
) -> int:
    """Print the collector's records (see the module's doc). Exit 0 done, 1 the journal could
    not be read (why printed), 2 a usage error."""
    now = dt.datetime.now(dt.timezone.utc)
    try:
        start = parse_time(since, now, utc=utc) if since else None
        end = parse_time(until, now, utc=utc) if until else None
    except BadTime as error:
        return _say(errors, str(error), EXIT_BAD_INPUT)
    if follow and (reverse or summary):
        which = "-r" if reverse else "--summary"
        return _say(errors, f"{which} and -f do not go together", EXIT_BAD_INPUT)
    source, status = _source(directory, files or [], errors)
    if status:
        return status
    try:
        scan = command(source, robot=robot, since=start, until=end)
        tail = command(source, robot=robot, since=start, until=end, follow=True)
        senders = Senders([journalctl(), *source])
    except NoJournalctl as error:
        return _say(errors, str(error), EXIT_FAILED)
    if follow and last is None and start is None and end is None:
        last = FOLLOW_LAST
    wanted = _Filter(cause, cause_present, start, end)
    try:
        scanned = _scan(scan, errors, senders)
    except _JournalctlFailed as error:
        return _say(errors, str(error), EXIT_FAILED)
    known: set[tuple[str, ...]] = set()
    entries = _once(scanned, known)
    heard = _Heard(errors)
    heard.add(entries)
    chosen = wanted.select(entries)
    shown = [] if last == 0 else chosen[-last:] if last is not None else chosen
    printer = RecordPrinter(out, output=output, utc=utc, causes=causes)
    printer.before.update(wanted.first_before(shown))  # what each robot's first line changed
    if summary:
        _summarize(shown, wanted, out, json_lines=output in JSON_OUTPUTS, utc=utc)
    else:
        _show(printer, shown, reverse=reverse)
    if not follow:
        if not shown and not quiet and output not in JSON_OUTPUTS:
            print(NO_ENTRIES, file=out)
        return 0
    seen = {e.cursor for e in scanned}
    return _follow(
        tail,
        seen=seen,
        known=known,
        wanted=wanted,
        printer=printer,
        errors=errors,
        source=source,
        senders=senders,
        heard=heard,
    )


class _JournalctlFailed(Exception):
    pass


def _say(errors: IO[str], text: str, status: int) -> int:
    """``text`` on ``errors``, escaped: it may hold a sender's words (SR-13.7)."""
    print(f"srcsctl fleet: {printable(text)}", file=errors)
    return status


class _Heard:
    """Every sender each host name came from; a host name heard from a second sender is said
    on ``errors``, once for each new sender (SR-13.8): an uploader chooses its ``_HOSTNAME``,
    so one of them may not be the robot the name says, and each is shown apart."""

    def __init__(self, errors: IO[str]) -> None:
        self.errors = errors
        self.senders: dict[str, list[str | None]] = {}

    def add(self, entries: Iterable[Entry]) -> None:
        for item in entries:
            known = self.senders.setdefault(item.robot, [])
            if item.sender in known:
                continue
            known.append(item.sender)
            if len(known) > 1:
                named = ", ".join("a file no collector named" if s is None else s for s in known)
                _say(
                    self.errors,
                    f"warning: host name {item.robot} came from {len(known)} senders: {named}; "
                    "a host name is the sender's word: each sender is shown as a robot of its own",
                    0,
                )


def _source(directory: Path | None, files: list[Path], errors: IO[str]) -> tuple[list[str], int]:
    """journalctl's source options, or a status after saying why there is none."""
    if files:
        for path in files:
            if not path.is_file():
                what = "no such file" if not path.exists() else "not a file"
                return [], _say(errors, f"{path}: {what}", EXIT_BAD_INPUT)
            if not os.access(path, os.R_OK):
                refused = f"{path}: permission denied{advice(path, errno.EACCES)}"
                return [], _say(errors, refused, EXIT_FAILED)
        return [f"--file={path}" for path in files], 0
    folder = directory or DEFAULT_DIRECTORY
    if not folder.exists():
        missing = f"{folder}: no such directory (is this the collector?)"
        return [], _say(errors, missing, EXIT_BAD_INPUT)
    if not folder.is_dir():
        return [], _say(errors, f"{folder}: not a directory", EXIT_BAD_INPUT)
    try:
        os.listdir(folder)
    except OSError as error:  # never an empty answer with exit 0 (SR-7.9)
        why = error.strerror or str(error)
        return [], _say(errors, f"{folder}: {why}{advice(folder, error.errno)}", EXIT_FAILED)
    return [f"--directory={folder}"], 0


def _entries(lines: Iterable[str], errors: IO[str], senders: Senders) -> Iterator[Entry]:
    for line in lines:
        found = entry(line, senders)
        if isinstance(found, str):
            _say(errors, found, 0)
        else:
            yield found


def _once(entries: Iterable[Entry], known: set[tuple[str, ...]]) -> list[Entry]:
    """Each record once (SR-13.1): an entry whose robot, ``seq`` and robot's stamps are those
    of one already read (``known``, which this adds to) is a second copy of it, which
    systemd-journal-upload sent again after the collector went away before answering; it is
    dropped. An entry without the robot's stamps is always kept."""
    kept = []
    for item in entries:
        if item.identity is not None:
            if item.identity in known:
                continue
            known.add(item.identity)
        kept.append(item)
    return kept


def _scan(line: list[str], errors: IO[str], senders: Senders) -> list[Entry]:
    """Every entry journalctl gives now, in its order."""
    try:
        done = subprocess.run(line, capture_output=True, text=True, check=False)  # noqa: S603
    except OSError as error:
        raise _JournalctlFailed(f"{line[0]}: {error.strerror or error}") from None
    if done.returncode != 0:
        said = done.stderr.strip().splitlines()
        raise _JournalctlFailed(f"journalctl: {said[-1] if said else f'exit {done.returncode}'}")
    return list(_entries(done.stdout.splitlines(), errors, senders))


WAKE_S: Final = 1.0
"""How often ``-f`` looks for a new file in the collector's directory while journalctl is
quiet."""


def _journal_files(source: list[str]) -> frozenset[str]:
    """The journal files of a ``--directory`` source now (none to watch for ``--file``)."""
    folder = next((s.partition("=")[2] for s in source if s.startswith("--directory=")), None)
    if folder is None:
        return frozenset()
    try:
        return frozenset(n for n in os.listdir(folder) if n.endswith((".journal", ".journal~")))
    except OSError:
        return frozenset()


def _follow(
    line: list[str],
    *,
    seen: set[str],
    known: set[tuple[str, ...]],
    wanted: _Filter,
    printer: RecordPrinter,
    errors: IO[str],
    source: list[str],
    senders: Senders,
    heard: _Heard,
) -> int:
    """Each record the collector takes in from now on, until Ctrl-C or SIGTERM (exit 0).
    journalctl follows every entry of the window from each file's start (``--lines=all``);
    those already shown are known by their cursors. A file that appears later (a robot's
    first upload, a file the receiver started anew) is placed by journalctl by time among the
    others, and an entry stamped before the newest one shown would be passed by (a robot
    whose clock is behind, or that uploads after an outage): journalctl is started again
    over every file when one appears (SR-13.5)."""
    interruptible()
    try:
        while True:
            files = _journal_files(source)
            senders.read()  # the files' senders, the new one's too
            try:
                tail = subprocess.Popen(  # noqa: S603
                    line, stdout=subprocess.PIPE, stderr=subprocess.PIPE
                )
            except OSError as error:
                return _say(errors, f"{line[0]}: {error.strerror or error}", EXIT_FAILED)
            try:
                ended = _read_tail(
                    tail,
                    files=files,
                    seen=seen,
                    known=known,
                    wanted=wanted,
                    printer=printer,
                    errors=errors,
                    source=source,
                    senders=senders,
                    heard=heard,
                )
            finally:
                # SIGKILL, not SIGTERM: journalctl 257 (Debian 13) handles SIGTERM in its event
                # loop, which a write blocked on the full pipe we stopped reading never reaches,
                # so a wait after SIGTERM waited for ever (SR-13.5).
                tail.kill()
                tail.wait()
            if ended:
                said = tail.stderr.read().decode(errors="replace") if tail.stderr else ""
                lines = said.strip().splitlines()
                return _say(errors, f"journalctl: {lines[-1] if lines else 'ended'}", 1)
    except KeyboardInterrupt:
        return 0


def _read_tail(
    tail: subprocess.Popen[bytes],
    *,
    files: frozenset[str],
    seen: set[str],
    known: set[tuple[str, ...]],
    wanted: _Filter,
    printer: RecordPrinter,
    errors: IO[str],
    source: list[str],
    senders: Senders,
    heard: _Heard,
) -> bool:
    """Show the new records journalctl prints; ``False`` when a new file appeared (start
    again: looked for before each batch is shown, and after a second of silence), ``True``
    when journalctl ended."""
    assert tail.stdout is not None
    fd, pending = tail.stdout.fileno(), b""
    while True:
        ready, _, _ = select.select([fd], [], [], WAKE_S)
        if not ready:
            if _journal_files(source) - files:
                return False
            continue
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            return True
        if _journal_files(source) - files:
            # A new file before anything of it is shown: journalctl may print first what of
            # it falls after its position, and the rest only when started again, out of the
            # robot's order (SR-13.5). Started again, it shows the file from its start.
            return False
        *complete, pending = (pending + chunk).split(b"\n")
        text = [raw.decode(errors="replace") for raw in complete]
        fresh = [e for e in _entries(text, errors, senders) if e.cursor not in seen]
        seen.update(e.cursor for e in fresh)
        once = _once(fresh, known)
        heard.add(once)
        _show(printer, wanted.select(once))


def _show(printer: RecordPrinter, shown: list[Entry], *, reverse: bool = False) -> None:
    """The entries' lines, each after its robot's label (escaped, as the line is: SR-13.7);
    in JSON, ``robot`` (the host name) and ``sender`` first (SR-13.8)."""
    sources = [e.label for e in shown]
    width = max((len(label) for label in sources), default=0)
    heads = [{"robot": e.robot, "sender": e.sender} for e in shown]
    printer.show(
        [e.data for e in shown], reverse=reverse, sources=sources, width=width, heads=heads
    )


class _Filter:
    """``--cause`` and ``--cause-present``, as ``log`` judges them; each robot's records are
    compared with the one before of the same robot (:attr:`last`) when they carry no
    ``changes`` (written before SRCS_CHANGES)."""

    def __init__(
        self,
        cause: CauseFilter | None,
        present: CauseFilter | None,
        start: dt.datetime | None = None,
        end: dt.datetime | None = None,
    ) -> None:
        self.cause, self.present, self.start, self.end = cause, present, start, end
        self.last: dict[tuple[str, str | None], StopRecord | None] = {}  # by robot
        self.before: dict[str, StopRecord | None] = {}  # by cursor

    def select(self, entries: list[Entry]) -> list[Entry]:
        chosen = []
        for item in entries:
            previous = self.last.get(item.who)
            self.last[item.who] = item.record
            self.before[item.cursor] = previous
            if item.within(self.start, self.end) and self._wanted(item.record, previous):
                chosen.append(item)
        return chosen

    def first_before(self, shown: list[Entry]) -> dict[str | None, StopRecord | None]:
        """For each robot (by its label, as the printer knows it), the record before its first
        one shown."""
        firsts: dict[str | None, StopRecord | None] = {}
        for item in shown:
            if item.label not in firsts:
                firsts[item.label] = self.before.get(item.cursor)
        return firsts

    def _wanted(self, record: StopRecord | None, previous: StopRecord | None) -> bool:
        if self.present is None and self.cause is None:
            return True
        if record is None:  # no typed record: names no cause a filter takes, as in ``log``
            return False
        present = self.present
        if present is not None and not any(present.takes(c.name) for c in record.causes):
            return False
        if self.cause is None:
            return True
        return any(self.cause.takes(name) for _, name in changes(record, previous))


def _summarize(
    shown: list[Entry], wanted: _Filter, out: IO[str], *, json_lines: bool, utc: bool
) -> None:
    """One line per robot (host name and sender), by label: its records counted as
    ``srcsctl log --summary`` counts a record file's (:mod:`tally_text`, SR-13.9): its stops
    and the last one's trigger, its start-ups, proof tests and re-arms; escaped (SR-13.7)."""
    robots: dict[tuple[str, str | None], Tally] = {}
    for item in shown:
        robots.setdefault(item.who, Tally()).add(item.record, wanted.before.get(item.cursor))
    labels = {who: label(*who) for who in robots}
    width = max((len(name) for name in labels.values()), default=0)
    for who in sorted(robots, key=labels.__getitem__):
        if json_lines:
            head = {"robot": who[0], "sender": who[1]}
            out.write(json.dumps({**head, **tally_json(robots[who])}) + "\n")
            continue
        line = tally_line(robots[who], utc=utc)
        out.write(f"{labels[who]:{width}}  {printable(line)}\n")
    out.flush()


def main(argv: list[str] | None = None) -> int:
    """``srcsctl fleet`` alone: the command as ``srcsctl`` runs it, for a collector's own
    scripts and for the check that it loads no module of the safety core (SR-13.6)."""
    parser = argparse.ArgumentParser(prog="srcsctl fleet", description=__doc__)
    add_arguments(parser)
    return run(parser.parse_args(argv), sys.stdout, sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
