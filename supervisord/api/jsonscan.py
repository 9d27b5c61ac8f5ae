"""Scans of a request line's JSON text that run before or instead of the parser (SR-8.13,
SR-10.5): each costs time linear in the line, whatever its bytes, and mostly at C speed;
sans-IO.

A JSON string is ``"`` then any character but ``"`` and ``\\`` or a ``\\`` and the character
after it (not a newline), then ``"``. Looking for one from every ``"`` of a line, as a
regular expression's search does, is quadratic when a string never closes: ``"\\"\\"\\"...``
tries the rest of the line from each of its quotes (a 64 KiB line took 10 s in the loop). It
need not: when the string that starts at a quote never closes, every quote before the place
its scan stopped is the second character of an escape pair of that scan, so a string started
there walks the same pairs to the same place and does not close either. So the scans here
take a string that never closes as one piece, up to where its scan stopped, and go on from
there: each byte is looked at a bounded number of times.

:func:`brackets_outside_strings` serves the nesting check before the parser; :func:`op_in_broken`
reads the op of a line the parser refused (SR-8.13, :func:`supervisord.api.requests.readable_stop`).
Both find exactly the strings and tokens the quadratic search found
(``tests/api/test_worst_case_input.py`` compares them).
"""

from __future__ import annotations

import re
from itertools import compress, count
from typing import Final

STOP_OP_NAMES: Final = ("estop", "hold")
"""The ops honoured in a broken line, the first winning when a line names both (SR-8.13)."""

_WS: Final = rb"[ \t\r\n]*"  # JSON's whitespace, the only bytes allowed between tokens here
# A JSON string after its opening quote: the unrolled form of (?:[^"\\]|\\.)*, whose own scan
# never looks back. Every pattern here starts with the quote, outside any group, so that the
# search skips to the next quote at C speed.
_REST: Final = rb'[^"\\]*(?:\\.[^"\\]*)*'
# After the closing quote's alternative at the same quote: a string that never closed, as one
# piece up to where its scan stopped (the end of the line, or a "\\" before a newline).
_UNCLOSED: Final = rb"(" + _REST + rb")"


def _form(text: str) -> bytes:
    """A pattern of every JSON string token that stands for ``text`` (ASCII letters), after
    its opening quote: each character as itself or as a ``\\uXXXX`` escape, its hex digits
    in either case. JSON has no other way to write a letter, so a token stands for ``text``
    exactly when it matches."""
    chars = []
    for char in text:
        escape = "".join(f"[{d}{d.upper()}]" if d.isalpha() else d for d in f"{ord(char):04x}")
        chars.append(f"(?:{char}|\\\\u{escape})")
    return ("".join(chars) + '"').encode()


# One scan of a line, left to right, each match at a quote outside any string: a key "op",
# ":" and a stop op, only whitespace between (groups 1 and 2: a candidate, if the key is in a
# key's place), a whole string, a string that never closed (group 3).
_CANDIDATE: Final = _form("op") + _WS + rb":" + _WS + rb'"'  # then the op's own form
_SCAN: Final = re.compile(
    rb'"(?:'
    + b"|".join(
        [
            *(rb"(" + _CANDIDATE + _form(op) + rb")" for op in STOP_OP_NAMES),
            _REST + rb'"',
            _UNCLOSED,
        ]
    )
    + rb")"
)
_PER_MATCH: Final = len(STOP_OP_NAMES) + 2  # split's items per match: the text before, groups
_STRINGS: Final = re.compile(rb'"(?:' + _REST + rb'"|' + _UNCLOSED + rb")")
_KEY_PLACE: Final = (b"{", b",")  # the token before a key
_WHITESPACE: Final = b" \t\r\n"

_NOT_BRACKETS: Final = bytes(sorted(set(range(256)) - set(b"{}[]")))
_OPEN_OBJECT, _OPEN_ARRAY = 0x7B, 0x5B


def brackets_outside_strings(line: bytes) -> bytes:
    """The brackets of ``line`` that are no part of a whole JSON string, in order (those after
    a quote whose string never closes count). Linear (module docstring)."""
    return b"".join(filter(None, _STRINGS.split(line))).translate(None, _NOT_BRACKETS)


def op_in_broken(line: bytes) -> str | None:
    """``estop`` or ``hold`` when a key ``"op"`` of the outermost object of ``line`` is
    followed by ``:`` and that text as a whole string, only JSON whitespace between (escapes
    read as what they stand for); ``estop`` when both are named. Linear (module docstring).

    The line is read as JSON tokens: whole strings, and ``{ } [ ] : ,`` outside them; what is
    between tokens is skipped. A quote whose string never closes is no token, and the
    brackets after it still count.

    One split at C speed finds every string and every candidate (``_SCAN``); then, for each
    candidate whose key is in a key's place, the nesting is brought up to date from the text
    outside strings since the one before: a bounded step per candidate, each byte taken once."""
    parts = _SCAN.split(line)
    for group, op in enumerate(STOP_OP_NAMES, start=1):  # the e-stop first: it wins
        nesting = _Nesting()
        done = 0  # parts[:done] are in ``nesting``
        for match in compress(count(), parts[group::_PER_MATCH]):
            before = match * _PER_MATCH  # the text between the last match and this one
            if not parts[before].rstrip(_WHITESPACE).endswith(_KEY_PLACE):
                continue  # the key is not in a key's place: after a string, or first
            # Outside whole strings up to the key (the candidates hold no bracket).
            nesting.take(b"".join(filter(None, parts[done : before + 1])))
            done = before + 1
            if nesting.outermost_object():
                return op
    return None


class _Nesting:
    """The brackets open outside strings, as the stack of a reader that ignores a closing
    bracket with nothing open: only its height and its bottom bracket are kept, all that
    "the outermost object" asks (SR-8.13)."""

    __slots__ = ("bottom", "height")

    def __init__(self) -> None:
        self.height = 0
        self.bottom = 0  # the bracket at the bottom of the stack (when height > 0)

    def outermost_object(self) -> bool:
        return self.height == 1 and self.bottom == _OPEN_OBJECT

    def take(self, text: bytes) -> None:
        """The brackets of ``text`` (read outside any string), in order."""
        brackets = text.translate(None, _NOT_BRACKETS)
        if not brackets:
            return
        closing = brackets.count(b"}") + brackets.count(b"]")
        if not closing:  # only openings: a run of "{{{{" costs no loop
            if not self.height:
                self.bottom = brackets[0]
            self.height += len(brackets)
        elif closing == len(brackets):
            self.height = max(0, self.height - closing)
        else:
            height, bottom = self.height, self.bottom
            for bracket in brackets:  # one step per bracket: linear
                if bracket in (_OPEN_OBJECT, _OPEN_ARRAY):
                    if not height:
                        bottom = bracket
                    height += 1
                elif height:
                    height -= 1
            self.height, self.bottom = height, bottom
