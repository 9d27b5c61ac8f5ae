"""How ``srcsctl log`` and ``srcsctl fleet`` print records: ``-o``'s modes, one line per
record (:func:`~supervisord.cli.record_text.record_line`) or one JSON object, each line saying
what changed since the one before it. ``fleet`` puts the robot's name before each line and
keeps "the one before" per robot (docs/srcsctl.md "fleet")."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import IO, Any, Final

from supervisord.cli.record_text import record_line, written_line
from supervisord.cli.times import show_time
from supervisord.record.stop import StopRecord, read_written

NO_ENTRIES: Final = "-- No entries --"
"""What journalctl prints on stdout when nothing matched (not in a JSON mode, not following)."""
JSON_OUTPUTS: Final = frozenset({"json", "json-pretty"})


class RecordPrinter:
    """Prints records as lines (or JSON), each line saying what changed since the one
    before it of the same source (:attr:`previous`, for records that do not say it
    themselves). A source is ``None`` for ``log`` (one record file) and the robot's name for
    ``fleet``, written before the line (and as ``robot`` first in JSON)."""

    def __init__(self, out: IO[str], *, output: str, utc: bool, causes: bool) -> None:
        self.out, self.output, self.utc = out, output, utc
        self.causes = causes or output == "verbose"
        self.before: dict[str | None, StopRecord | None] = {}

    @property
    def previous(self) -> StopRecord | None:
        """The record before the next one of ``log``'s single source."""
        return self.before.get(None)

    @previous.setter
    def previous(self, data: Mapping[str, Any] | None) -> None:
        """The record before, as the file holds it (read here as the printed ones are)."""
        self.before[None] = None if data is None else read_written(data)

    def show(
        self,
        records: list[Mapping[str, Any]],
        *,
        reverse: bool = False,
        sources: list[str] | None = None,
        width: int = 0,
        heads: Sequence[Mapping[str, Any]] | None = None,
    ) -> None:
        """Print ``records`` (each source's in its own order); ``sources``: each one's robot,
        written in a column ``width`` wide (as the caller made it printable); ``heads``: the
        fields each JSON object starts with (``robot``: the source, without them). A line's
        record text is escaped by :func:`record_line` (SR-13.7); JSON escapes its own."""
        lines = []
        for index, data in enumerate(records):
            source = sources[index] if sources is not None else None
            if self.output in JSON_OUTPUTS:
                indent = 2 if self.output == "json-pretty" else None
                head = heads[index] if heads is not None else {"robot": source}
                shown = data if source is None else {**head, **data}
                lines.append(json.dumps(shown, indent=indent))
                continue
            record = read_written(data)  # typed; a line no typed record is shown as written
            utc = data.get("utc") if record is None else record.utc
            when = "" if self.output == "cat" else show_time(utc, utc=self.utc)
            if record is None:
                line = written_line(data, when)
            else:
                previous = self.before.get(source)
                line = record_line(record, when, previous=previous, causes=self.causes)
            line = line.lstrip() if self.output == "cat" else line
            lines.append(line if source is None else f"{source:{width}}  {line}")
            self.before[source] = record
        for line in reversed(lines) if reverse else lines:
            self.out.write(line + "\n")
        self.out.flush()  # a pipe sees each record as it comes (line by line, not at exit)
