"""Text from another party, made safe for a terminal (SR-13.7): every character a terminal
would act on, or that would hide or reorder what is around it, shown as its escape.

A record's text comes from another machine (a robot's upload at a fleet's collector) or a
file (a record file copied from a robot): its cause names, details, reason, trigger and
states are another party's bytes. Printed raw, an ESC or CSI retitles, clears and recolours
the operator's terminal, a CR or a newline writes over a line or forges another robot's, and a
bidi override reorders what follows it on the line. :func:`printable` is the one function
every such text goes through before ``srcsctl`` writes it to a terminal.
"""

from __future__ import annotations

import unicodedata
from typing import Final

ESCAPED_CATEGORIES: Final = frozenset({"Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"})
"""Unicode's categories shown escaped: controls (C0, DEL, C1: ESC, CR, LF, the 8-bit CSI
U+009B), format characters (the bidi embeddings, overrides and isolates U+202A-202E and
U+2066-2069, the marks U+200E/200F/061C, zero-width characters, U+FEFF), lone surrogates (an
undecodable byte kept by ``surrogateescape``), private-use and unassigned code points (what a
terminal does with them is its own), and the line and paragraph separators U+2028/2029."""
_SHORT: Final = {"\\": "\\\\", "\t": "\\t", "\n": "\\n", "\r": "\\r"}


def _escape(char: str) -> str:
    short = _SHORT.get(char)
    if short is not None:
        return short
    code = ord(char)
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def printable(text: str) -> str:
    """``text`` with every character of :data:`ESCAPED_CATEGORIES` shown as its escape
    (``\\x1b``, ``\\r``, ``\\u202e``) and the backslash as ``\\\\``, so that two texts are
    never shown alike; every other character (letters of any script, spaces, punctuation) as
    it is. Character by character: a line built of our own words and such texts, escaped
    whole, is the line of the texts escaped one by one. Linear in the text's length."""
    if text.isascii() and text.isprintable() and "\\" not in text:
        return text  # the common case, without a look at each character
    return "".join(
        _escape(c) if c in _SHORT or unicodedata.category(c) in ESCAPED_CATEGORIES else c
        for c in text
    )
