"""The robot's config file read into TOML values: any file, however hostile (missing,
unreadable, too large, not UTF-8, nested too deep, not TOML), is refused with a
:class:`~supervisord.errors.ConfigError` naming its line where it has one (SR-11.2).

Apart from the loader so that the clients' reader (:mod:`supervisord.config.client`) reads the
file with the same refusals without loading the safety core (SR-8.8).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Final

from supervisord.config import toml
from supervisord.config.nesting import MAX_DEPTH, too_deep
from supervisord.errors import ConfigError

_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)$")
MAX_CONFIG_BYTES: Final = 1 << 20
"""A robot's config is a few kB (the shipped examples: under 4 kB); a file larger than 1 MiB
is not one (``/dev/zero``, a log, an image) and is refused before it is parsed, so that the
daemon's start never waits on a parse of it or runs out of memory reading it (SR-11.2)."""


def read_at_most(source: Path) -> bytes:
    """The file's bytes, but never more than one beyond :data:`MAX_CONFIG_BYTES`: enough to
    see it is too large (``/dev/zero`` never ends)."""
    with source.open("rb") as file:
        return file.read(MAX_CONFIG_BYTES + 1)


def read_toml(source: Path) -> dict[str, object]:
    """The parsed file; a syntax error names its line and column (key ``line L, column C``)
    and carries the text of that line as the value."""
    return read_toml_text(source)[1]


def read_toml_text(
    source: Path, read: Callable[[Path], bytes] = read_at_most
) -> tuple[str, dict[str, object]]:
    """The file's text and what it parses to (:func:`read_toml`); ``read`` gives the file's
    bytes (``srcsd`` reads so that a stopping signal ends the wait), at most one beyond
    :data:`MAX_CONFIG_BYTES`. Any file, however hostile (too large, not UTF-8, not TOML,
    nested too deep), raises :class:`ConfigError`, with its line where it has one (SR-11.2)."""
    try:
        raw = read(source)
    except OSError as error:
        raise ConfigError(
            "file", str(source), f"give the path of a readable TOML file ({error.strerror})"
        ) from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(
            "file",
            str(source),
            f"give the robot's config: this file is larger than {MAX_CONFIG_BYTES} bytes "
            "(1 MiB), and a config is a few kB",
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        line = raw.count(b"\n", 0, error.start) + 1
        column = error.start - (raw.rfind(b"\n", 0, error.start) + 1) + 1
        raise ConfigError(
            f"line {line}, column {column}", raw[error.start : error.end], "save the file as UTF-8"
        ) from None
    deep = too_deep(text)
    if deep is not None:  # the parser would recurse past Python's limit (SR-11.2)
        start = text.rfind("\n", 0, deep) + 1
        end = text.find("\n", deep)
        raise ConfigError(
            f"line {text.count(chr(10), 0, deep) + 1}, column {deep - start + 1}",
            text[start : len(text) if end < 0 else end],
            f"nest arrays and tables at most {MAX_DEPTH} deep (a robot's config needs 3)",
        )
    try:
        return text, toml.loads(text)
    except toml.TOMLDecodeError as error:
        message = str(error)
        lines = text.splitlines() or [""]
        found = _POSITION.search(message)
        if found:
            line, column = int(found[1]), int(found[2])
        else:  # "(at end of document)"
            line, column = len(lines), len(lines[-1]) + 1
        reason = re.sub(r"\s*\(at [^)]*\)$", "", message)
        shown = lines[line - 1] if line <= len(lines) else ""
        raise ConfigError(
            f"line {line}, column {column}",
            shown,
            f"correct the TOML syntax there ({reason[:1].lower()}{reason[1:]})",
        ) from None
