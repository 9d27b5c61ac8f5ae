"""``srcsctl``: the operator's and integrator's tool."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from supervisord.cli.decode import run_decode
from supervisord.cli.demo import run_demo


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="srcsctl", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    decode = commands.add_parser(
        "decode",
        help="decode a capture of VSC traffic into JSON lines",
        description="Decode a capture into one JSON object per frame or rejection "
        "(docs/protocol.md, 'srcsctl decode'). Exit status 2 when any input was unreadable.",
    )
    decode.add_argument("file", nargs="?", default="-", help="the capture (default: stdin)")
    formats = decode.add_mutually_exclusive_group()
    for flag, what in (
        ("--raw", "binary serial bytes"),
        ("--can", "candump lines: ID#DATA, or candump's default or -L formats"),
        ("--hid", "one HID report per line, in hex (9 bytes input, 26 bytes output)"),
    ):
        formats.add_argument(flag, dest="mode", action="store_const", const=flag[2:], help=what)
    decode.set_defaults(mode="hex")

    demo = commands.add_parser("demo", help="watch scripted VSC traffic decoded live")
    demo.add_argument("--speed", type=float, default=1.0, help="time factor (default 1)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "decode":
        return run_decode(args.file, args.mode, sys.stdout, sys.stderr)
    if args.command == "demo":
        return run_demo(sys.stdout, args.speed)
    return 2  # pragma: no cover - argparse rejects unknown commands first


if __name__ == "__main__":
    sys.exit(main())
