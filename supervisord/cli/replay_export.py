"""``srcsctl replay --mcap`` and ``--plot``: the window written for viewing tools (SR-7.15,
SR-7.16; ``docs/record.md`` "Looking at a stop"). Wiring only: the signals are
:mod:`supervisord.record.timeline`'s, the file formats :mod:`supervisord.record.mcap_export`'s
and :mod:`supervisord.record.stop_picture`'s.

A file is written by :mod:`supervisord.cli.output_file` (SR-11.4): a new file of a random name
beside it, opened exclusively without following a link, renamed into place (a reader sees a
whole file or none); ``-`` is standard output; a link or a device at the name is refused.
The MCAP library is imported only here, and only when asked for; the robot's and the
collector's package carry it, without the compression libraries it names (the file is
written uncompressed), and the picture needs nothing.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import IO, BinaryIO, Final

from supervisord.cli.output_file import is_standard_output, write_output
from supervisord.record.flight import LoadedWindow
from supervisord.record.replay import Replay
from supervisord.record.stop_picture import stop_picture
from supervisord.record.timeline import Timeline, timeline

MCAP_MISSING: Final = (
    "the mcap package is missing from this installation, which carries it (a robot's in "
    "/opt/srcsd, a collector's in /opt/srcs-collector, a desk's in the source tree's .venv): "
    "install its package again, or run the srcsctl of ./dev's .venv"
)


def mcap_available() -> bool:
    return importlib.util.find_spec("mcap") is not None


def _name(path: Path) -> str:
    return "standard output" if is_standard_output(path) else str(path)


def write_exports(
    window: LoadedWindow,
    result: Replay,
    out: IO[str],
    *,
    mcap: Path | None = None,
    plot: Path | None = None,
    stdout: BinaryIO | None = None,
) -> Timeline:
    """Write the MCAP file and the picture asked for (``-``: to ``stdout``); one line each on
    ``out``. Raises ``OutputRefused`` or ``OSError`` (``output_file``)."""
    made = timeline(window, result)
    if mcap is not None:
        from supervisord.record.mcap_export import export_mcap  # noqa: PLC0415 - only when asked for

        write_output(mcap, lambda file: export_mcap(made, file), stdout)
        messages = sum(len(signal.samples) for signal in made.signals.values())
        out.write(f"mcap: wrote {_name(mcap)}: {len(made.signals)} channels, {messages} messages\n")
    if plot is not None:
        picture = stop_picture(made)
        write_output(plot, lambda file: file.write(picture.svg.encode()), stdout)
        out.write(f"plot: wrote {_name(plot)}: {picture.width}x{picture.height} px\n")
    return made
