"""``srcsctl replay``: run a flight recorder window through a fresh safety core and show, step by
step, that it makes the decisions the record holds (SR-7.13; docs/record.md "Replay",
docs/srcsctl.md).

The record file is the record that counts (SR-7.13): the replay is compared with its records,
the stop record included, and the window's own copy of the stop record is checked against it.

Exit 0 when every record the replay makes that the record file holds is the same, the stop
record included; 1 at the first that differs (the step and the fields are printed); 2 when the
window cannot be read or replayed (damaged, nested too deep, another version's snapshot, a
window whose start the bound cut); 3 when the record file does not hold the stop record or
cannot be read (the replay is then compared with the window's own copy, and says so: nothing
was checked against the record file); 5 when the window's copy of the stop record differs from
the record file's (the fields are printed): the window was edited, or is another record's.

``--mcap FILE`` and ``--plot FILE.svg`` write the window, its records and the replayed
decisions as an MCAP file and as a picture (SR-7.15, SR-7.16; ``replay_export``); the exit
status stays the replay's. Each is written safely against links and shared folders, ``-``
being standard output (SR-11.4, ``output_file``): then the replay's own text goes to standard
error, so that standard output holds the file alone. A link or a device named as the file is
refused before the replay (exit 2).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, BinaryIO, Final

from supervisord import __version__
from supervisord.cli import replay_export as export
from supervisord.cli.output_file import OutputRefused, check_target, is_standard_output
from supervisord.cli.terminal_text import printable
from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import VscHeartbeat
from supervisord.record.flight import LoadedWindow, read_window, record_of, window_path, windows
from supervisord.record.flight_codec import FlightFormatError
from supervisord.record.format import trigger_json
from supervisord.record.jsonl import RecordUnreadable, StoredRecord, read_records
from supervisord.record.replay import (
    Mismatch,
    Replay,
    ReplayError,
    Step,
    copy_differs,
    differing,
    replay,
)
from supervisord.record.stop import StopRecord, read_written
from supervisord.safety.events import Event, VscReceived
from supervisord.vocabulary import State

EXIT_MISMATCH: Final = 1
EXIT_BAD_INPUT: Final = 2
EXIT_NOT_CHECKED: Final = 3
"""The record file does not hold the window's stop record, or cannot be read (SR-7.13)."""
EXIT_NOT_THE_RECORD: Final = 5
"""The window's copy of its stop record differs from the record file's (SR-7.13)."""
INPUT_WIDTH: Final = 64

Json = Any


def find_window(which: str | None, record: Path | None) -> Path:
    """The window file: ``which`` as a record's sequence number (its window beside ``record``)
    or a path; with neither, the newest window of ``record``. Raises ``LookupError``."""
    if which is not None and not which.isdigit():
        return Path(which)
    if record is None:
        raise LookupError("name the record (--config FILE or --file PATH) or a window file")
    if which is not None:
        path = window_path(record, int(which))
        if not path.exists():
            raise LookupError(no_window(record, int(which)))
        return path
    found = windows(record)
    if not found:
        raise LookupError(f"no flight recorder window beside {record} yet")
    return found[-1][1]


def no_window(record: Path, seq: int) -> str:
    """Why record ``seq`` has no window, in words: what the record is (windows are written for
    stops only, SR-7.12), and the stops nearest to it that have one."""
    data = _record_numbered(record, seq)
    typed = None if data is None else read_written(data)
    if data is None:
        what = f"there is no record {seq} in {record}"
    elif typed is not None and typed.is_stop:
        what = (
            f"record {seq} is a stop, but its window is not kept: only the newest windows are "
            "(within the record's flight_max_bytes), and one that could not be written is "
            "counted in status"
        )
    else:
        what = f"record {seq} is {_what_record(typed, data)}: windows are kept for stops only"
    kept = [number for number, _ in windows(record)]
    below = [number for number in kept if number < seq][-1:]
    above = [number for number in kept if number > seq][:1]
    nearest = ", ".join(f"#{number}" for number in below + above)
    near = f"; the nearest stops with windows: {nearest}" if nearest else "; no window is kept"
    return f"no window of record {seq}: {what}{near} (srcsctl replay SEQ)"


def _record_numbered(record: Path, seq: int) -> Mapping[str, Json] | None:
    """The newest record numbered ``seq`` (numbering starts again only with a new file)."""
    found = None
    try:
        for item in read_records(record):
            if isinstance(item, StoredRecord) and item.seq == seq:
                found = item.data
    except (RecordUnreadable, OSError, RecursionError, ValueError):
        return None
    return found


def _what_record(record: StopRecord | None, data: Mapping[str, Json]) -> str:
    """``a re-arm (STOPPED -> RUN)``, ``a cause_cleared record (STOPPED)``; a line that is
    no typed record by its fields as written."""
    if record is None:
        return f"a {data.get('kind') or 'state_change'} record ({data.get('to')})"
    before, after = record.from_state, record.to_state
    if before is State.STOPPED and after is not State.STOPPED:
        return f"a re-arm ({before} -> {after})"
    if before is not after:
        return f"a change of state ({before} -> {after})"
    return f"a {record.record_kind} record ({after})"


def recorded_records(
    record: Path | None, after: int
) -> tuple[dict[int, Mapping[str, Json]], str | None]:
    """The records of ``record`` (all its files) numbered after ``after``, by number, and why
    some of it could not be read (``None``: it all could)."""
    if record is None:
        return {}, "no record file named (--file or --config)"
    found: dict[int, Mapping[str, Json]] = {}
    unread = None
    try:
        for item in read_records(record):
            if isinstance(item, StoredRecord):
                if item.seq > after:
                    found[item.seq] = item.data
            elif item.line == 0:  # not a regular file, or not opened
                unread = f"{item.file} cannot be read: {item.text}"
    except RecordUnreadable as error:  # there, but closed to this user (SR-7.9)
        unread = str(error)
    except (OSError, RecursionError, ValueError) as error:
        # A line nested past the interpreter's limit.
        unread = f"{record} cannot be read: {type(error).__name__}: {error}"
    return found, unread


def describe(event: Event | None) -> str:
    """One input as a short line: its record name and fields, a VSC message by its content."""
    if event is None:
        return "start (a fresh core)"
    if isinstance(event, VscReceived):
        message = event.message
        if isinstance(message, VscHeartbeat):
            view = message_json(message)
            return f"vsc_received heartbeat {view['vsc_mode_name']} e-stop 0x{message.estop:08x}"
        return f"vsc_received {_compact(message_json(message))}"
    fields = trigger_json(event)
    name = fields.pop("event")
    return f"{name} {_compact(fields)}" if fields else str(name)


def _compact(value: Json) -> str:
    # ASCII: JSON escapes every control, bidi and separator character itself (SR-13.7).
    return json.dumps(value, separators=(",", ":"))


def _cut(text: str, width: int = INPUT_WIDTH) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def _causes(record: Mapping[str, Json]) -> str:
    causes = record.get("causes")
    names = [c.get("name", "?") for c in causes if isinstance(c, dict)] if causes else []
    return ", ".join(str(n) for n in names)


def _record_line(record: Mapping[str, Json]) -> str:
    return printable(  # a record file's text (SR-13.7)
        f"#{record.get('seq')} {record.get('from')} -> {record.get('to')} "
        f"{record.get('kind', 'state_change')} [{_causes(record)}]"
    )


class _Printer:
    def __init__(
        self, out: IO[str], stop_ns: int, show_all: bool, copy_only: int | None = None
    ) -> None:
        self.out, self.stop_ns, self.show_all = out, stop_ns, show_all
        self.copy_only = copy_only  # the stop record the record file does not hold
        self.quiet = 0  # inputs passed without a line

    def time(self, step: Step | None) -> str:
        """When the input came, in seconds from the stop."""
        if step is None or step.event is None:
            return "      start"
        return f"{(step.event.now - self.stop_ns) / 1e9:+9.3f} s"

    def step(self, step: Step) -> None:
        changed = step.previous is not step.decision.state
        if not (self.show_all or step.records or changed or step.event is None):
            self.quiet += 1
            return
        self.flush()
        state = step.decision.state.name
        move = f"{step.previous.name} -> {state}" if changed else state
        line = f"{step.number:>6} {self.time(step)}  {_cut(describe(step.event)):<{INPUT_WIDTH}}"
        self.out.write(f"{line}  {move}\n")
        for replayed, recorded in step.records:
            verdict = "as recorded" if recorded is not None else "(not in the record files)"
            if recorded is not None and not _same(recorded, replayed):
                verdict = "DIFFERS"
            elif recorded is not None and replayed.get("seq") == self.copy_only:
                verdict = "as the window's copy (not in the record files)"
            self.out.write(f"{'':>20}{_record_line(replayed)}  {verdict}\n")

    def flush(self) -> None:
        if self.quiet:
            plural = "s" if self.quiet > 1 else ""
            self.out.write(f"{'':>20}... {self.quiet} input{plural}, no record\n")
            self.quiet = 0


def _same(recorded: Mapping[str, Json], replayed: Mapping[str, Json]) -> bool:
    return not differing(recorded, replayed)


def _header(window: LoadedWindow, out: IO[str]) -> int:
    header, base = window.header, window.base
    stop_ns = window.stop.get("mono_ns")
    stop_ns = stop_ns if isinstance(stop_ns, int) else 0
    first = window.inputs[0].now if window.inputs else stop_ns
    start = base.get("now_ns")
    start = start if isinstance(start, int) else first
    kind = {"start": "a fresh core at the daemon's start", "snapshot": "a snapshot of the core"}
    said = (
        f"window of record #{window.seq} ({window.path}), written by srcsd {header.get('srcsd')}: "
        f"{len(window.inputs)} inputs over {(stop_ns - start) / 1e9:.3f} s before the stop, "
        f"from {kind.get(str(base.get('kind')), str(base.get('kind')))}"
    )
    out.write(printable(said) + "\n")  # the window file's text (SR-13.7)
    out.write(f"the stop: {_record_line(window.stop)}\n")
    if header.get("srcsd") != __version__:
        out.write(
            f"note: recorded by srcsd {printable(str(header.get('srcsd')))}, replayed by "
            f"{__version__}: a core that changed since may decide otherwise\n"
        )
    return stop_ns


def _mismatch(mismatch: Mismatch, result: Replay, printer: _Printer, out: IO[str]) -> None:
    where = "at the end of the window"
    if mismatch.step is not None:
        step = mismatch.step
        where = f"at step {step.number} ({printer.time(step).strip()}, {describe(step.event)})"
    out.write(f"MISMATCH {where}: record #{mismatch.seq}\n")
    recorded, replayed = mismatch.recorded, mismatch.replayed
    if replayed is None:
        out.write(f"  recorded: {_record_line(recorded or {})}\n")
        ended = result.steps[-1].decision.state.name if result.steps else "?"
        out.write(f"  replayed: no such record (the replay is in {ended} there)\n")
        return
    out.write(f"  differing fields: {printable(', '.join(mismatch.fields))}\n")
    for field in mismatch.fields:
        was = (recorded or {}).get(field)
        name = printable(field)  # a record file's key (SR-13.7)
        out.write(f"  {name}: recorded {_compact(was)}\n")
        out.write(f"  {' ' * len(name)}  replayed {_compact(replayed.get(field))}\n")


def _copy_differs(
    window: LoadedWindow, record: Path | None, fields: tuple[str, ...], out: IO[str]
) -> None:
    out.write(
        f"NOT THE RECORD: the window's copy of stop record #{window.seq} differs from the "
        f"record file ({record}): differing fields: {printable(', '.join(fields))}; the replay "
        "is compared with the record file\n"
    )


def _copy_only(window: LoadedWindow, unread: str | None, record: Path | None) -> str:
    """Why the stop record was compared with the window's own copy only."""
    if unread is not None:
        return unread
    return f"{record} does not hold record #{window.seq} (rotated away, or never written)"


def _refused_targets(mcap: Path | None, plot: Path | None, stdout: BinaryIO | None) -> str | None:
    """Why the files named cannot be written (no MCAP library; SR-11.4), before anything is
    replayed; ``None`` when they can."""
    if mcap is not None and not export.mcap_available():
        return f"--mcap: {export.MCAP_MISSING}"
    named = [(option, t) for option, t in (("--mcap", mcap), ("--plot", plot)) if t is not None]
    to_stdout = [option for option, target in named if is_standard_output(target)]
    if len(to_stdout) > 1:
        return "only one of --mcap and --plot can be - (standard output)"
    if to_stdout and stdout is None:
        return f"{to_stdout[0]} -: standard output is not taken here"
    for option, target in named:
        try:
            check_target(target)
        except OutputRefused as error:
            return f"{option}: {error}"
    return None


def _text_out(out: IO[str], errors: IO[str], *targets: Path | None) -> IO[str]:
    """Where the replay's text goes: standard error when a file goes to standard output, so
    that it holds the file alone (SR-11.4)."""
    return errors if any(t is not None and is_standard_output(t) for t in targets) else out


def _write_failure(error: OutputRefused | OSError) -> str:
    if isinstance(error, OSError):
        return f"cannot write {error.filename}: {error.strerror}"
    return str(error)  # a link or a device planted since the check


def run_replay(
    which: str | None,
    record: Path | None,
    out: IO[str],
    errors: IO[str],
    *,
    show_all: bool = False,
    mcap: Path | None = None,
    plot: Path | None = None,
    stdout: BinaryIO | None = None,
) -> int:
    """``srcsctl replay``: see the module docstring. ``mcap`` and ``plot`` name the files the
    window is exported to (SR-7.15, SR-7.16), written whatever the replay's verdict; ``-``
    writes to ``stdout`` (SR-11.4)."""
    refused = _refused_targets(mcap, plot, stdout)
    if refused is not None:
        print(f"srcsctl replay: {refused}", file=errors)
        return EXIT_BAD_INPUT
    out = _text_out(out, errors, mcap, plot)
    try:
        path = find_window(which, record)
        window = read_window(path)
    except (LookupError, FlightFormatError, OSError) as error:
        print(f"srcsctl replay: {error}", file=errors)
        return EXIT_BAD_INPUT
    record = record or record_of(path)
    after = window.base.get("after_seq")
    recorded, unread = recorded_records(record, after if isinstance(after, int) else 0)
    checked = window.seq in recorded  # the stop record is the record file's (SR-7.13)
    stop_ns = _header(window, out)
    contradicted = copy_differs(window, recorded)
    if contradicted:
        _copy_differs(window, record, contradicted, out)
    try:
        result: Replay = replay(window, recorded)
    except ReplayError as error:
        print(f"srcsctl replay: {error}", file=errors)
        return EXIT_BAD_INPUT
    except RecursionError:
        # A snapshot's state nested past the interpreter's limit: damaged (SR-7.13).
        print("srcsctl replay: the window cannot be replayed: nested too deep", file=errors)
        return EXIT_BAD_INPUT
    printer = _Printer(out, stop_ns, show_all, None if checked else window.seq)
    for step in result.steps:
        printer.step(step)
    printer.flush()
    if result.mismatch is not None:
        _mismatch(result.mismatch, result, printer, out)
    if mcap is not None or plot is not None:
        try:
            export.write_exports(window, result, out, mcap=mcap, plot=plot, stdout=stdout)
        except (OutputRefused, OSError) as error:
            print(f"srcsctl replay: {_write_failure(error)}", file=errors)
            return EXIT_BAD_INPUT
    if contradicted:
        out.write(
            f"the window is not the record's: its copy of stop record #{window.seq} says "
            f"otherwise than the record file in {', '.join(contradicted)}\n"
        )
        out.flush()
        return EXIT_NOT_THE_RECORD
    if result.mismatch is not None:
        out.flush()
        return EXIT_MISMATCH
    unchecked = f" ({result.not_compared} not in the record files)" if result.not_compared else ""
    if not checked:
        out.write(
            f"NOT CHECKED against the record file: {_copy_only(window, unread, record)}; the "
            f"replay reproduces only the window's own copy of the stop "
            f"{_record_line(window.stop)}, {result.compared} records compared{unchecked}\n"
        )
        out.flush()
        return EXIT_NOT_CHECKED
    out.write(
        f"replay matches the record: {result.compared} records compared{unchecked}; "
        f"the stop {_record_line(window.stop)} reproduced\n"
    )
    out.flush()
    return 0
