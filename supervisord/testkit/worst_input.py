"""Request lines built to be slow for the code that reads a client's bytes in the loop
(SR-10.5), and that code's path for one line; for ``tests/api/test_worst_case_input.py`` and
``bench/client_input.py``.

Each family makes a line of exactly ``size`` bytes (no newline) from one pattern repeated: a
string that never closes, nesting, escapes, long runs of one character, many keys or
objects, long numbers. :func:`serve_line` is what the server does with a line it read
(``ApiServer._dispatch``): the parser, the SR-8.13 reader when the parser refuses it, and the
reply's line.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from supervisord.api.connection import server_line
from supervisord.api.requests import honoured_error, read_request
from supervisord.api.views import ok_reply


def _fill(head: bytes, unit: bytes, size: int, tail: bytes = b"") -> bytes:
    """``head``, ``unit`` repeated, ``tail``: ``size`` bytes, padded with spaces (JSON
    whitespace) before ``tail`` to the exact length."""
    room = size - len(head) - len(tail)
    if room < 0:
        raise ValueError(f"a line of {size} bytes cannot hold {head!r} and {tail!r}")
    body = unit * (room // len(unit))
    return head + body + b" " * (room - len(body)) + tail


LINES: Final[dict[str, Callable[[int], bytes]]] = {
    # Break 1: a quote, then escaped quotes, never closed (every quote began a scan).
    "escaped quotes": lambda n: _fill(b'"', b'\\"', n),
    # Nesting past the limit, then the same string: the nesting check scans strings too.
    "deep, then escaped quotes": lambda n: _fill(b'{"op":"estop",' + b"[" * 17 + b'"', b'\\"', n),
    "opening braces": lambda n: _fill(b"", b"{", n),
    "empty objects": lambda n: _fill(b"", b"{}", n),
    "mixed brackets": lambda n: _fill(b'{"op":', b"[{]}", n),
    "commas": lambda n: _fill(b'{"op":', b",", n),
    "empty strings": lambda n: _fill(b"{", b'""', n),
    "whitespace": lambda n: _fill(b"{", b" ", n, b'"op" : "hold" x'),
    # Every key in an op's place: each one read (a hold does not end the search).
    "op keys": lambda n: _fill(b"{", b'"op":"hold",', n),
    "escaped op keys": lambda n: _fill(b"{", b'"\\u006fp":"\\u0068old",', n),
    "unknown keys": lambda n: _fill(b'{"op":"status",', b'"key":1,"kez":1,', n, b'"k":1}'),
    "list of objects": lambda n: _fill(b'{"op":"status","id":[', b"{},", n, b"{}]}"),
    "long number": lambda n: _fill(b'{"op":"status","id":1', b"1", n, b"}"),
    "long fraction": lambda n: _fill(b'{"op":"status","id":1.', b"1", n, b"}"),
    "escaped text": lambda n: _fill(b'{"op":"hello","name":"', b"\\u00e9", n, b'"}'),
    "lone surrogates": lambda n: _fill(b'{"op":"status","', b"\\udfff", n, b'":1}'),
    "long op": lambda n: _fill(b'{"op":"', b"x", n, b'"}'),
    "not UTF-8": lambda n: _fill(b'{"op":"estop","x":"', b"\xff", n, b'"'),
}
"""Each worst-case family: a line of ``size`` bytes (at least 64)."""


def serve_line(line: bytes) -> bytes:
    """The reply line the server gives ``line`` when the daemon answers ok: the parser, the
    SR-8.13 reader for a refused line, the reply encoded (``ApiServer._dispatch``)."""
    request, error = read_request(line)
    if error is None:
        assert request is not None
        return server_line(ok_reply(request))
    return server_line(error if request is None else honoured_error(error, request))
