"""``srcsctl decode``: a capture in, one JSON object per frame or rejection out.

Input is hex text (default), raw binary (``--raw``), candump lines (``--can``) or one HID
report per hex line (``--hid``). A line it cannot read is reported on stderr with its
number and skipped; decoding goes on, and the exit status is 2 at the end.
"""

from __future__ import annotations

import io
import json
import string
import sys
from collections.abc import Iterable, Iterator
from typing import IO, Any

from supervisord.protocol.framing import FrameDecoder, Rejection
from supervisord.protocol.hid import (
    INPUT_LENGTH,
    HidRejection,
    decode_hid_input,
    decode_hid_output,
)
from supervisord.protocol.j1939 import CanFrame, CanRejection, decode_can
from supervisord.protocol.jsonview import hid_json, message_json, rejection_json
from supervisord.protocol.payload import encode_payload

EXIT_BAD_INPUT = 2
_HEX = frozenset(string.hexdigits)
_RAW_CHUNK = 65536


class BadLine(ValueError):
    """A line of the capture that is not in the expected format."""


def parse_hex_line(line: str) -> bytes:
    """Bytes of one hex line: pairs of digits, optionally ``0x``-prefixed and separated by
    spaces, commas or colons; ``#`` starts a comment."""
    text = line.split("#", 1)[0].replace(",", " ").replace(":", " ")
    out = bytearray()
    for token in text.split():
        digits = token[2:] if token.lower().startswith("0x") else token
        if not digits or len(digits) % 2 or not _HEX.issuperset(digits):
            raise BadLine(f"not hex: {token!r}")
        out += bytes.fromhex(digits)
    return bytes(out)


def parse_candump_line(line: str) -> CanFrame | None:
    """One frame from ``ID#DATA``, ``(time) iface ID#DATA`` or ``iface ID [n] b0 b1 ..``."""
    text = line.split("#", 1)[0] if line.lstrip().startswith("#") else line
    tokens = text.split()
    if not tokens:
        return None
    framed = [token for token in tokens if "#" in token]
    try:
        if framed:
            ident_text, _, data_text = framed[-1].partition("#")
            data = bytes.fromhex(data_text) if data_text else b""
        else:  # candump's default format: can0  0CFDE801   [8]  09 00 ...
            at = next(i for i, token in enumerate(tokens) if token.startswith("["))
            ident_text = tokens[at - 1]
            data = bytes.fromhex("".join(tokens[at + 1 :]))
        if not ident_text or not _HEX.issuperset(ident_text):
            raise BadLine(f"not a CAN id: {ident_text!r}")
        return CanFrame(int(ident_text, 16), data, is_extended_id=len(ident_text) > 3)
    except (ValueError, StopIteration) as error:
        raise BadLine(f"not a candump frame: {line.strip()!r}") from error


def _frame_events(decoder: FrameDecoder, chunks: Iterable[bytes]) -> Iterator[dict[str, Any]]:
    offset = 0
    for chunk in chunks:
        for event in decoder.feed(chunk):
            yield _with_offset(event, offset)
            offset += event.byte_count if isinstance(event, Rejection) else _frame_size(event)
    for event in decoder.end():
        yield _with_offset(event, offset)


def _frame_size(message: Any) -> int:
    return 6 + len(encode_payload(message))


def _with_offset(event: Any, offset: int) -> dict[str, Any]:
    body = rejection_json(event) if isinstance(event, Rejection) else message_json(event)
    return {**body, "offset": offset}


class _Run:
    """One decode run: where the errors go and whether any occurred."""

    def __init__(self, source_name: str, errors: IO[str]) -> None:
        self.source_name, self.errors, self.failed = source_name, errors, False

    def bad(self, number: int, error: BadLine) -> None:
        self.failed = True
        print(f"srcsctl decode: {self.source_name}:{number}: {error}", file=self.errors)

    def hex_chunks(self, lines: Iterable[str]) -> Iterator[bytes]:
        for number, line in enumerate(lines, 1):
            try:
                yield parse_hex_line(line)
            except BadLine as error:
                self.bad(number, error)

    def can_objects(self, lines: Iterable[str]) -> Iterator[dict[str, Any]]:
        for number, line in enumerate(lines, 1):
            try:
                frame = parse_candump_line(line)
            except BadLine as error:
                self.bad(number, error)
                continue
            if frame is not None:
                result = decode_can(frame)
                body = (
                    rejection_json(result)
                    if isinstance(result, CanRejection)
                    else message_json(result)
                )
                yield {**body, "can_id": frame.arbitration_id, "line": number}

    def hid_objects(self, lines: Iterable[str]) -> Iterator[dict[str, Any]]:
        for number, line in enumerate(lines, 1):
            try:
                report = parse_hex_line(line)
            except BadLine as error:
                self.bad(number, error)
                continue
            if report:
                decoded = (
                    decode_hid_input(report)
                    if len(report) == INPUT_LENGTH
                    else decode_hid_output(report)
                )
                body = (
                    rejection_json(decoded)
                    if isinstance(decoded, HidRejection)
                    else hid_json(decoded)
                )
                yield {**body, "line": number}


def run_decode(path: str, mode: str, out: IO[str], errors: IO[str]) -> int:
    """Decode the capture at ``path`` (``-`` for stdin) in ``mode``; return the exit status."""
    run = _Run("<stdin>" if path == "-" else path, errors)
    try:
        binary: IO[bytes] = sys.stdin.buffer if path == "-" else open(path, "rb")  # noqa: SIM115
    except OSError as error:
        print(f"srcsctl decode: {run.source_name}: {error.strerror}", file=errors)
        return EXIT_BAD_INPUT
    # Text modes read undecodable bytes as U+FFFD, which then fails as "not hex" on its line.
    text = io.TextIOWrapper(binary, encoding="utf-8", errors="replace", newline=None)
    with binary:
        if mode == "raw":
            chunks = iter(lambda: binary.read(_RAW_CHUNK), b"")
            objects = _frame_events(FrameDecoder(), chunks)
        elif mode == "can":
            objects = run.can_objects(text)
        elif mode == "hid":
            objects = run.hid_objects(text)
        else:
            objects = _frame_events(FrameDecoder(), run.hex_chunks(text))
        for obj in objects:
            out.write(json.dumps(obj) + "\n")
        text.detach()
    return EXIT_BAD_INPUT if run.failed else 0
