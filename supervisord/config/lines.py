"""Where each key of a TOML file is written: its line and column, for ``--check-config``.

The standard library's parser gives a position only for a syntax error, never for a key, so
the text is scanned once more, after it parsed: every table header (``[vsc]``,
``[[outputs]]``, the second of which is ``outputs[1]``) and every key under it, dotted keys
(``vsc.timeout_ms = 200``) and the keys of inline tables (``vsc = { timeout_ms = 200 }``)
included, each under its full key path, the path the loader names in its errors
(``outputs[1].chip``). Strings (multi-line ones too) and arrays spanning lines are stepped
over, so that a ``[`` or ``x =`` inside them is never taken for a header or a key.

A key that is not in the file (a required key left out) is placed at its table's header, the
place to add it; a key the scan cannot place at all (none of its tables is written) has no
line. The scan never decides what is valid: the loader does, on the parsed values.
"""

from __future__ import annotations

import bisect
import re
from typing import Final

KeyPath = tuple[str | int, ...]
"""A key's path: ``("outputs", 1, "chip")`` for ``outputs[1].chip``."""
Position = tuple[int, int]
"""Line and column, both from 1."""

_BARE: Final = re.compile(r"[A-Za-z0-9_-]+")
_PART: Final = re.compile(r"([^.\[\]]+)((?:\[\d+\])*)")
_INDEX: Final = re.compile(r"\[(\d+)\]")


def key_path(key: str) -> KeyPath | None:
    """The path of a loader's key name (``outputs[1].chip``), or ``None`` for a name that is
    not a key path (``line 3, column 5``, ``file``)."""
    if not key or " " in key:
        return None
    path: list[str | int] = []
    for part in key.split("."):
        found = _PART.fullmatch(part)
        if found is None:
            return None
        path.append(found.group(1))
        path += [int(index) for index in _INDEX.findall(found.group(2))]
    return tuple(path)


def position(positions: dict[KeyPath, Position], path: KeyPath) -> Position | None:
    """Where ``path`` is written, else where its nearest written table is, else ``None``."""
    for end in range(len(path), 0, -1):
        found = positions.get(path[:end])
        if found is not None:
            return found
    return None


class _Scanner:
    """One pass over a TOML text that parsed: the position of every header and key."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.i = 0
        self.starts = [0] + [m.end() for m in re.finditer("\n", text)]
        self.found: dict[KeyPath, Position] = {}
        self.arrays: dict[KeyPath, int] = {}  # each array of tables: how many so far

    def at(self, index: int) -> Position:
        line = bisect.bisect_right(self.starts, index)
        return line, index - self.starts[line - 1] + 1

    def note(self, path: KeyPath, index: int) -> None:
        self.found.setdefault(path, self.at(index))

    def peek(self, length: int = 1) -> str:
        return self.text[self.i : self.i + length]

    def blank(self, *, newlines: bool) -> None:
        """Step over spaces (and line ends and comments when ``newlines``)."""
        while self.i < len(self.text):
            char = self.text[self.i]
            if char in " \t" or (newlines and char in "\r\n"):
                self.i += 1
            elif newlines and char == "#":
                end = self.text.find("\n", self.i)
                self.i = len(self.text) if end < 0 else end
            else:
                return

    def string(self) -> str:
        """A string at the cursor (any of the four kinds); returns its text, roughly (escapes
        left as written: only key names use it, and they rarely have escapes)."""
        for quote in ('"""', "'''"):
            if self.peek(3) == quote:
                start = self.i + 3
                end = start
                while True:
                    end = self.text.index(quote, end)
                    if quote == '"""' and _escaped(self.text, end):
                        end += 1
                        continue
                    break
                while self.text[end + 3 : end + 4] == quote[0]:  # """a"""" ends in a quote
                    end += 1
                self.i = end + 3
                return self.text[start:end]
        quote = self.peek()
        start = end = self.i + 1
        while True:
            end = self.text.index(quote, end)
            if quote == '"' and _escaped(self.text, end):
                end += 1
                continue
            break
        self.i = end + 1
        return self.text[start:end]

    def dotted_key(self) -> list[str]:
        parts = []
        while True:
            self.blank(newlines=False)
            if self.peek() in ('"', "'"):
                parts.append(self.string())
            else:
                bare = _BARE.match(self.text, self.i)
                if bare is None:
                    raise ValueError(f"no key at {self.at(self.i)}")
                parts.append(bare.group())
                self.i = bare.end()
            self.blank(newlines=False)
            if self.peek() != ".":
                return parts
            self.i += 1

    def resolve(self, parts: list[str]) -> KeyPath:
        """A header's names as a key path: a name that is an array of tables so far stands
        for its latest table (``[outputs.extra]`` after ``[[outputs]]``)."""
        path: KeyPath = ()
        for part in parts:
            path = (*path, part)
            if path in self.arrays:
                path = (*path, self.arrays[path] - 1)
        return path

    def header(self) -> KeyPath:
        start = self.i
        many = self.peek(2) == "[["
        self.i += 2 if many else 1
        parts = self.dotted_key()
        self.i += 2 if many else 1
        if many:
            array = (*self.resolve(parts[:-1]), parts[-1])
            self.note(array, start)
            count = self.arrays.get(array, 0)
            self.arrays[array] = count + 1
            table: KeyPath = (*array, count)
        else:
            table = self.resolve(parts)
        self.note(table, start)
        return table

    def pair(self, table: KeyPath) -> None:
        """``key = value``: the key and every prefix of a dotted key, then the value."""
        start = self.i
        parts = self.dotted_key()
        for end in range(1, len(parts) + 1):
            self.note((*table, *parts[:end]), start)
        self.blank(newlines=False)
        self.i += 1  # "="
        self.value((*table, *parts))

    def value(self, path: KeyPath) -> None:
        self.blank(newlines=False)
        char = self.peek()
        if char in ('"', "'"):
            self.string()
        elif char == "[":
            self.i += 1
            while True:
                self.blank(newlines=True)
                if self.peek() == "]":
                    self.i += 1
                    return
                self.value(path)
                self.blank(newlines=True)
                if self.peek() == ",":
                    self.i += 1
        elif char == "{":
            self.i += 1
            while True:
                self.blank(newlines=True)
                if self.peek() == "}":
                    self.i += 1
                    return
                self.pair(path)
                self.blank(newlines=True)
                if self.peek() == ",":
                    self.i += 1
        else:
            scalar = re.compile(r"[^,\]}#\r\n]*").match(self.text, self.i)
            assert scalar is not None  # matches the empty string at worst
            self.i = scalar.end()

    def scan(self) -> dict[KeyPath, Position]:
        table: KeyPath = ()
        while True:
            self.blank(newlines=True)
            if self.i >= len(self.text):
                return self.found
            before = self.i
            if self.peek() == "[":
                table = self.header()
            else:
                self.pair(table)
            if self.i <= before:  # never twice at one place, whatever the text
                raise ValueError(f"stuck at {self.at(self.i)}")


def _escaped(text: str, index: int) -> bool:
    """Whether the character at ``index`` follows an odd number of backslashes."""
    count = 0
    while index - count - 1 >= 0 and text[index - count - 1] == "\\":
        count += 1
    return count % 2 == 1


def key_positions(text: str) -> dict[KeyPath, Position]:
    """The position of every header and key of ``text`` (a TOML text that parsed), by key
    path. A text the scan does not follow to its end (a form it does not know) gives the
    positions found up to there."""
    scanner = _Scanner(text)
    try:
        return scanner.scan()
    except (ValueError, IndexError):
        return scanner.found
