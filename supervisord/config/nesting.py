"""How deep a TOML text nests, measured on its text before it is parsed (SR-11.2).

The standard library's TOML parser recurses once per level of an array or inline table, and
what is done with the parsed values afterwards (the copy ``--check-config`` works on, the
messages that show a value) recurses too: 3,000 nested arrays raised ``RecursionError``, a
traceback where a refusal with a line belongs, and ``srcsd`` exited 1, which systemd restarts,
instead of 78. So a text that nests deeper than :data:`MAX_DEPTH` is refused at the place it
goes deeper, before anything recurses on it.

The depth counted is the depth of the tables and arrays the text builds: each open ``[`` of
an array and ``{`` of an inline table, each part of a dotted key (``a.b.c = 1`` is three
tables deep) and of a table header (``[a.b.c]``), added up along the way in. It is measured by
one pass that steps over strings and comments and knows where a key is written (at a line's
start, in a header, after an inline table's ``{`` or ``,``) and where a value is (after ``=``,
in an array), so that the ``.`` of ``1.5`` is no key part. It never decides what is valid
TOML: the parser does, on a text shallow enough to parse.
"""

from __future__ import annotations

import re
from typing import Final

MAX_DEPTH: Final = 32
"""Deeper than any robot's config goes by far (the shipped ones: 3, ``outputs[0].chip``),
and shallow enough for the parser and the checks to recurse on (about four calls of the
parser's per level, against Python's limit of 1,000)."""

_SIGNIFICANT: Final = re.compile(r"[\[\]{}=,.#\"'\n]")
_BASIC: Final = re.compile(r'"(?:[^"\\\n]|\\.)*"?')
_LITERAL: Final = re.compile(r"'[^'\n]*'?")
_ARRAY: Final = "["
_INLINE: Final = "{"
_HEADER: Final = "h"


class _Frame:
    """One open ``[``, ``{`` or header, and the key depth to go back to when it closes."""

    __slots__ = ("keys", "kind")

    def __init__(self, kind: str, keys: int) -> None:
        self.kind = kind
        self.keys = keys


class _Depth:
    """The pass of :func:`too_deep`: what is open at the cursor, and whether a key is being
    written there."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.frames: list[_Frame] = []
        self.header = 0  # the parts of the current table header, beyond the first
        self.keys = 0  # the parts of the dotted keys whose values are open, beyond the first
        self.in_key = True

    @property
    def depth(self) -> int:
        return self.header + self.keys + len(self.frames)

    def step(self, char: str, i: int) -> int:
        """Take the significant ``char`` at ``i``; returns where to look on from."""
        text = self.text
        if char in "\"'#":
            return _skipped(text, i)
        i += 1
        if char == "\n":
            if not self.frames:
                self.in_key, self.keys = True, 0
        elif char == "[":
            i += self.open_bracket(i)
        elif char == "{":
            self.frames.append(_Frame(_INLINE, self.keys))
            self.in_key = True
        elif char in "]}":
            i += self.close(i)
        elif char == "=":
            self.in_key = False
        elif char == ",":
            if self.frames and self.frames[-1].kind == _INLINE:
                self.in_key, self.keys = True, self.frames[-1].keys
        elif self.in_key:  # "." between the parts of a key
            if self.frames and self.frames[-1].kind == _HEADER:
                self.header += 1
            else:
                self.keys += 1
        return i

    def open_bracket(self, after: int) -> int:
        """An array, or a table header ([name] or [[name]]); returns the characters it takes
        beyond the ``[``."""
        if not self.frames and self.in_key:
            self.frames.append(_Frame(_HEADER, 0))
            self.header = 0
            return int(self.text.startswith("[", after))
        self.frames.append(_Frame(_ARRAY, self.keys))
        self.in_key = False
        return 0

    def close(self, after: int) -> int:
        """A ``]`` or ``}``; returns the characters it takes beyond it (``]]``)."""
        self.in_key = False
        if not self.frames:
            return 0
        closed = self.frames.pop()
        self.keys = closed.keys
        return int(closed.kind == _HEADER and self.text.startswith("]", after))


def too_deep(text: str, limit: int = MAX_DEPTH) -> int | None:
    """The index in ``text`` where its nesting first goes deeper than ``limit``, or ``None``
    when it never does."""
    state = _Depth(text)
    i = 0
    while (found := _SIGNIFICANT.search(text, i)) is not None:
        i = state.step(found.group(), found.start())
        if state.depth > limit:
            return found.start()
    return None


def _skipped(text: str, start: int) -> int:
    """The index after the comment or string that starts at ``start`` (any of TOML's four
    kinds of string); the text's or the line's end for one not closed (the parser says what
    is wrong with it)."""
    if text[start] == "#":
        end = text.find("\n", start)
        return len(text) if end < 0 else end
    for quote in ('"""', "'''"):
        if text.startswith(quote, start):
            end = start + 3
            while True:
                end = text.find(quote, end)
                if end < 0:
                    return len(text)
                if quote == '"""' and _escaped(text, end):
                    end += 1
                    continue
                end += 3
                # up to two more quotes are the string's own: """a"""" ends in a quote
                for _ in range(2):
                    end += text.startswith(quote[0], end)
                return end
    pattern = _BASIC if text[start] == '"' else _LITERAL
    found = pattern.match(text, start)
    assert found is not None  # the opening quote matches at least
    return found.end()


def _escaped(text: str, index: int) -> bool:
    """Whether the character at ``index`` follows an odd number of backslashes."""
    count = 0
    while index - count - 1 >= 0 and text[index - count - 1] == "\\":
        count += 1
    return count % 2 == 1
