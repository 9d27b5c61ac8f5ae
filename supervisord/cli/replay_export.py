"""``srcsctl replay --mcap`` and ``--plot``: the window written for viewing tools (SR-7.15,
SR-7.16; ``docs/record.md`` "Looking at a stop"). Wiring only: the signals are
:mod:`supervisord.record.timeline`'s, the file formats :mod:`supervisord.record.mcap_export`'s
and :mod:`supervisord.record.stop_picture`'s.

A file is written to a temporary name beside it and renamed into place: a reader sees a whole
file or none. The MCAP library is imported only here, and only when asked for: it is the
``export`` extra, which the robot's package leaves out (the picture needs nothing).
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import IO, Final

from supervisord.record.flight import LoadedWindow
from supervisord.record.replay import Replay
from supervisord.record.stop_picture import stop_picture
from supervisord.record.timeline import Timeline, timeline

MCAP_MISSING: Final = (
    "the mcap package is not installed; install the export extra "
    "(pip install 'srcs-supervisord[export]') where the window is looked at"
)


def mcap_available() -> bool:
    return importlib.util.find_spec("mcap") is not None


def _write(path: Path, fill: Callable[[IO[bytes]], object]) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        with temporary.open("wb") as file:
            fill(file)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def write_exports(
    window: LoadedWindow,
    result: Replay,
    out: IO[str],
    *,
    mcap: Path | None = None,
    plot: Path | None = None,
) -> Timeline:
    """Write the MCAP file and the picture asked for; one line each on ``out``."""
    made = timeline(window, result)
    if mcap is not None:
        from supervisord.record.mcap_export import export_mcap  # noqa: PLC0415 - the export extra, asked for

        _write(mcap, lambda file: export_mcap(made, file))
        messages = sum(len(signal.samples) for signal in made.signals.values())
        out.write(f"mcap: wrote {mcap}: {len(made.signals)} channels, {messages} messages\n")
    if plot is not None:
        picture = stop_picture(made)
        _write(plot, lambda file: file.write(picture.svg.encode()))
        out.write(f"plot: wrote {plot}: {picture.width}x{picture.height} px\n")
    return made
