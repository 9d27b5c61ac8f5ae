"""``srcsctl decode``: a capture in, one JSON object per frame or rejection out.

Input is hex text (default), raw binary (``--raw``), CAN frames (``--can``: candump lines, or
a file in one of python-can's formats) or one HID report per hex line (``--hid``); with
``--follow``, a live serial port (``--raw``) or CAN interface (``--can``), read-only. A line
it cannot read is reported on stderr with its number and skipped; decoding goes on, and the
exit status is 2 at the end. Every object is written and flushed as soon as it is decoded,
so a pipe (``candump -L can0 | srcsctl decode --can``) shows frames as they come.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import string
import sys
from collections.abc import Iterable, Iterator
from typing import IO, Any

import can
import serial

from supervisord.cli import capture
from supervisord.cli.interrupt import interruptible
from supervisord.protocol.framing import FrameDecoder, Rejection
from supervisord.protocol.hid import (
    INPUT_LENGTH,
    HidRejection,
    decode_hid_input,
    decode_hid_output,
)
from supervisord.protocol.j1939 import CAN_ID_MASK, CanFrame, CanRejection, decode_can
from supervisord.protocol.jsonview import hid_json, message_json, rejection_json
from supervisord.protocol.payload import encode_payload

EXIT_BAD_INPUT = 2
_HEX = frozenset(string.hexdigits)
_RAW_CHUNK = 65536
CAN_ERR_FLAG = 0x2000_0000  # SocketCAN's error-frame flag in a candump id (linux/can.h)


class BadLine(ValueError):
    """A line of the capture that is not in the expected format."""


def run(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    """Run ``srcsctl decode`` with its parsed arguments; return the exit status."""
    # Ctrl-C and SIGTERM end decode (exit 0, the lines so far out) also when it was started
    # with SIGINT ignored, as a background job of a script is: Python then installs no
    # handler, and a live pipe's decode ignored the SIGINT for ever (SR-8.9).
    try:
        interruptible()
        return _run(args, out, errors)
    except KeyboardInterrupt:  # one that came before the reading began
        return 0
    except BrokenPipeError:
        # The reader of the output went away (``| head -1``): a finished job, not a fault.
        # Python would flush stdout again at exit and print a traceback; point it at
        # /dev/null first (the Python documentation's advice for SIGPIPE).
        with contextlib.suppress(OSError, ValueError, io.UnsupportedOperation):
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, out.fileno())
        return 0


def _run(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    if args.follow:
        if args.mode not in ("raw", "can") or args.file == "-":
            print(
                "srcsctl decode: --follow needs --raw PORT or --can CHANNEL",
                file=errors,
            )
            return EXIT_BAD_INPUT
        return run_follow(args.file, args.mode, args.interface, out, errors)
    return run_decode(args.file, args.mode, out, errors)


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


def parse_candump_line(line: str) -> tuple[can.Message, float | None] | None:
    """One frame and its time from ``ID#DATA``, ``(time) iface ID#DATA`` or ``(time) iface
    ID [n] b0 ..`` (the time is optional in each, None when absent). ``ID#R`` is a remote
    frame and an id with SocketCAN's error flag an error frame."""
    text = line.split("#", 1)[0] if line.lstrip().startswith("#") else line
    tokens = text.split()
    if not tokens:
        return None
    timestamp: float | None = None
    try:
        if tokens[0].startswith("(") and tokens[0].endswith(")"):
            timestamp = float(tokens.pop(0)[1:-1])
        framed = [token for token in tokens if "#" in token]
        remote = False
        if framed:
            ident_text, _, data_text = framed[-1].partition("#")
            remote = data_text.upper().startswith("R")
            data = b"" if remote else bytes.fromhex(data_text)
        else:  # candump's default format: can0  0CFDE801   [8]  09 00 ...
            at = next(i for i, token in enumerate(tokens) if token.startswith("["))
            ident_text = tokens[at - 1]
            remote = "remote" in tokens[at + 1 :]
            data = b"" if remote else bytes.fromhex("".join(tokens[at + 1 :]))
        if not ident_text or not _HEX.issuperset(ident_text):
            raise BadLine(f"not a CAN id: {ident_text!r}")
        ident = int(ident_text, 16)
        if len(ident_text) > 3 and ident > CAN_ID_MASK | CAN_ERR_FLAG:
            raise BadLine(f"not a CAN id: {ident_text!r}")
        error_frame = len(ident_text) > 3 and bool(ident & CAN_ERR_FLAG)
        return can.Message(
            timestamp=0.0 if timestamp is None else timestamp,
            arbitration_id=ident & CAN_ID_MASK,
            is_extended_id=len(ident_text) > 3,
            is_remote_frame=remote,
            is_error_frame=error_frame,
            data=data,
            # candump lines carry up to 64 bytes (CAN FD); the decoder rejects over 8.
            is_fd=len(data) > 8,
            check=False,
        ), timestamp
    except (ValueError, StopIteration, IndexError, TypeError) as error:
        if isinstance(error, BadLine):
            raise
        raise BadLine(f"not a candump frame: {line.strip()!r}") from error


def can_json(message: can.Message) -> dict[str, Any]:
    """The JSON object of one CAN frame however it was captured: the SRCS message or the
    rejection, then ``can_id``. Error and remote frames are rejections with their own reason
    (no SRCS message is either); so is a frame of more than 8 bytes (CAN FD)."""
    ident, length = message.arbitration_id, len(message.data)
    reason = (
        "error_frame"
        if message.is_error_frame
        else "remote_frame"
        if message.is_remote_frame
        else "wrong_length"
        if length > 8
        else None
    )
    if reason is not None:
        body: dict[str, Any] = {"type": "rejected", "reason": reason, "length": length}
    else:
        try:
            frame = CanFrame(ident, bytes(message.data), message.is_extended_id)
        except ValueError:  # an id beyond 11 or 29 bits: no reader of ours makes one
            body = {"type": "rejected", "reason": "bad_value", "length": length}
        else:
            result = decode_can(frame)
            body = (
                rejection_json(result) if isinstance(result, CanRejection) else message_json(result)
            )
    return {**body, "can_id": ident}


def _frame_events(
    decoder: FrameDecoder, chunks: Iterable[tuple[float | None, bytes]]
) -> Iterator[dict[str, Any]]:
    """Serial objects with their stream offsets; with a time per chunk (``--follow``), each
    also gets the ``capture_time`` of the chunk that completed it."""
    offset = 0
    for when, chunk in chunks:
        for event in decoder.feed(chunk):
            yield _with_offset(event, offset, when)
            offset += event.byte_count if isinstance(event, Rejection) else _frame_size(event)
    for event in decoder.end():
        yield _with_offset(event, offset, None)


def _frame_size(message: Any) -> int:
    return 6 + len(encode_payload(message))


def _with_offset(event: Any, offset: int, when: float | None) -> dict[str, Any]:
    body = rejection_json(event) if isinstance(event, Rejection) else message_json(event)
    timed = {} if when is None else {"capture_time": when}
    return {**body, **timed, "offset": offset}


class _Run:
    """One decode run: where the errors go and whether any occurred."""

    def __init__(self, source_name: str, errors: IO[str]) -> None:
        self.source_name, self.errors, self.failed = source_name, errors, False

    def bad(self, number: int, error: BadLine) -> None:
        self.failed = True
        print(f"srcsctl decode: {self.source_name}:{number}: {error}", file=self.errors)

    def fail(self, problem: str) -> None:
        self.failed = True
        print(f"srcsctl decode: {self.source_name}: {problem}", file=self.errors)

    def hex_chunks(self, lines: Iterable[str]) -> Iterator[tuple[float | None, bytes]]:
        for number, line in enumerate(lines, 1):
            try:
                yield None, parse_hex_line(line)
            except BadLine as error:
                self.bad(number, error)

    def can_objects(self, lines: Iterable[str]) -> Iterator[dict[str, Any]]:
        for number, line in enumerate(lines, 1):
            try:
                parsed = parse_candump_line(line)
            except BadLine as error:
                self.bad(number, error)
                continue
            if parsed is not None:
                message, when = parsed
                yield {**can_json(message), "capture_time": when, "line": number}

    def log_objects(self, path: str) -> Iterator[dict[str, Any]]:
        """python-can's formats: the reader's timestamp is the capture's time."""
        try:
            for number, message in enumerate(capture.read_log(path), 1):
                yield {**can_json(message), "capture_time": message.timestamp, "frame": number}
        except capture.CaptureError as error:
            self.fail(str(error))

    def follow_objects(self, messages: Iterable[can.Message]) -> Iterator[dict[str, Any]]:
        for number, message in enumerate(messages, 1):
            yield {**can_json(message), "capture_time": message.timestamp, "frame": number}

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


def _write(objects: Iterable[dict[str, Any]], out: IO[str]) -> None:
    """One JSON line per object, flushed at once: a pipe's reader sees each frame as it is
    decoded, not when a block buffer fills."""
    for obj in objects:
        out.write(json.dumps(obj) + "\n")
        out.flush()


def run_decode(path: str, mode: str, out: IO[str], errors: IO[str]) -> int:
    """Decode the capture at ``path`` (``-`` for stdin) in ``mode``; return the exit status."""
    run = _Run("<stdin>" if path == "-" else path, errors)
    if mode == "can" and path != "-" and capture.log_suffix(path) is not None:
        try:
            _write(run.log_objects(path), out)
        except BrokenPipeError:
            raise  # our output's reader left: see run()
        except OSError as error:
            run.fail(error.strerror or str(error))
        return EXIT_BAD_INPUT if run.failed else 0
    try:
        binary: IO[bytes] = sys.stdin.buffer if path == "-" else open(path, "rb")  # noqa: SIM115
    except OSError as error:
        run.fail(error.strerror or str(error))
        return EXIT_BAD_INPUT
    # Text modes read undecodable bytes as U+FFFD, which then fails as "not hex" on its line.
    # TextIOWrapper fills its buffer with read1, which returns what a pipe holds, so lines
    # are decoded as they arrive.
    text = io.TextIOWrapper(binary, encoding="utf-8", errors="replace", newline=None)
    with binary:
        if mode == "raw":
            # read1, not read: read blocks until 64 KiB or the end of a pipe.
            read1 = getattr(binary, "read1", binary.read)
            chunks = ((None, chunk) for chunk in iter(lambda: read1(_RAW_CHUNK), b""))
            objects = _frame_events(FrameDecoder(), chunks)
        elif mode == "can":
            objects = run.can_objects(text)
        elif mode == "hid":
            objects = run.hid_objects(text)
        else:
            objects = _frame_events(FrameDecoder(), run.hex_chunks(text))
        # Ctrl-C (or SIGTERM) is how a live pipe (candump -L can0 | srcsctl decode --can)
        # ends: the lines so far are out, so it ends as the end of the input would, without
        # a traceback.
        with contextlib.suppress(KeyboardInterrupt):
            _write(objects, out)
        text.detach()
    return EXIT_BAD_INPUT if run.failed else 0


def run_follow(source: str, mode: str, interface: str, out: IO[str], errors: IO[str]) -> int:
    """Decode a live serial port (``raw``) or CAN channel (``can``) until Ctrl-C or SIGTERM
    (exit 0), or until the source fails (exit 2). Read-only: see :mod:`capture`."""
    run = _Run(source if mode == "raw" else f"{interface}:{source}", errors)
    # Ctrl-C and SIGTERM raise KeyboardInterrupt here (``run``): the port or bus is closed
    # on the way out.
    try:
        if mode == "raw":
            with capture.open_port(source) as port:
                _write(_frame_events(FrameDecoder(), capture.follow_port(port)), out)
        else:
            with capture.open_bus(interface, source) as bus:
                _write(run.follow_objects(capture.follow_bus(bus)), out)
    except KeyboardInterrupt:
        return 0
    except BrokenPipeError:
        raise  # our output's reader left: see run()
    except (capture.CaptureError, serial.SerialException, can.CanError, OSError) as error:
        run.fail(str(error) or type(error).__name__)
    except (ValueError, ImportError) as error:  # python-can: unknown interface or options
        run.fail(str(error))
    return EXIT_BAD_INPUT
