"""The arguments of ``srcsctl decode``, apart from the decoder itself: ``srcsctl`` builds its
parser from them without importing python-can, which only ``decode`` needs, so that
``estop``, ``status`` and ``hold`` work on a robot without it (SR-8.8)."""

from __future__ import annotations

import argparse


def add_arguments(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``decode`` to ``srcsctl``'s parser."""
    decode = commands.add_parser(
        "decode",
        help="decode a capture of VSC traffic into JSON lines",
        description="Decode a capture into one JSON object per frame or rejection, each "
        "flushed as it is decoded (protocol.md in /usr/share/doc/srcs-supervisord/docs). Exit "
        "status 2 when "
        "any input was unreadable.",
    )
    decode.add_argument(
        "file",
        nargs="?",
        default="-",
        help="the capture (default: stdin); with --follow, the serial port or CAN channel",
    )
    formats = decode.add_mutually_exclusive_group()
    for flag, what in (
        ("--raw", "binary serial bytes"),
        (
            "--can",
            "CAN frames: candump lines (ID#DATA, candump's default or -L formats, .log), or "
            "a .asc, .blf, .csv, .db, .trc or .mf4 file (also .gz) read by python-can",
        ),
        ("--hid", "one HID report per line, in hex (9 bytes input, 26 bytes output)"),
    ):
        formats.add_argument(flag, dest="mode", action="store_const", const=flag[2:], help=what)
    decode.set_defaults(mode="hex")
    decode.add_argument(
        "--follow",
        action="store_true",
        help="read a live serial port (--raw) or CAN channel (--can) until Ctrl-C; never "
        "writes to the port or sends on the bus",
    )
    decode.add_argument(
        "--interface",
        default="socketcan",
        metavar="NAME",
        help="with --can --follow: python-can's interface (default: socketcan)",
    )
