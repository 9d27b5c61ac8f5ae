"""``srcsctl``: the operator's and integrator's tool."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from supervisord.cli import control
from supervisord.cli.decode import run_decode
from supervisord.cli.demo import run_demo
from supervisord.cli.log import run_log
from supervisord.config import load_config
from supervisord.errors import ConfigError

DEFAULT_CONFIG = "/etc/srcs/srcsd.toml"


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

    log = commands.add_parser(
        "log",
        help="show the record of stops",
        description="Show the record of stops, oldest first (docs/record.md). A time is ISO "
        "8601 (UTC unless it names a zone) or an age such as 10m, 2h, 3d.",
    )
    where = log.add_mutually_exclusive_group()
    where.add_argument("--config", metavar="FILE", help="the robot's config (its [record] path)")
    where.add_argument("--file", metavar="PATH", help="the record file itself")
    log.add_argument("--since", metavar="TIME", help="records at or after TIME")
    log.add_argument("--until", metavar="TIME", help="records before TIME")
    log.add_argument(
        "--cause",
        metavar="NAME",
        help="records with this cause (client_lost matches client_lost:autonomy)",
    )
    log.add_argument("--json", action="store_true", help="the records as JSON lines")

    control.add_arguments(commands)

    demo = commands.add_parser(
        "demo",
        help="the supervisor against the simulated VSC, with a live view",
        description="Start srcs-sim and srcsd wired together in a private directory and show "
        "them live; keys press the remote's e-stop, pause, takeover and cut the link. Without "
        "a terminal, or with --auto, it plays a short story of stops and re-arms.",
    )
    demo.add_argument("--auto", action="store_true", help="play the story instead of keys")
    demo.add_argument(
        "--speed", type=float, default=1.0, help="story pauses run this much faster (default 1)"
    )
    demo.add_argument("--config", type=Path, help="another demo config (default config/demo.toml)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "decode":
        return run_decode(args.file, args.mode, sys.stdout, sys.stderr)
    if args.command == "log":
        return _log(args)
    if args.command in control.COMMANDS:
        return control.run(args, sys.stdout, sys.stderr)
    if args.command == "demo":
        return run_demo(sys.stdout, speed=args.speed, auto=args.auto or None, config=args.config)
    return 2  # pragma: no cover - argparse rejects unknown commands first


def _log(args: argparse.Namespace) -> int:
    if args.file:
        path = Path(args.file)
    else:
        try:
            path = load_config(args.config or DEFAULT_CONFIG).record.path
        except ConfigError as error:
            print(f"srcsctl log: {error}", file=sys.stderr)
            return 2
    return run_log(
        path,
        sys.stdout,
        sys.stderr,
        since=args.since,
        until=args.until,
        cause=args.cause,
        as_json=args.json,
    )


if __name__ == "__main__":
    sys.exit(main())
