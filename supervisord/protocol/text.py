"""Text that every encoder takes, and digits that are digits (SR-8.7, ``docs/safety.md``
"No input can raise").

A Python ``str`` can hold what no encoder writes: a lone surrogate (``"\\ud800"`` in JSON, or
an undecodable byte of a name from the password database, which Python carries as
``"\\udce9"``). Every text that comes from outside (a client, the VSC, a user account) and
reaches a reply, a push, the record or the journal goes through :func:`clean` at its source,
so that no encoder in the loop can raise. ``str.isdigit`` takes ``"²"`` and ``int``/``float``
take non-ASCII digits, signs, underscores and padding: parsers of wire text use
:func:`ascii_digits` instead.

Pure: no imports, no I/O (the safety core may use it).
"""

from __future__ import annotations

from typing import Final

_SURROGATES: Final = range(0xD800, 0xE000)
_ESCAPED_BYTES: Final = range(0xDC80, 0xDD00)  # what "surrogateescape" makes of bytes 0x80-0xFF


def is_clean(text: str) -> bool:
    """Whether ``text`` encodes as UTF-8 (it holds no lone surrogate)."""
    if text.isascii():
        return True
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def clean(text: str) -> str:
    """``text`` as any encoder takes it: unchanged when it encodes as UTF-8, else each lone
    surrogate written out as visible text: ``\\xe9`` for a byte that was not UTF-8 (Python's
    ``surrogateescape``), ``\\ud800`` for any other. A name shown escaped stays recognisable
    (``r\\xe9mi``) and can never be mistaken for a valid one of the same letters."""
    if is_clean(text):
        return text
    out = []
    for ch in text:
        code = ord(ch)
        if code in _ESCAPED_BYTES:
            out.append(f"\\x{code - 0xDC00:02x}")
        elif code in _SURROGATES:
            out.append(f"\\u{code:04x}")
        else:
            out.append(ch)
    return "".join(out)


def clean_json(value: object) -> object:
    """A copy of a JSON-ready value (dicts, lists, tuples, text, numbers) with every text,
    keys included, passed through :func:`clean`. Other values are returned as they are, for
    the encoder to refuse (they are our own mistake, not input)."""
    if isinstance(value, str):
        return clean(value)
    if isinstance(value, dict):
        return {(clean(k) if isinstance(k, str) else k): clean_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean_json(v) for v in value]
    return value


def ascii_digits(text: str) -> bool:
    """Whether ``text`` is one or more of the ASCII digits 0-9 and nothing else: no ``²``,
    no other script's digits, no sign, underscore or whitespace (which ``int`` accepts)."""
    return text.isascii() and text.isdigit()
