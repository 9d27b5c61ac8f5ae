"""srcsctl: the operator's and integrator's tool for srcsd, the safety supervisor."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from supervisord import __version__
from supervisord.cli import control, decode_options, fleet, log_options
from supervisord.cli.access import advice
from supervisord.cli.log_options import PAGER_END_LAST
from supervisord.cli.numbers import positive
from supervisord.errors import ConfigError

# What reads the record or the config (and with them the safety core's values) is imported by
# the command that needs it: the operator's commands load the client library only (SR-8.8,
# tests/test_layers.py).


CONFIG_DIR = Path("/etc/srcs")
"""Where install.md puts the robots' configs, one ``NAME.toml`` per ``srcsd@NAME``."""


def default_config(directory: Path = CONFIG_DIR) -> Path:
    """The config ``log`` reads when none is named: the only ``*.toml`` in ``directory``.
    Raises :class:`LookupError` naming the choices when there is none or more than one
    (a fixed ``srcsd.toml``, the old default, is a file install.md never makes)."""
    found = sorted(directory.glob("*.toml"))
    if len(found) == 1:
        return found[0]
    if not found:
        raise LookupError(
            f"no config in {directory}; name one with --robot NAME, --config FILE, --file PATH "
            "or --demo"
        )
    names = ", ".join(str(path) for path in found)
    raise LookupError(
        f"{len(found)} configs in {directory} ({names}); name one with --robot NAME or --config"
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="srcsctl",
        description=__doc__,
        parents=[control.socket_options()],
        epilog="--config, --robot, --demo and --socket may also come after the command and "
        "its arguments.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    decode_options.add_arguments(commands)

    log = commands.add_parser(
        "log",
        help="show the record of stops",
        description="Show the record of stops, oldest first, one line each: the time, the "
        "state change, the kind, the causes raised or cleared and the reason "
        "(srcsctl(1)). A time is ISO 8601 (local time unless it names a zone; UTC with "
        "--utc), a time of day, now, today, yesterday, or an age such as '5 min ago', "
        "-5min, 2h, 3d. A * after a cause: its condition has cleared and its latch holds the "
        "stop until a re-arm. Nothing matched: '-- No entries --', as journalctl. Without "
        "--config, --robot or --file: the only config in /etc/srcs.",
        parents=[control.socket_options(record=True)],
    )
    log.add_argument("--file", metavar="PATH", help="the record file itself")
    log_options.add_time_range(log)
    log.add_argument(
        "-b",
        "--boot",
        nargs="?",
        const="0",
        metavar="0",
        help="records since the machine booted (its boot time in /proc/stat); only this boot",
    )
    log_options.add_cause_filters(log)
    log_options.add_output(log)
    log.add_argument(
        "-e",
        "--pager-end",
        action="store_true",
        help=f"the last {PAGER_END_LAST} records, unless -n says how many (as journalctl -e)",
    )
    log_options.add_follow_and_display(log, follows="as it is written")
    log.add_argument(
        "--summary",
        action="store_true",
        help="one line instead: the stops (the last one's time and trigger), start-ups, "
        "proof tests and re-arms, counted as 'fleet --summary' counts them",
    )
    log.add_argument(
        "-x",
        "--catalog",
        action="store_true",
        help="accepted and ignored: each line says in words what happened",
    )

    fleet_command = commands.add_parser(
        "fleet",
        help="on a fleet's collector: which robots stopped, and why",
        description="Show the stop records a fleet's collector holds (systemd-journal-remote's "
        "journal), read with journalctl, one line each as 'log' prints them, after the "
        "robot's host name; each robot's in its own order (srcsctl(1), docs/fleet.md). "
        "--since and --until take log's times and compare them with each robot's own clock. "
        "Nothing matched: '-- No entries --'.",
    )
    fleet.add_arguments(fleet_command)

    replay = commands.add_parser(
        "replay",
        help="replay a stop's flight recorder window and check it against the record",
        description="Run the inputs the supervisor's safety core was given before a stop (its "
        "flight recorder window, written beside the record) through a fresh core with the "
        "recorded configuration, and show step by step that it makes the recorded decisions "
        "(srcsctl(1)). Exit 1 at the first record that differs. Without --config, "
        "--robot or --file: the only config in /etc/srcs.",
        parents=[control.socket_options(record=True)],
    )
    replay.add_argument(
        "window",
        nargs="?",
        metavar="SEQ|FILE",
        help="the stop record's sequence number, or a window file (default: the newest window)",
    )
    replay.add_argument("--file", metavar="PATH", help="the record file itself")
    replay.add_argument(
        "--all", action="store_true", help="a line for every input, not only those that decide"
    )
    replay.add_argument(
        "--mcap",
        metavar="OUT",
        help="also write the window and the replayed decisions as an MCAP file, one JSON "
        "channel per signal, for Foxglove (uncompressed); "
        "- for standard output (the replay's text then goes to standard error); a link or a "
        "device is refused",
    )
    replay.add_argument(
        "--plot",
        metavar="OUT.svg",
        help="also draw the window on one time axis as a self-contained SVG picture; - for "
        "standard output (the replay's text then goes to standard error); a link or a device "
        "is refused",
    )

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
        "--speed",
        type=positive,  # a pause divided by 0 or nan (SR-11.3)
        default=1.0,
        help="story pauses run this much faster (default 1)",
    )
    demo.add_argument("--config", type=Path, help="another demo config (default: the packaged one)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(_ages_as_values(sys.argv[1:] if argv is None else argv))
    if unknown:  # said with the command's own usage, never the top level's (SR-11.3)
        command_parser(parser, args).error(f"unrecognized arguments: {' '.join(unknown)}")
    if args.command not in ("demo", "fleet"):  # fleet names robots, not a config
        try:
            chosen = chosen_config(args)
        except LookupError as error:
            print(f"srcsctl {args.command}: {error}", file=sys.stderr)
            return 2  # a usage error (docs/srcsctl.md "Exit status")
        if chosen is not None:
            args.config = str(chosen)
    # decode and demo are imported only when asked for: decode needs python-can, demo the
    # simulator, and the operator's estop, status and hold need neither (SR-8.8).
    if args.command == "decode":
        try:
            from supervisord.cli import decode  # noqa: PLC0415
        except ImportError as error:
            print(f"srcsctl decode: needs python-can and pyserial: {error}", file=sys.stderr)
            return 1  # the action failed (docs/srcsctl.md "Exit status")
        return decode.run(args, sys.stdout, sys.stderr)
    if args.command == "log":
        return _log(args)
    if args.command == "replay":
        return _replay(args)
    if args.command == "fleet":
        return fleet.run(args, sys.stdout, sys.stderr)
    if args.command in control.COMMANDS:
        return control.run(args, sys.stdout, sys.stderr)
    if args.command == "demo":
        from supervisord.cli.demo import run_demo  # noqa: PLC0415

        return run_demo(sys.stdout, speed=args.speed, auto=args.auto or None, config=args.config)
    return 2  # pragma: no cover - argparse rejects unknown commands first


def command_parser(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the command ``args`` were parsed for (``srcsctl log``, ``srcsctl display
    row``): its ``error`` shows that command's usage."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            chosen = action.choices.get(getattr(args, action.dest, None) or "")
            if chosen is not None:
                return command_parser(chosen, args)
    return parser


def robot_config(name: str, directory: Path = CONFIG_DIR) -> Path:
    """``/etc/srcs/NAME.toml`` for ``--robot NAME`` (also ``srcsd@NAME`` or
    ``srcsd@NAME.service``, as systemctl names the unit). Raises :class:`LookupError` naming
    the robots there when it does not exist."""
    name = name.removeprefix("srcsd@").removesuffix(".service")
    path = directory / f"{name}.toml"
    if path.is_file():
        return path
    robots = ", ".join(p.stem for p in sorted(directory.glob("*.toml"))) or "none"
    raise LookupError(f"no robot {name!r}: {path} does not exist (robots here: {robots})")


def chosen_config(args: argparse.Namespace) -> Path | None:
    """The config that ``--robot`` or ``--demo`` stands for, or ``None`` when neither is
    given. Raises :class:`LookupError` when the robot or demo is not there, or when more
    than one way of naming the daemon was given (at different places of the line)."""
    given = [
        option
        for option, dest in (("--config", "config"), ("--robot", "robot"), ("--demo", "demo"))
        if getattr(args, dest, None)
    ]
    given += ["--socket"] if getattr(args, "socket", None) else []
    if len(given) > 1:
        raise LookupError(f"give one of {', '.join(given)}, not several")
    if getattr(args, "robot", None):
        return robot_config(args.robot)
    if getattr(args, "demo", False):
        from supervisord.cli.demo_find import NoDemo, demo_config  # noqa: PLC0415

        try:
            return demo_config()
        except NoDemo as error:
            raise LookupError(str(error)) from None
    return None


def _ages_as_values(argv: Sequence[str]) -> list[str]:
    """``--since -1h`` as ``--since=-1h``: argparse would take ``-1h`` for an option."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] in ("--since", "--until", "-S", "-U") and arg.startswith("-"):
            out[-1] = f"{out[-1]}={arg}"
        else:
            out.append(arg)
    return out


def _record_path(args: argparse.Namespace, command: str) -> Path | None:
    """The record file ``--file`` names, else ``--config``'s, else the one config's in
    /etc/srcs; ``None`` after printing why there is none."""
    if args.file:
        return Path(args.file)
    from supervisord.config.client import load_client_config  # noqa: PLC0415 (SR-8.8)

    try:
        return load_client_config(getattr(args, "config", None) or default_config()).record_path
    except (ConfigError, LookupError) as error:
        print(f"srcsctl {command}: {error}", file=sys.stderr)
        return None


def _replay(args: argparse.Namespace) -> int:
    record: Path | None = None
    named = args.file or getattr(args, "config", None)
    if named or args.window is None or args.window.isdigit():
        # A window file alone names its record by its folder (PATH.flight).
        record = _record_path(args, "replay")
        if record is None:
            return 2
    from supervisord.cli.replay import run_replay  # noqa: PLC0415

    return run_replay(
        args.window,
        record,
        sys.stdout,
        sys.stderr,
        show_all=args.all,
        mcap=Path(args.mcap) if args.mcap else None,
        plot=Path(args.plot) if args.plot else None,
        stdout=sys.stdout.buffer,
    )


def _log(args: argparse.Namespace) -> int:
    if args.boot not in (None, "", "0"):
        # journalctl -b -1: the record keeps no boot ids; a time says which (SR-11.3).
        print(
            f"srcsctl log: -b {args.boot}: only this boot (-b or -b 0); for an earlier one "
            "give --since and --until",
            file=sys.stderr,
        )
        return 2
    path = _record_path(args, "log")
    if path is None:
        return 2
    last = args.lines if args.lines is not None or not args.pager_end else PAGER_END_LAST
    from supervisord.cli.log import run_log  # noqa: PLC0415
    from supervisord.record.jsonl import RecordUnreadable  # noqa: PLC0415

    try:
        return run_log(
            path,
            sys.stdout,
            sys.stderr,
            since=args.since,
            until=args.until,
            cause=args.cause,
            cause_present=args.cause_present,
            output="json" if args.json and not args.output else args.output or "short",
            utc=args.utc,
            last=last,
            follow=args.follow,
            reverse=args.reverse,
            causes=args.causes,
            this_boot=args.boot is not None,
            quiet=args.quiet,
            summary=args.summary,
        )
    except RecordUnreadable as error:  # never an empty answer with exit 0 (SR-7.9)
        print(f"srcsctl log: {error}{advice(error.path, error.errno)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
