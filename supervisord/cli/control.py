"""The ``srcsctl`` commands that talk to a running ``srcsd`` over its API socket.

Each command is one connection and a few requests through :class:`SupervisorClient`
(``docs/api.md``). Exit status: 0 done, 1 refused or failed (the daemon's reason is printed),
2 a usage or configuration error, 3 no daemon to talk to.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Final, TextIO

from supervisord.api.wire import ApiError, ErrorCode
from supervisord.client import DEFAULT_SOCKET_PATH, ClientError, ConnectError, SupervisorClient
from supervisord.config import load_config
from supervisord.errors import ConfigError
from supervisord.protocol.codes import DisplayMode

EXIT_REFUSED: Final = 1
EXIT_USAGE: Final = 2
EXIT_NO_DAEMON: Final = 3
DEFAULT_NAME: Final = "srcsctl"
RECONNECT_S: Final = 1.0

DISPLAY_MODES: Final[Mapping[str, DisplayMode]] = {
    "gps": DisplayMode(0),
    "text": DisplayMode(1),
    "labelled": DisplayMode(2),
    "values": DisplayMode(3),
}


def add_arguments(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the commands of this module to ``srcsctl``'s parser."""
    socket_options = argparse.ArgumentParser(add_help=False)
    where = socket_options.add_mutually_exclusive_group()
    where.add_argument("--config", metavar="FILE", help="the robot's config (its [api] socket)")
    where.add_argument(
        "--socket",
        metavar="PATH",
        help=f"the API socket (default $SRCS_SOCKET or {DEFAULT_SOCKET_PATH})",
    )
    named = argparse.ArgumentParser(add_help=False)
    named.add_argument(
        "--name",
        help="the client name to act as; a named e-stop or hold stays until that name releases "
        "it (default for hold: srcsctl; estop and release: the operator's local e-stop)",
    )

    def add(
        name: str, help_text: str, *parents: argparse.ArgumentParser
    ) -> argparse.ArgumentParser:
        return commands.add_parser(
            name, help=help_text, description=help_text, parents=[socket_options, *parents]
        )

    status = add("status", "show the state, its causes, the outputs and the link")
    status.add_argument("--json", action="store_true", help="the daemon's reply as JSON")
    watch = add("watch", "follow state changes and stop records live (Ctrl-C ends)")
    watch.add_argument("--json", action="store_true", help="every push as a JSON line")
    watch.add_argument(
        "--joystick", action="store_true", help="also show the sticks and buttons as they come"
    )
    add("estop", "stop now: local_estop, or client_estop:NAME with --name", named)
    add("hold", "hold motion (client_hold:NAME) until `srcsctl release hold`", named)
    release = add("release", "end an e-stop or hold you asked for (a stop stays latched)", named)
    release.add_argument("what", nargs="?", choices=("estop", "hold"), default="estop")
    add("reset", "re-arm from the vehicle computer (admin; needs rearm.local_reset = true)")

    display = add("display", "put text, values or a page on the remote's screen")
    kinds = display.add_subparsers(dest="display", required=True, metavar="WHAT")
    row = kinds.add_parser("row", help="text row 1-4 (at most 20 characters)")
    row.add_argument("index", type=int)
    row.add_argument("text")
    value = kinds.add_parser("value", help="user value 1-9, optionally with its label")
    value.add_argument("key", type=int)
    value.add_argument("value", type=int)
    value.add_argument("--label", help="the value's label (at most 20 characters)")
    label = kinds.add_parser("label", help="the label of user value 1-9")
    label.add_argument("key", type=int)
    label.add_argument("text")
    mode = kinds.add_parser("mode", help="the page: gps, text, labelled or values (or 0-3)")
    mode.add_argument("mode", choices=(*DISPLAY_MODES, "0", "1", "2", "3"))

    vibrate = add("vibrate", "vibrate the remote's handles for 750 ms")
    vibrate.add_argument("side", nargs="?", choices=("left", "right", "both"), default="both")

    commission = add(
        "commission",
        "switch the VSC's key-85 watchdog and remote-status messages on, permanently (admin)",
    )
    commission.add_argument(
        "--yes", action="store_true", help="do not ask for confirmation (scripts)"
    )


COMMANDS: Final = frozenset(
    {"status", "watch", "estop", "hold", "release", "reset", "display", "vibrate", "commission"}
)


def run(args: argparse.Namespace, out: TextIO, err: TextIO, stdin: TextIO = sys.stdin) -> int:
    """Run one of :data:`COMMANDS`; returns the exit status."""
    prog = f"srcsctl {args.command}"
    try:
        path = socket_path(args.config, args.socket)
    except ConfigError as error:
        print(f"{prog}: {error}", file=err)
        return EXIT_USAGE
    if args.command == "commission" and not (args.yes or _confirmed(out, stdin)):
        print(f"{prog}: not confirmed; nothing was written", file=err)
        return EXIT_REFUSED
    if args.command == "watch":
        return _watch(path, args, out, err)
    try:
        with SupervisorClient.connect(path, timeout=10.0) as client:
            return _one_shot(client, args, out)
    except ConnectError as error:
        print(f"{prog}: {error} (is srcsd running?)", file=err)
        return EXIT_NO_DAEMON
    except ApiError as error:
        print(f"{prog}: {error.code}: {error.message}", file=err)
        if error.code == ErrorCode.TOO_MANY_CLIENTS and os.geteuid() != 0:
            # docs/api.md "Limits": an admin's connection takes over an e-stop slot.
            print(f"{prog}: run it as root or a member of the admin group to get one", file=err)
        return EXIT_REFUSED
    except ClientError as error:
        print(f"{prog}: {error}", file=err)
        return EXIT_NO_DAEMON


def socket_path(config: str | None, socket: str | None) -> Path:
    """``--socket``, else the config's ``[api] socket``, else ``$SRCS_SOCKET``, else the
    default. Raises :class:`ConfigError` for a bad config."""
    if socket:
        return Path(socket)
    if config:
        return load_config(config).api.socket
    return Path(os.environ.get("SRCS_SOCKET") or DEFAULT_SOCKET_PATH)


def _confirmed(out: TextIO, stdin: TextIO) -> bool:
    print(
        "This writes key 85 = 1 and enables remote status on the VSC, permanently: from then on\n"
        "the VSC e-stops whenever no user heartbeat arrives for 500 ms. Type 'yes' to go on: ",
        end="",
        file=out,
        flush=True,
    )
    return stdin.readline().strip().lower() == "yes"


def _one_shot(client: SupervisorClient, args: argparse.Namespace, out: TextIO) -> int:
    command = args.command
    if command == "status":
        status = client.status()
        if args.json:
            print(json.dumps(status, sort_keys=True), file=out)
        else:
            out.write(format_status(status))
        return 0
    if command in ("estop", "hold", "release"):
        holding = command == "hold" or (command == "release" and args.what == "hold")
        name = args.name or (DEFAULT_NAME if holding else None)
        if name is not None:
            client.hello(name)
        if command == "estop":
            client.estop()
        elif command == "hold":
            client.hold()
        else:
            client.release(args.what)
        who = f"client {name}" if name else "local"
        print(f"{command} ({who}): done; the supervisor is {client.status()['state']}", file=out)
        return 0
    if command == "reset":
        client.reset()
        print(f"reset: accepted; the supervisor is {client.status()['state']}", file=out)
        return 0
    if command == "display":
        _display(client, args)
        return 0
    if command == "vibrate":
        client.vibrate(args.side)
        return 0
    reply = client.commission()
    remote = "on" if reply.get("remote_status") else "not seen (older firmware?)"
    print(f"commissioned: key 85 reads {reply.get('key85')}; remote status {remote}", file=out)
    return 0


def _display(client: SupervisorClient, args: argparse.Namespace) -> None:
    if args.display == "row":
        client.display_row(args.index, args.text)
    elif args.display == "value":
        if args.label is not None:
            client.display_label(args.key, args.label)
        client.display_value(args.key, args.value)
    elif args.display == "label":
        client.display_label(args.key, args.text)
    else:
        mode = args.mode
        client.display_mode(
            DISPLAY_MODES[mode] if mode in DISPLAY_MODES else DisplayMode(int(mode))
        )


# -- status --------------------------------------------------------------------------------


def format_status(status: Mapping[str, Any]) -> str:
    """The human form of a ``status`` reply (``docs/api.md``)."""
    daemon: Mapping[str, Any] = status.get("daemon") or {}
    robot = daemon.get("robot") or "?"
    lines = [f"robot {robot}: {status.get('state')}"]
    link = daemon.get("link")
    if link:
        state = "open" if link.get("open") else "NOT OPEN"
        lines.append(
            f"  link     {link.get('description')}: {state} "
            f"({link.get('opens')} opens, {link.get('open_failures')} failed attempts)"
        )
    causes = status.get("causes") or []
    if not causes:
        lines.append("  causes   none")
    for index, cause in enumerate(causes):
        label = "causes" if index == 0 else ""
        lines.append(f"  {label:8} {_cause_text(cause)}")
    outputs = status.get("outputs") or {}
    levels = " ".join(f"{name}={'ON' if on else 'off'}" for name, on in outputs.items())
    lines.append(f"  outputs  {levels or 'none'}")
    lines.append(f"  to VSC   heartbeat e-stop byte {status.get('heartbeat_estop')}")
    if "messages" in daemon:
        rejected = ", ".join(f"{k} {v}" for k, v in (daemon.get("rejections") or {}).items())
        lines.append(
            f"  traffic  {daemon['messages']} messages; rejected: {rejected or 'none'}; "
            f"record errors {daemon.get('record_errors', 0)}; "
            f"internal faults {daemon.get('internal_faults', 0)}"
        )
    return "\n".join(lines) + "\n"


def _cause_text(cause: Mapping[str, Any]) -> str:
    flags = [
        w for w, on in (("active", cause.get("active")), ("latched", cause.get("latched"))) if on
    ]
    details = " ".join(f"{k}={v}" for k, v in (cause.get("details") or {}).items())
    text = f"{cause.get('name')} ({cause.get('severity')}, {', '.join(flags) or 'clear'})"
    return f"{text} {details}".rstrip()


# -- watch ---------------------------------------------------------------------------------


def _watch(path: Path, args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    """Follow the daemon until Ctrl-C, reconnecting when it restarts."""
    topics = ["state", "records", *(["joystick"] if args.joystick else [])]
    show: Callable[[str, Mapping[str, Any]], str] = (
        (lambda _e, data: json.dumps(dict(data), sort_keys=True)) if args.json else format_push
    )
    said_waiting = False
    try:
        while True:
            try:
                with SupervisorClient.connect(path, timeout=10.0) as client:
                    said_waiting = False
                    client.subscribe(*topics)
                    print(
                        show("state", {"event": "state", **client.status()}), file=out, flush=True
                    )
                    while True:
                        push = client.next_event(timeout=3600)
                        if push is not None:
                            print(show(push.event, push.data), file=out, flush=True)
            except ClientError as error:
                if not said_waiting:
                    print(f"srcsctl watch: {error}; retrying every second", file=err, flush=True)
                    said_waiting = True
                time.sleep(RECONNECT_S)
    except KeyboardInterrupt:
        return 0


def format_push(event: str, data: Mapping[str, Any]) -> str:
    """One line for a push: the local time, then what happened."""
    stamp = dt.datetime.now().astimezone().strftime("%H:%M:%S.%f")[:-3]
    if event == "state":
        causes = ", ".join(_short_cause(c) for c in data.get("causes") or []) or "no causes"
        outputs = " ".join(
            f"{k}={'ON' if v else 'off'}" for k, v in (data.get("outputs") or {}).items()
        )
        return f"{stamp} {data.get('state'):8} {causes} | {outputs}"
    if event == "record":
        reason = f" ({data['reason']})" if data.get("reason") else ""
        names = ", ".join(c.get("name", "?") for c in data.get("causes") or []) or "none"
        return (
            f"{stamp} record #{data.get('seq')} {data.get('kind')}: "
            f"{data.get('from')} -> {data.get('to')}; causes {names}{reason}"
        )
    if event == "joystick":
        suffix = "_joystick_value"
        axes = " ".join(
            f"{key.removesuffix(suffix)}={value.get('value')}"
            for key, value in data.items()
            if key.endswith(suffix) and isinstance(value, Mapping)
        )
        pressed = [
            name
            for side in ("left_button_values", "right_button_values")
            for name in (data.get(side) or {}).get("pressed", [])
        ]
        return f"{stamp} joystick {axes} pressed {','.join(pressed) or '-'}"
    return f"{stamp} {event} {json.dumps(dict(data), sort_keys=True)}"


def _short_cause(cause: Mapping[str, Any]) -> str:
    return f"{cause.get('name')}{'' if cause.get('active') else '*'}"
