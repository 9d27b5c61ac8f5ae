"""Man pages and shell completion, generated from the commands' own argument parsers.

    python -m supervisord.cli.reference man OUTDIR         # srcsd.8 srcsctl.1 ...
    python -m supervisord.cli.reference completion OUTDIR  # OUTDIR/srcsctl, OUTDIR/zsh/_srcsctl ...

``man`` writes srcsd.8, srcsctl.1, srcs-sim.1, srcs-exporter.8, srcs-fleet-agent.8 and the
collector's srcs-fleet-targets.8 and srcs-fleet-pki.8 (``--only NAME...``: those alone), and
with srcsd's the configuration file's, srcsd.toml.5, from its JSON Schema
(:mod:`supervisord.cli.config_page`); ``completion`` writes one bash file per command, named
after it (bash-completion's convention), and zsh's ``_NAME``.

The package build runs both (docs/srcsctl.md "Man pages and completion"). The options, their
arguments and help, the commands of ``srcsctl`` and their usage lines come from the very
parsers the programs parse with (each module's ``build_parser()``), through two libraries:
argparse-manpage for the roff and shtab for the completion scripts. A page therefore cannot
list an option the program has lost, nor miss one it gained. What a parser does not know is
written here, once per command: a description for a person, the exit statuses, the environment,
the files and related pages.

``srcs-ros2`` has no page: it takes ROS's own arguments (``--ros-args -p NAME:=VALUE``) and
has no argparse parser to generate one from (docs/ros2.md).

A build-time tool: it needs the ``dev`` extra (argparse-manpage, shtab) and no program imports
it. Output is reproducible: the text is laid out at a fixed width whatever the terminal, and
the date on each page is ``SOURCE_DATE_EPOCH``'s when it is set (today's otherwise).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import shtab
from argparse_manpage.compat import get_reproducible_date
from argparse_manpage.manpage import Manpage

from supervisord import __version__
from supervisord.cli import config_page, srcsctl
from supervisord.cli.cause_names import CAUSE_NAMES
from supervisord.cli.output_file import OutputRefused, write_output

PROJECT = "srcs-supervisord"
DOC_DIR = f"/usr/share/doc/{PROJECT}"
COLLECTOR_DOC_DIR = "/usr/share/doc/srcs-collector"
MANUALS = {1: "User Commands", 8: "System Administration Commands"}

FILE_METAVARS = frozenset({"FILE", "PATH", "SOCKET", "SYMLINK"})
"""Options whose value is a path: completed with file names (shtab.FILE)."""
FILE_POSITIONALS = frozenset({("srcsctl decode", "file"), ("srcsctl replay", "window")})
"""Positional arguments that name a file, by (parser, dest)."""

ROBOTS = {
    "bash": "_srcs_robots_compgen",
    "zsh": "_srcs_robots",
    "preamble": {
        "bash": "_srcs_robots_compgen() {\n"
        "  local robots=() f\n"
        f"  for f in {srcsctl.CONFIG_DIR}/*.toml; do\n"
        '    [ -f "$f" ] || continue\n'
        "    f=${f##*/}\n"
        '    robots+=("${f%.toml}")\n'
        "  done\n"
        '  compgen -W "${robots[*]}" -- "$1"\n'
        "}\n",
        "zsh": "_srcs_robots() {\n"
        "  local -a robots\n"
        f"  robots=({srcsctl.CONFIG_DIR}/*.toml(N:t:r))\n"
        "  compadd -a robots\n"
        "}\n",
    },
}
"""``--robot``'s values: the robots of ``/etc/srcs/NAME.toml``, as ``--robot`` finds them,
read when completing (a robot added later is offered)."""
_CAUSE_WORDS = " ".join(CAUSE_NAMES)
CAUSES = {
    "bash": "_srcs_causes_compgen",
    "zsh": f"({_CAUSE_WORDS})",
    "preamble": {"bash": f'_srcs_causes_compgen() {{\n  compgen -W "{_CAUSE_WORDS}" -- "$1"\n}}\n'},
}
"""``--cause``'s values: the safety core's cause names."""
COMPLETE_BY_DEST = {"robot": ROBOTS, "cause": CAUSES, "cause_present": CAUSES}
"""Options completed from a list of their own, by ``dest``."""


@dataclass(frozen=True)
class Command:
    """One program: its parser and what the parser does not say."""

    name: str
    section: int
    build: Callable[[], argparse.ArgumentParser]
    summary: str
    """The NAME line, after the dash."""
    description: tuple[str, ...]
    """Paragraphs of DESCRIPTION, plain text."""
    exit_status: tuple[tuple[str, str], ...]
    files: tuple[tuple[str, str], ...]
    see_also: tuple[str, ...]
    """``name(section)`` entries."""
    environment: tuple[tuple[str, str], ...] = ()


def _parser(module: str) -> Callable[[], argparse.ArgumentParser]:
    """``supervisord.cli.MODULE.build_parser``, imported when a page is made: the collector's
    package (packaging/build_collector_deb.py) generates its pages without the robot's
    dependencies (pyserial, python-can), which the daemon's and simulator's modules import."""

    def build() -> argparse.ArgumentParser:
        parser: argparse.ArgumentParser = importlib.import_module(
            f"supervisord.cli.{module}"
        ).build_parser()
        return parser

    return build


CONFIG_FILE = ("/etc/srcs/NAME.toml", "a robot's configuration, one per srcsd@NAME instance")
API_SOCKET = ("/run/srcsd/api.sock", "the API socket (its [api] socket in the configuration)")
RECORD_FILE = (
    "/var/lib/srcsd/stops.jsonl",
    "the record of stops, one JSON line per stop and re-arm, with its rotated files "
    "(its [record] path)",
)
DOCS = (
    f"{DOC_DIR}/",
    "the documentation (installation, configuration, safety rules, API) and example configurations",
)

COMMANDS: tuple[Command, ...] = (
    Command(
        name="srcsd",
        section=8,
        build=_parser("srcsd"),
        summary="safety supervisor for a robot with an SRCS remote",
        description=(
            "srcsd runs as a systemd service, one instance per robot: srcsd@NAME reads "
            "/etc/srcs/NAME.toml. It owns the link to the remote's receiver on the vehicle "
            "(the VSC, over serial, CAN J1939 or USB HID), feeds the VSC's watchdog, turns "
            "silence into a stop, drives the enable lines of the motion controllers and "
            "records every stop. The robot's software and srcsctl(1) talk to it over a Unix "
            "socket.",
            "It starts STOPPED; the operator's takeover on the remote re-arms it. Its log "
            "lines reach the journal with their own priority (journalctl -u srcsd@NAME -p "
            "warning). The whole configuration is validated before anything is opened; "
            "--check-config validates a file without starting.",
        ),
        exit_status=(
            ("0", "stopped by SIGTERM or SIGINT, every output off; with --check-config: valid"),
            (
                "1",
                "a valid configuration, but a resource could not be had (the record's "
                "directory, a socket held by another server); systemd restarts it. With "
                "--check-config: the file is invalid",
            ),
            ("2", "bad arguments"),
            (
                "78",
                "a configuration error: invalid, missing or unreadable (EX_CONFIG). The "
                "unit's RestartPreventExitStatus=78 makes it fail at once instead of "
                "restarting",
            ),
            (
                "128+N",
                "stopped by another signal N (SIGHUP, SIGQUIT, SIGUSR1, ...), every output off "
                "as for SIGTERM; systemd restarts it, STOPPED",
            ),
        ),
        files=(CONFIG_FILE, API_SOCKET, RECORD_FILE, DOCS),
        see_also=(
            "srcsctl(1)",
            "srcsd.toml(5)",
            "srcs-exporter(8)",
            "srcs-sim(1)",
            "systemd.service(5)",
            "journalctl(1)",
        ),
    ),
    Command(
        name="srcsctl",
        section=1,
        build=srcsctl.build_parser,
        summary="control and inspect the SRCS safety supervisor",
        description=(
            "srcsctl talks to a running srcsd(8) over its API socket: its state and causes "
            "(status, watch), a stop or hold from the vehicle computer (estop, hold, release, "
            "reset), the remote's screen and vibration, the VSC's watchdog (commission, "
            "prooftest), and the gate a robot's services start behind (wait-ready). It also "
            "reads files: the record of stops (log), the flight "
            "recorder's window of a stop, replayed through a fresh safety core and checked "
            "against the record (replay), and captures of VSC traffic (decode). The demo runs "
            "the supervisor against the simulated VSC.",
            "The daemon is the one at --socket PATH, else the [api] socket of --config FILE, "
            "else $SRCS_SOCKET, else /run/srcsd/api.sock. Times are local with their offset, "
            "or UTC with --utc. A * after a cause means its condition has cleared and the "
            "stop waits for a re-arm.",
        ),
        exit_status=(
            ("0", "done"),
            (
                "1",
                "the daemon refused or the action failed (the reason is printed), or a "
                "commissioning was not confirmed; replay: the replay differs from the record; "
                "wait-ready: not ready at the timeout (what is missing is printed)",
            ),
            (
                "2",
                "usage or configuration error; decode: some input was unreadable; replay: the "
                "window cannot be read or replayed",
            ),
            (
                "3",
                "no daemon answers at the socket; replay: not checked against the record file "
                "(it does not hold the stop record, or cannot be read)",
            ),
            ("4", "the socket exists but this user may not open it"),
            (
                "5",
                "replay: the window's copy of the stop record differs from the record file's",
            ),
        ),
        environment=(
            ("SRCS_SOCKET", "the API socket when neither --socket nor --config is given"),
        ),
        files=(
            API_SOCKET,
            (
                "/etc/srcs/*.toml",
                "the robots' configurations: log and replay read the only one there when "
                "given neither --config nor --file",
            ),
            RECORD_FILE,
            (
                "/var/lib/srcsd/stops.jsonl.flight/SEQ.jsonl",
                "the flight recorder's window of stop record SEQ, which replay reads",
            ),
            DOCS,
        ),
        see_also=("srcsd(8)", "srcs-sim(1)", "srcs-exporter(8)"),
    ),
    Command(
        name="srcs-sim",
        section=1,
        build=_parser("sim"),
        summary="a simulated SRCS VSC with its remote",
        description=(
            "srcs-sim simulates the SRCS receiver on the vehicle (the VSC) and its remote, "
            "on a pseudo-terminal (--serial) or a CAN bus (--can), for testing srcsd(8) and "
            "the robot's own code without the hardware. It prints the port it serves and "
            "then 'srcs-sim: ready'. Keys drive it when its input is a terminal (h lists "
            "them); the control socket (--control) drives it from tests.",
            "A udp_multicast CAN bus is for processes of one machine only: run them inside "
            "a private network namespace.",
        ),
        exit_status=(
            ("0", "stopped by SIGTERM or SIGINT; the pseudo-terminal and socket are removed"),
            ("2", "bad arguments, an unreadable EEPROM file, a port that cannot be made"),
        ),
        files=(DOCS,),
        see_also=("srcsd(8)", "srcsctl(1)"),
    ),
    Command(
        name="srcs-exporter",
        section=8,
        build=_parser("exporter"),
        summary="the SRCS safety supervisor's state and counters as Prometheus metrics",
        description=(
            "srcs-exporter follows one srcsd(8) over its API socket and serves its state, "
            "causes, stops and re-arms, link, traffic, heartbeat and stop-latency histograms "
            "and the remote's battery and signal over HTTP, as OpenMetrics for Prometheus. "
            "It runs as its own service, srcs-exporter@NAME, so that the supervisor itself "
            "keeps no network access. It listens on loopback unless told otherwise.",
        ),
        exit_status=(
            ("0", "stopped by SIGTERM or SIGINT"),
            ("1", "it cannot listen on its address"),
            ("2", "bad arguments"),
            ("78", "a configuration it cannot read, or a --poll out of range (no restart)"),
        ),
        files=(CONFIG_FILE, API_SOCKET, DOCS),
        see_also=("srcsd(8)", "srcsctl(1)", "prometheus(1)"),
    ),
    Command(
        name="srcs-fleet-agent",
        section=8,
        build=_parser("fleet_agent"),
        summary="a robot's end of the fleet stop: the fleet's MQTT broker to srcsd",
        description=(
            "srcs-fleet-agent carries the fleet's stops to one srcsd(8), so that the "
            "supervisor itself keeps no network access. It subscribes, over mutual TLS, to "
            "the robot's stops at the fleet's MQTT broker (to all, to its groups, to itself), "
            "refuses a replayed or stale message, passes each fresh one to srcsd as "
            "fleet_stop or fleet_release, and publishes srcsd's acknowledgement: the state "
            "after the stop, every output's read-back, the stop record's number and the time "
            "from the stop's arrival to the outputs off. Nothing it passes on can re-arm the "
            "robot or turn an output on.",
            "It runs as its own service, srcs-fleet-agent@NAME, as the user srcs-fleet, which "
            "the robot's configuration names in [fleet] agent_user. The package installs it "
            "disabled: a fleet enables it per robot (systemctl enable --now "
            "srcs-fleet-agent@NAME) once /etc/srcs/fleet-NAME.env and the certificates are "
            "in place.",
        ),
        exit_status=(
            ("0", "stopped by SIGTERM or SIGINT"),
            ("2", "bad arguments"),
            (
                "78",
                "a configuration, certificate or key it cannot read (the unit does not restart it)",
            ),
        ),
        files=(
            CONFIG_FILE,
            ("/etc/srcs/fleet-NAME.env", "the fleet, the robot, its groups and the broker"),
            ("/etc/srcs/fleet/", "ca.pem, the fleet's CA, and the robot's ROBOT.pem and ROBOT.key"),
            API_SOCKET,
            DOCS,
        ),
        see_also=("srcsd(8)", "srcsctl(1)", "mosquitto(8)"),
    ),
    Command(
        name="srcs-fleet-targets",
        section=8,
        build=_parser("fleet_targets"),
        summary="the fleet's Prometheus targets, generated from the list of robots",
        description=(
            "srcs-fleet-targets reads the fleet's list of robots, one 'NAME [ADDRESS[:PORT]]' "
            "a line, and writes the file_sd targets file the collector's Prometheus reads, "
            "the robot's name as the target label robot. Every line is checked first (a host "
            "name, an address, a port, nothing twice); the file is replaced in one rename, "
            "and a refused list leaves the old one. Prometheus re-reads the file by itself.",
        ),
        exit_status=(
            ("0", "written"),
            ("2", "bad arguments, an unreadable list, a line that is no robot"),
        ),
        files=(
            ("/etc/srcs-collector/robots", "the list of robots"),
            ("/var/lib/srcs-collector/targets/robots.yml", "the targets Prometheus reads"),
            (f"{COLLECTOR_DOC_DIR}/", "the fleet's documentation (docs/fleet.md)"),
        ),
        see_also=("srcsctl(1)", "srcs-fleet-pki(8)", "prometheus(1)"),
    ),
    Command(
        name="srcs-fleet-pki",
        section=8,
        build=_parser("fleet_pki"),
        summary="make and renew the fleet's certificates",
        description=(
            "srcs-fleet-pki makes the fleet's certificates with openssl(1): the CA (ca), the "
            "collector's server certificate for every name and address the robots connect to "
            "(server), and one client certificate per robot with its host name as the CN "
            "(robot). Making again is renewing: a new key and certificate signed by the same "
            "CA; ca on an existing CA signs a new CA certificate with the same key, so every "
            "certificate it signed stays valid. status lists the days each has left.",
            "Keep the CA's key off the collector when you can: make the certificates on an "
            "administrator's machine with --dir, and copy each robot's pair to its robot.",
        ),
        exit_status=(
            ("0", "made, or listed"),
            ("1", "openssl failed or is missing, a file could not be written, a bad name"),
            ("2", "bad arguments"),
        ),
        files=(
            ("/etc/srcs-collector/pki/", "ca.pem, collector.pem, NAME.pem and their keys"),
            (f"{COLLECTOR_DOC_DIR}/", "the fleet's documentation (docs/fleet.md)"),
        ),
        see_also=("srcsctl(1)", "srcs-fleet-targets(8)", "openssl(1)"),
    ),
)
COLLECTOR_COMMANDS = ("srcsctl", "srcs-fleet-targets", "srcs-fleet-pki")
"""The collector package's commands (packaging/build_collector_deb.py); the robot's package
leaves the two srcs-fleet-* out."""


class _UnwrappedFormatter(argparse.HelpFormatter):
    """One line per usage and help text: man fills the text to the reader's width, and the
    output does not depend on the terminal the build ran in."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, width=100_000, max_help_position=100_000)


def walk(
    parser: argparse.ArgumentParser, path: str | None = None
) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every parser of a command, by its path (``srcsctl``, ``srcsctl display row``)."""
    path = path or parser.prog
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from walk(child, f"{path} {name}")


def prepared(command: Command) -> argparse.ArgumentParser:
    """A fresh parser of ``command``, ready for the libraries: unwrapped text, its commands
    under COMMANDS rather than "positional arguments", paths completed as file names."""
    parser = command.build()
    for path, each in walk(parser):
        each.formatter_class = _UnwrappedFormatter
        for group in each._action_groups:
            if any(isinstance(a, argparse._SubParsersAction) for a in group._group_actions):
                group.title = "commands"
        for action in each._actions:
            if action.metavar in FILE_METAVARS or (path, action.dest) in FILE_POSITIONALS:
                action.complete = shtab.FILE  # type: ignore[attr-defined]  # shtab's documented hook
            elif action.option_strings and action.dest in COMPLETE_BY_DEST:
                action.complete = COMPLETE_BY_DEST[action.dest]  # type: ignore[attr-defined]
    return parser


def _roff(text: str) -> str:
    """Plain text as roff: backslashes and hyphens escaped, no line starting a request."""
    text = text.replace("\\", "\\e").replace("-", "\\-")
    return "\n".join(
        "\\&" + line if line.startswith((".", "'")) else line for line in text.split("\n")
    )


def _entries(pairs: Sequence[tuple[str, str]]) -> str:
    return "\n".join(f".TP\n.B {_roff(term)}\n{_roff(text)}" for term, text in pairs)


def _see_also(refs: Sequence[str]) -> str:
    items = []
    for ref in refs:
        name, _, section = ref.rstrip(")").partition("(")
        items.append(f".BR {_roff(name)} ({section})")
    return ",\n".join(items)


def man_page(command: Command, version: str = __version__) -> str:
    """The roff source of ``command``'s man page."""
    parser = prepared(command)
    parser.description = None  # replaced by the DESCRIPTION below, written for a person
    page = Manpage(parser, format="single-commands-section")
    page.section = command.section
    page.source = f"{PROJECT} {version}"
    page.manual = MANUALS[command.section]
    page.description = command.summary
    page.add_section("description", "=", "\n.PP\n".join(_roff(p) for p in command.description))
    page.add_section("exit status", ">", _entries(command.exit_status))
    if command.environment:
        page.add_section("environment", ">", _entries(command.environment))
    page.add_section("files", ">", _entries(command.files))
    page.add_section("see also", ">", _see_also(command.see_also))
    lines = str(page).split("\n")
    # No hyphenation and no justification: an option such as --check-config is never split
    # across lines (a reader can copy it), and a long synopsis is not stretched apart.
    lines[1:1] = [".nh", ".ad l"]
    # The library leaves the synopsis' dashes as hyphens; every other option is a minus
    # (man-pages(7), "hyphen-used-as-minus-sign").
    synopsis = lines.index(".SH SYNOPSIS") + 2
    lines[synopsis] = _roff(lines[synopsis])
    return "\n".join(lines)


def completion(command: Command, shell: str) -> str:
    """``command``'s completion script for ``shell`` (bash or zsh)."""
    script = shtab.complete(prepared(command), shell=shell)
    note = f"# {command.name}: generated from its parser by supervisord/cli/reference.py\n"
    if script.startswith("#compdef"):  # zsh reads its first line: it stays first
        first, _, rest = script.partition("\n")
        return f"{first}\n{note}{rest}"
    return note + script


def chosen(only: Sequence[str] = ()) -> list[Command]:
    """The commands named in ``only`` (every one when empty). Raises ``ValueError``."""
    unknown = set(only) - {command.name for command in COMMANDS}
    if unknown:
        raise ValueError(f"no such command: {', '.join(sorted(unknown))}")
    return [command for command in COMMANDS if not only or command.name in only]


def _write(path: Path, text: str) -> None:
    """Safely against links and shared folders, as every file a command writes (SR-11.4): a
    package build may run this as root into a folder others can write."""
    data = text.encode("utf-8")
    write_output(path, lambda file: file.write(data))


def write_man(outdir: Path, only: Sequence[str] = ()) -> list[Path]:
    """Write every man page (or those of ``only``) into ``outdir``; return their paths."""
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    for command in chosen(only):
        path = outdir / f"{command.name}.{command.section}"
        _write(path, man_page(command))
        written.append(path)
        if command.name == "srcsd":
            # The daemon's file, with the daemon's page: only where srcsd is (not the
            # collector's package, whose build would import no output plugin).
            path = outdir / f"{config_page.NAME}.{config_page.SECTION}"
            _write(path, toml_page())
            written.append(path)
    return written


def toml_page(version: str = __version__) -> str:
    """srcsd.toml(5) from the configuration's JSON Schema, dated as the other pages."""
    from supervisord.config import schema  # noqa: PLC0415 - imports every output plugin

    return config_page.config_page(
        schema.json_schema(), schema.CROSS_CHECKS, version, get_reproducible_date()
    )


def write_completion(outdir: Path, only: Sequence[str] = ()) -> list[Path]:
    """Write bash completion as ``outdir/NAME`` (bash-completion loads a command's file by
    the command's name) and zsh's as ``outdir/zsh/_NAME``; return their paths."""
    (outdir / "zsh").mkdir(parents=True, exist_ok=True)
    written = []
    for command in chosen(only):
        for path, shell in (
            (outdir / command.name, "bash"),
            (outdir / "zsh" / f"_{command.name}", "zsh"),
        ):
            _write(path, completion(command, shell))
            written.append(path)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m supervisord.cli.reference",
        description="Write the man pages or the shell completion of every command.",
    )
    parser.add_argument("what", choices=("man", "completion"))
    parser.add_argument("outdir", type=Path)
    parser.add_argument("--only", nargs="+", default=[], metavar="NAME", help="these commands")
    args = parser.parse_args(argv)
    write = write_man if args.what == "man" else write_completion
    try:
        written = write(args.outdir, args.only)
    except (OSError, ValueError, OutputRefused) as error:
        print(f"reference: {error}", file=sys.stderr)
        return 1
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
