"""The ``srcsctl`` commands that talk to a running ``srcsd`` over its API socket.

Each command is one connection and a few requests through :class:`SupervisorClient`
(``docs/api.md``), on the operator socket when this user can open it, else on the client
socket (SR-8.14; ``wait-ready``, a robot service's gate, always on the client socket), and on
the client socket again when the operator socket refuses it as full (SR-8.17).
Exit status: 0 done, 1 refused or failed (the daemon's reason is printed),
2 a usage or configuration error, 3 no daemon to talk to.
"""

from __future__ import annotations

import argparse
import datetime as dt
import grp
import json
import os
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Final, TextIO

from supervisord.api.framing import ApiError, ErrorCode, operator_socket_path
from supervisord.api.messages import RemoteStatusReport
from supervisord.api.ops import StartProofTest
from supervisord.api.pushes import JoystickPush, Push, RecordPush, RemoteStatusPush, StatePush
from supervisord.api.readiness import DEFAULT_SRCSCTL, missing, srcsctl_for
from supervisord.api.status import Cause, ClientStatus, EstopAvailable, Maintenance, RemoteReport
from supervisord.cli import numbers
from supervisord.cli.interrupt import interruptible
from supervisord.cli.numbers import whole_in
from supervisord.cli.ready import DEFAULT_TIMEOUT_S, wait_ready
from supervisord.cli.stoptest import add_stoptest, confirmed_stoptest, run_stoptest
from supervisord.cli.times import clock, clock_of
from supervisord.client import (
    DEFAULT_SOCKET_PATH,
    ClientError,
    ConnectError,
    StatusReply,
    SupervisorClient,
)
from supervisord.errors import ConfigError
from supervisord.protocol.codes import USER_VALUE_KEYS, DisplayMode
from supervisord.protocol.messages import I32
from supervisord.vocabulary import Phase

EXIT_REFUSED: Final = 1
EXIT_USAGE: Final = 2
EXIT_NO_DAEMON: Final = 3
EXIT_DENIED: Final = 4
DEFAULT_NAME: Final = "srcsctl"
RECONNECT_S: Final = 1.0
DISPLAY_ROWS: Final = range(1, 5)
"""The remote's text rows (docs/api.md "display")."""

DISPLAY_MODES: Final[Mapping[str, DisplayMode]] = {
    "gps": DisplayMode(0),
    "text": DisplayMode(1),
    "labelled": DisplayMode(2),
    "values": DisplayMode(3),
}


def socket_options(*, record: bool = False) -> argparse.ArgumentParser:
    """Which daemon (or, for the record, which robot's record): ``--config``, ``--robot``
    (``-R``), ``--demo`` and, except for the record, ``--socket``; for every level of the
    parser: before the command, after it, after a subcommand's arguments. The
    defaults are suppressed so that a level where the option is absent keeps what another
    level set; read them with ``getattr(args, "socket", None)``."""
    options = argparse.ArgumentParser(add_help=False)
    where = options.add_mutually_exclusive_group()
    what = "its [record] path" if record else "its [api] socket"
    where.add_argument(
        "--config",
        metavar="FILE",
        default=argparse.SUPPRESS,
        help=f"the robot's config ({what})",
    )
    where.add_argument(
        "-R",
        "--robot",
        metavar="NAME",
        default=argparse.SUPPRESS,
        help="the robot of srcsd@NAME: its config /etc/srcs/NAME.toml",
    )
    where.add_argument(
        "--demo",
        action="store_true",
        default=argparse.SUPPRESS,
        help="the running srcsctl demo (its config in its private directory)",
    )
    if not record:
        where.add_argument(
            "--socket",
            metavar="PATH",
            default=argparse.SUPPRESS,
            help=f"the API socket (default $SRCS_SOCKET or {DEFAULT_SOCKET_PATH})",
        )
    return options


def add_arguments(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the commands of this module to ``srcsctl``'s parser."""
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
            name, help=help_text, description=help_text, parents=[socket_options(), *parents]
        )

    utc = argparse.ArgumentParser(add_help=False)
    utc.add_argument("--utc", action="store_true", help="times in UTC (default: local time)")

    status = add("status", "show the state, its causes, the outputs and the link")
    status.add_argument("--json", action="store_true", help="the daemon's reply as JSON")
    watch = add(
        "watch",
        "follow the daemon live: a line when the state or an output changes, one per stop "
        "record (as srcsctl log prints it), Ctrl-C ends; * after a cause: it has cleared and "
        "its latch holds the stop until a re-arm",
        utc,
    )
    watch.add_argument("--json", action="store_true", help="every push as a JSON line")
    watch.add_argument("-o", "--output", choices=("short", "json"), help="json: as --json")
    watch.add_argument(
        "--causes", action="store_true", help="also every cause of each record, and its trigger"
    )
    watch.add_argument(
        "--joystick", action="store_true", help="also show the sticks and buttons as they come"
    )
    add("estop", "stop now: local_estop, or client_estop:NAME with --name", named)
    add("hold", "hold motion (client_hold:NAME) until 'srcsctl release hold'", named)
    release = add("release", "end an e-stop or hold you asked for (a stop stays latched)", named)
    release.add_argument("what", nargs="?", choices=("estop", "hold"), default="estop")
    add("reset", "re-arm from the vehicle computer (admin; needs rearm.local_reset = true)")

    display = add("display", "put text, values or a page on the remote's screen")
    kinds = display.add_subparsers(dest="display", required=True, metavar="WHAT")

    def kind(name: str, help_text: str) -> argparse.ArgumentParser:
        return kinds.add_parser(name, help=help_text, parents=[socket_options()])

    row = kind("row", "text row 1-4 (at most 20 characters)")
    # Out of range is a usage error here (exit 2), not the daemon's refusal (SR-11.3).
    row.add_argument("index", type=whole_in(DISPLAY_ROWS.start, DISPLAY_ROWS.stop - 1))
    row.add_argument("text")
    value = kind("value", "user value 1-9, optionally with its label")
    value.add_argument("key", type=whole_in(USER_VALUE_KEYS.start, USER_VALUE_KEYS.stop - 1))
    value.add_argument("value", type=whole_in(*I32))
    value.add_argument("--label", help="the value's label (at most 20 characters)")
    label = kind("label", "the label of user value 1-9")
    label.add_argument("key", type=whole_in(USER_VALUE_KEYS.start, USER_VALUE_KEYS.stop - 1))
    label.add_argument("text")
    mode = kind("mode", "the page: gps, text, labelled or values (or 0-3)")
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
    add(
        "prooftest",
        "prove the VSC's key-85 watchdog again: withhold the heartbeat, see the VSC stop "
        "(admin; only while STOPPED)",
    )
    add_stoptest(add)
    ready = add(
        "wait-ready",
        "wait until the stop path works: the VSC heard, its watchdog on and proven, every "
        "output held and reading back; exit 0, or 1 naming what is missing (3: no srcsd)",
    )
    ready.add_argument(
        "--timeout",
        type=numbers.duration,  # nan or inf would never time out (SR-8.10, SR-11.3)
        default=DEFAULT_TIMEOUT_S,
        metavar="TIME",
        help="give up after TIME: seconds, or a time span such as 2s, 500ms, 1min, 1m30s "
        f"(default {DEFAULT_TIMEOUT_S:g})",
    )
    ready.add_argument(
        "--rearmable",
        action="store_true",
        help="wait also until a takeover would be accepted: every stop condition clear for "
        "rearm.hold_ms and no client commanding motion (the operator's act aside)",
    )


COMMANDS: Final = frozenset(
    {
        "status",
        "watch",
        "estop",
        "hold",
        "release",
        "reset",
        "display",
        "vibrate",
        "commission",
        "prooftest",
        "wait-ready",
        "stoptest",
    }
)


def run(args: argparse.Namespace, out: TextIO, err: TextIO, stdin: TextIO = sys.stdin) -> int:
    """Run one of :data:`COMMANDS`; returns the exit status."""
    prog = f"srcsctl {args.command}"
    try:
        path, operator = socket_paths(getattr(args, "config", None), getattr(args, "socket", None))
    except ConfigError as error:
        print(f"{prog}: {error}", file=err)
        return EXIT_USAGE
    if args.command == "commission" and not (args.yes or _confirmed(out, stdin)):
        print(f"{prog}: not confirmed; nothing was written", file=err)
        return EXIT_REFUSED
    if args.command == "stoptest" and not (args.yes or confirmed_stoptest(out, stdin)):
        print(f"{prog}: not confirmed; nothing was done", file=err)
        return 3  # not done (docs/srcsctl.md "The field stop test")
    if args.command == "watch":
        return _watch(path, operator, args, out, err)
    try:
        if args.command == "wait-ready":
            return wait_ready(
                path, args.timeout, out, err, rearmable=args.rearmable, srcsctl=reached_by(args)
            )
        if args.command == "stoptest":
            return on_either(
                path,
                operator,
                lambda client: run_stoptest(client, out, wired=args.wired, timeout_s=args.timeout),
                err=err,
                prog=prog,
            )
        return on_either(
            path, operator, lambda client: _one_shot(client, args, out), err=err, prog=prog
        )
    except ConnectError as error:
        if isinstance(error.__cause__, PermissionError):
            print(f"{prog}: {denied(path, error)}", file=err)
            return EXIT_DENIED
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


def denied(path: Path, error: ConnectError) -> str:
    """A refused ``connect`` said as such (it used to read "is srcsd running?"), with the
    fix: the socket is 0660, its group's members may connect (docs/api.md "The socket")."""
    try:
        group = grp.getgrgid(path.stat().st_gid).gr_name
        how = f"run it as root or as a member of the group {group}"
    except (OSError, KeyError):
        how = "run it as root, or as a user who may open the socket and its directory"
    return f"{error}: permission denied; {how}"


def connect(path: Path, operator: Path | None, timeout: float = 10.0) -> SupervisorClient:
    """A connection on the ``operator`` socket if this user can open it, else on the client
    socket at ``path`` (SR-8.14, docs/srcsctl.md "Which socket"). The operator socket is
    missing under an older srcsd and closed to a user outside its group; any failure to
    connect there falls back, and only the client socket's failure is reported."""
    if operator is not None:
        try:
            return SupervisorClient.connect(operator, timeout=timeout)
        except ConnectError:
            pass  # not there, or not for this user: the client socket, as before
    return SupervisorClient.connect(path, timeout=timeout)


def on_either(
    path: Path,
    operator: Path | None,
    work: Callable[[SupervisorClient], int],
    timeout: float = 10.0,
    *,
    err: TextIO | None = None,
    prog: str = "srcsctl",
) -> int:
    """``work`` on a connection to the ``operator`` socket when this user can open it and it
    takes the connection, else on the client socket at ``path`` (SR-8.14, SR-8.17).

    A full operator socket accepts the connection, then answers ``too_many_clients`` and
    closes it (docs/api.md "Error codes"): that refusal is read only at the first request, so
    the fallback is made there, not at the connect. ``too_many_clients`` is never the answer
    to a request that was acted on (a full socket, or an e-stop slot refusing all but
    ``estop`` and ``status``), and every command prints nothing before its first answer, so
    the whole command runs again on the client socket, where its e-stop slots and an admin's
    eviction take the operator's ``estop`` (docs/srcsctl.md "Which socket"); ``err`` is told."""
    if operator is not None:
        try:
            client = SupervisorClient.connect(operator, timeout=timeout)
        except ConnectError:
            client = None  # not there, or not for this user: the client socket, as before
        if client is not None:
            with client:
                try:
                    return work(client)
                except ApiError as error:
                    if error.code != ErrorCode.TOO_MANY_CLIENTS:
                        raise
                    if err is not None:
                        print(
                            f"{prog}: the operator socket is full ({error.message}); "
                            f"using the client socket {path}",
                            file=err,
                        )
    with SupervisorClient.connect(path, timeout=timeout) as client:
        return work(client)


def socket_paths(config: str | None, socket: str | None) -> tuple[Path, Path | None]:
    """The client socket (as :func:`socket_path`) and the operator socket to try first:
    the config's ``[api] operator_socket``, else the one beside the client socket; none with
    ``--socket``, which names exactly the socket to use. Raises :class:`ConfigError`."""
    if socket:
        return Path(socket), None
    if config:
        # Where the daemon is, and nothing of the safety core (SR-8.8).
        from supervisord.config.client import load_client_config  # noqa: PLC0415

        where = load_client_config(config)
        return where.socket, where.operator_socket
    path = socket_path(None, None)
    return path, operator_socket_path(path)


def socket_path(config: str | None, socket: str | None) -> Path:
    """``--socket``, else the config's ``[api] socket``, else ``$SRCS_SOCKET``, else the
    default. Raises :class:`ConfigError` for a bad config."""
    if socket:
        return Path(socket)
    if config:
        from supervisord.config.client import load_client_config  # noqa: PLC0415 (SR-8.8)

        return load_client_config(config).socket
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
            print(json.dumps(status.json(), sort_keys=True), file=out)
        else:
            out.write(format_status(status, reached_by(args)))
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
        print(
            f"{command} ({who}): done; the supervisor is {client.status().report.state}", file=out
        )
        return 0
    if command == "reset":
        client.reset()
        print(f"reset: accepted; the supervisor is {client.status().report.state}", file=out)
        return 0
    if command == "display":
        _display(client, args)
        return 0
    if command == "vibrate":
        client.vibrate(args.side)
        return 0
    if command == "prooftest":
        return _prooftest(client, out)
    reply = client.commission()
    remote = "on" if reply.remote_status else "not seen (older firmware?)"
    print(f"commissioned: key 85 reads {reply.key85}; remote status {remote}", file=out)
    return 0


PROOFTEST_WAIT_S: Final = 30.0  # a held bit waits for the operator (docs/safety.md)


def _prooftest(client: SupervisorClient, out: TextIO) -> int:
    """Ask for a proof test (docs/safety.md "The proof test"), then follow ``status`` until
    it has a result: exit 0 when it passed, 1 when it failed or gave none in time."""
    from supervisord.cli.record_text import verdict  # noqa: PLC0415 -- when used (SR-8.8)

    client.call(StartProofTest())
    print("prooftest: started; the user heartbeat is withheld for up to 1.5 s", file=out)
    deadline = time.monotonic() + PROOFTEST_WAIT_S
    phase = None
    while time.monotonic() < deadline:
        proof = client.status().report.prooftest
        phase = None if proof is None else proof.phase
        if proof is not None and phase in (Phase.PASSED, Phase.FAILED):
            print(f"prooftest: {verdict(proof.last)}", file=out)  # as its record says it
            return 0 if phase is Phase.PASSED else EXIT_REFUSED
        time.sleep(0.1)
    print(f"prooftest: no result in {PROOFTEST_WAIT_S:.0f} s ({phase})", file=out)
    return EXIT_REFUSED


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


def reached_by(args: argparse.Namespace) -> str:
    """The ``srcsctl`` line that reaches the daemon as this command did, for a fix to name
    (SR-8.18): ``srcsctl -R robot-a`` after ``-R robot-a``."""
    return srcsctl_for(
        robot=getattr(args, "robot", None),
        config=getattr(args, "config", None),
        socket=getattr(args, "socket", None),
        demo=bool(getattr(args, "demo", False)),
    )


def format_status(status: StatusReply, srcsctl: str = DEFAULT_SRCSCTL) -> str:
    """The human form of a ``status`` reply (``docs/api.md``); what keeps it from being
    ready is said with its fix, the command named as ``srcsctl`` (SR-8.18)."""
    from supervisord.cli.record_text import MARK_MEANS, verdict  # noqa: PLC0415 -- when used (SR-8.8)

    report, daemon = status.report, status.daemon
    loop, link = daemon.loop, daemon.loop.link
    since = daemon.in_state_s
    lines = [
        f"robot {daemon.robot or '?'}: {report.state}"
        + (f" for {duration(since)}" if since else "")
    ]
    up = loop.uptime_s
    lines.append(
        f"  daemon   srcsd {loop.version}, pid {loop.pid}"
        + (f", up {duration(up)}" if up is not None else "")
    )
    state = "open" if link.open else "NOT OPEN"
    if link.since_s is not None:
        state += f" for {duration(link.since_s)}"
    last_error = f"; last error: {link.last_error}" if link.last_error else ""
    errors = link.error_frames  # CAN only (docs/safety.md "CAN error frames")
    counted = f", {errors} CAN error frames" if errors is not None else ""
    lines.append(
        f"  link     {link.description}: {state} "
        f"({link.opens} opens, {link.open_failures} failed attempts{counted}){last_error}"
    )
    lines += _client_lines(daemon.clients)
    remote = daemon.remote
    lines.append(f"  remote   {remote_text(remote) if remote else 'no status seen'}")
    if status.estop_available is not None:
        lines.append(f"  e-stop   {estop_text(status.estop_available)}")
    if not report.causes:
        lines.append("  causes   none")
    for index, cause in enumerate(report.causes):
        label = "causes" if index == 0 else ""
        lines.append(f"  {label:8} {_cause_text(cause)}")
    if any(cause.held for cause in report.causes):
        lines.append(f"           {MARK_MEANS}")
    for index, gap in enumerate(missing(status, srcsctl)):
        lines.append(f"  {'ready' if index == 0 else '':8} {'no: ' if index == 0 else ''}{gap}")
    levels = " ".join(f"{name}={'ON' if on else 'off'}" for name, on in report.outputs.items())
    lines.append(f"  outputs  {levels or 'none'}")
    lines.append(f"  to VSC   heartbeat e-stop byte {report.heartbeat_estop}")
    if proof := report.prooftest:
        result = "none yet" if proof.last is None else verdict(proof.last)
        lines.append(f"  proof    {proof.phase}; last: {result}")
    if loop.maintenance is not None:
        lines.append(f"  tests    {tests_text(loop.maintenance)}")
    if loop.memory_locked is False:  # SR-9.6; None: a daemon older than the lock
        lines.append(f"  memory   {MEMORY_NOT_LOCKED}")
    rejected = ", ".join(f"{k} {v}" for k, v in loop.rejections.items())
    lines.append(
        f"  traffic  {loop.messages} messages; rejected: {rejected or 'none'}; "
        f"record errors {loop.record_errors}; internal faults {loop.internal_faults}"
    )
    return "\n".join(lines) + "\n"


TEST_NAMES: Final = {"stoptest": "stop test", "prooftest": "proof test"}
MEMORY_NOT_LOCKED: Final = (
    "NOT LOCKED: the loop may wait on a page fault under memory pressure; the daemon's start "
    'said why (docs/configuration.md "[realtime]")'
)
"""What ``status`` says of a daemon whose memory lock was refused or turned off (SR-9.6)."""


def tests_text(schedule: Maintenance) -> str:
    """The periodic tests (SR-12.2): ``stop test passed 3.0 d ago (every 30 d); proof test
    OVERDUE: never passed (every 30 d)``. A warning only: nothing stops for it."""
    parts = []
    for test, due in schedule.tests():
        age, every = due.last_pass_age_s, due.interval_days
        when = "never passed" if age is None else f"passed {duration(age)} ago"
        plan = f"every {every} d" if every else "no schedule"
        overdue = "OVERDUE: " if due.overdue else ""
        parts.append(f"{TEST_NAMES[test]} {overdue}{when} ({plan})")
    return "; ".join(parts)


def estop_text(available: EstopAvailable) -> str:
    """``available``, or ``NOT AVAILABLE: `` and each part missing (SR-8.11)."""
    if available.available:
        return "available"
    return "NOT AVAILABLE: " + ("; ".join(available.missing) or "no reason given")


def duration(seconds: float) -> str:
    """``12.3 s``, ``4 min 5 s``, ``2 h 3 min``, ``1 d 2 h``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = int(seconds)
    if whole < 3600:
        return f"{whole // 60} min {whole % 60} s"
    if whole < 86400:
        return f"{whole // 3600} h {whole % 3600 // 60} min"
    return f"{whole // 86400} d {whole % 86400 // 3600} h"


def _client_lines(clients: tuple[ClientStatus, ...]) -> list[str]:
    if not clients:
        return ["  clients  none"]
    lines = []
    for index, client in enumerate(clients):
        kind = f"required, {client.timeout_ms} ms" if client.required else "optional"
        age = client.heartbeat_age_s
        if not client.connected:
            beat = "not connected"
        elif age is None:
            beat = "connected, no heartbeat yet"
        else:
            beat = f"heartbeat {duration(age)} ago"
        label = "clients" if index == 0 else ""
        lines.append(f"  {label:8} {client.name} ({kind}): {beat}")
    return lines


def remote_text(remote: RemoteReport | RemoteStatusReport) -> str:
    """The remote's last status (manual §8.3.4; kept by the VSC after a link loss, PR-2.10)."""
    charging = ", charging" if remote.battery_charging else ""
    age = remote.age_s if isinstance(remote, RemoteReport) else None
    return (
        f"battery {remote.battery_level} %{charging}; link strength vsc "
        f"{remote.connection_strength_vsc} remote {remote.connection_strength_src}"
        f"; rssi vsc {remote.rssi_vsc} remote {remote.rssi_src}"
        + (f" ({duration(age)} ago)" if age is not None else "")
    )


def _cause_text(cause: Cause) -> str:
    """``vsc_estop (stop, active) sources=remote``; a cleared cause its latch still holds is
    marked as everywhere (``vsc_estop* (stop)``, docs/srcsctl.md "Marks")."""
    from supervisord.cli.record_text import mark  # noqa: PLC0415 -- when used (SR-8.8)

    state = ", active" if cause.active else ""
    details = " ".join(f"{k}={v}" for k, v in cause.details.items())
    return f"{mark(cause.name, held=cause.held)} ({cause.severity}{state}) {details}".rstrip()


# -- watch ---------------------------------------------------------------------------------


def _watch(
    path: Path, operator: Path | None, args: argparse.Namespace, out: TextIO, err: TextIO
) -> int:
    """Follow the daemon until Ctrl-C or SIGTERM, reconnecting when it restarts.

    The first state is the push the daemon sends right after ``subscribe`` (docs/api.md), so
    it is printed once, and with ``--json`` every line is a push; the human form
    starts with one line about the daemon (version, uptime, clients) from ``status``."""
    topics = [
        "state",
        "records",
        *(["joystick"] if args.joystick else []),
        *([] if args.json else ["remote_status"]),
    ]
    utc = bool(getattr(args, "utc", False))
    args.json = args.json or args.output == "json"

    def show(push: Push) -> str:
        return (
            json.dumps(push.json(), sort_keys=True)
            if args.json
            else format_push(push, utc=utc, causes=args.causes)
        )

    said_waiting = False
    try:
        interruptible()  # inside: a signal from here on ends it with exit 0 (SR-8.9)
        while True:
            try:
                with connect(path, operator) as client:
                    said_waiting = False
                    if not args.json:
                        print(daemon_line(client.status()), file=out, flush=True)
                    client.subscribe(*topics)
                    last: dict[str, object] = {}
                    while True:
                        push = client.next_event(timeout=3600)
                        if push is None:
                            continue
                        seen = None if args.json else shown_when(push)
                        if seen is not None:
                            if seen == last.get(push.event):
                                continue
                            last[push.event] = seen
                        print(show(push), file=out, flush=True)
            except ConnectError as error:
                if isinstance(error.__cause__, PermissionError):
                    print(f"srcsctl watch: {denied(path, error)}", file=err, flush=True)
                    return EXIT_DENIED
                said_waiting = _waiting(error, said_waiting, err)
            except (ClientError, ApiError) as error:
                said_waiting = _waiting(error, said_waiting, err)
    except KeyboardInterrupt:
        return 0


def shown_when(push: Push) -> object:
    """What of a push makes ``watch`` print one of its kind again, or ``None``: every one is
    printed. A remote status: when battery or link strength change, not once a second. A
    state: when the state or an output changes; each cause raised or cleared has its
    record's line."""
    if isinstance(push, RemoteStatusPush):
        message = push.message
        return (
            message.battery_level,
            message.battery_charging,
            message.connection_strength_vsc,
            message.connection_strength_src,
        )
    if isinstance(push, StatePush):
        return (push.report.state, dict(push.report.outputs))
    return None


def _waiting(error: Exception, said: bool, err: TextIO) -> bool:
    if not said:
        print(f"srcsctl watch: {error}; retrying every second", file=err, flush=True)
    time.sleep(RECONNECT_S)
    return True


def daemon_line(status: StatusReply) -> str:
    """``watch``'s first line: which daemon it follows (``#``: not an event)."""
    daemon = status.daemon
    up = daemon.loop.uptime_s
    names = ", ".join(
        f"{c.name}{'' if c.connected else ' (not connected)'}" for c in daemon.clients
    )
    return (
        f"# srcsd {daemon.loop.version} robot {daemon.robot or '?'}, pid {daemon.loop.pid}"
        + (f", up {duration(up)}" if up is not None else "")
        + f"; clients: {names or 'none'}"
    )


def format_push(
    push: Push,
    *,
    utc: bool = False,
    now: dt.datetime | None = None,
    causes: bool = False,
) -> str:
    """One line for a push: the time of day (local, or UTC with ``utc``: the rule of
    ``log``), then what happened. A record is the line ``log`` prints for it, at its own
    time; a state is the state, its causes (marked as everywhere) and the outputs."""
    from supervisord.cli.record_text import mark, record_line  # noqa: PLC0415 -- when used (SR-8.8)

    stamp = clock(now or dt.datetime.now(dt.timezone.utc), utc=utc)
    if isinstance(push, StatePush):
        report = push.report
        names = ", ".join(mark(c.name, held=c.held) for c in report.causes) or "no causes"
        outputs = " ".join(f"{k}={'ON' if v else 'off'}" for k, v in report.outputs.items())
        return f"{stamp} {report.state:8} {names} | {outputs}"
    if isinstance(push, RecordPush):
        record = push.record  # read as the record file holds it (docs/record.md)
        return record_line(record, clock_of(record.utc, utc=utc), causes=causes)
    if isinstance(push, RemoteStatusPush):
        return f"{stamp} remote {remote_text(push.message)}"
    if isinstance(push, JoystickPush):
        message = push.message
        axes = " ".join(f"{name}={axis.value}" for name, axis in message.axes().items())
        return f"{stamp} joystick {axes} pressed {','.join(message.pressed) or '-'}"
    return f"{stamp} {push.event} {json.dumps(push.json(), sort_keys=True)}"
