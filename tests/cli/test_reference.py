"""The man pages and shell completion generated from the commands' own parsers
(``supervisord/cli/reference.py``; docs/srcsctl.md "Man pages and
completion"): every option of every parser is in its page and its completion, ``man`` renders
each page without a warning, and a real bash completes from the files as installed."""

from __future__ import annotations

import argparse
import os
import pty
import select
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from supervisord import __version__
from supervisord.cli import reference
from supervisord.cli.reference import COMMANDS, Command
from supervisord.testkit.namespaces import in_private_mount

REPO = Path(__file__).resolve().parents[2]
BASH_COMPLETION = Path("/usr/share/bash-completion/bash_completion")
MAN = shutil.which("man")
BASH = shutil.which("bash") or "/bin/bash"

BY_NAME = {command.name: command for command in COMMANDS}
ids = [command.name for command in COMMANDS]


def _roff(text: str) -> str:
    return text.replace("-", "\\-")


def _options(parser: argparse.ArgumentParser, *, with_help: bool) -> list[str]:
    return [
        option
        for action in parser._actions
        if with_help or not isinstance(action, argparse._HelpAction)
        for option in action.option_strings
    ]


def _subcommands(parser: argparse.ArgumentParser) -> list[str]:
    return [
        name
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for name in action.choices
    ]


def _positional_words(parser: argparse.ArgumentParser) -> list[str]:
    """What names each positional argument on a page: its choices, or its metavar or dest."""
    words: list[str] = []
    for action in parser._actions:
        if action.option_strings or isinstance(action, argparse._SubParsersAction):
            continue
        if action.choices:
            words.extend(str(choice) for choice in action.choices)
        else:
            words.append(str(action.metavar or action.dest))
    return words


def missing_from_page(command: Command, page: str) -> list[str]:
    """Each parser's options, positional arguments and subcommands that its page lacks: a
    subcommand's under its own heading (``.SS srcsctl log``) or after it."""
    missing = []
    for path, parser in reference.walk(command.build()):
        start = 0
        if path != command.name:
            heading = f".SS \\fB{_roff(path)}\\fR"
            if heading not in page:
                missing.append(f"{path}: no heading")
                continue
            start = page.index(heading)
        after = page[start:]
        missing += [
            f"{path} {option}"
            for option in _options(parser, with_help=False)
            if f"\\fB{_roff(option)}\\fR" not in after
        ]
        missing += [
            f"{path} {word}" for word in _positional_words(parser) if _roff(word) not in after
        ]
        missing += [
            f"{path} {name}"
            for name in _subcommands(parser)
            if _roff(f"{path} {name}") not in after
        ]
    return missing


def _built(tmp_path_factory: pytest.TempPathFactory, kind: str) -> Path:
    """What the package build writes (``man`` or ``completion``), through the command line
    it calls."""
    out = tmp_path_factory.mktemp(kind)
    subprocess.run(
        [sys.executable, "-m", "supervisord.cli.reference", kind, str(out)],
        check=True,
        capture_output=True,
        cwd=REPO,
        timeout=60,
    )
    return out


@pytest.fixture(scope="module")
def man_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pages as the package build writes them, through the command line it calls."""
    return _built(tmp_path_factory, "man")


@pytest.fixture(scope="module")
def completion_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The completion files as the package build writes them, through its command line."""
    return _built(tmp_path_factory, "completion")


def test_the_command_line_writes_the_files_the_package_build_installs(
    man_dir: Path, completion_dir: Path
) -> None:
    """``man OUTDIR`` writes one page per command named NAME.SECTION, and ``completion
    OUTDIR`` one bash file named after each command (bash-completion loads it by that name)
    and zsh's ``zsh/_NAME``; no page for srcs-ros2, which has no argparse parser. The
    collector's two tools have theirs (packaging/build_collector_deb.py, SR-13.10), and the
    fleet stop's agent its own, in the robot's package (SR-13.13)."""
    assert sorted(p.name for p in man_dir.iterdir()) == [
        "srcs-exporter.8",
        "srcs-fleet-agent.8",
        "srcs-fleet-pki.8",
        "srcs-fleet-targets.8",
        "srcs-sim.1",
        "srcsctl.1",
        "srcsd.8",
        "srcsd.toml.5",
    ]
    names = [
        "srcs-exporter",
        "srcs-fleet-agent",
        "srcs-fleet-pki",
        "srcs-fleet-targets",
        "srcs-sim",
        "srcsctl",
        "srcsd",
    ]
    assert sorted(p.name for p in completion_dir.iterdir() if p.is_file()) == names
    assert sorted(p.name for p in (completion_dir / "zsh").iterdir()) == [f"_{n}" for n in names]


@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_every_option_of_every_parser_is_in_its_man_page(man_dir: Path, command: Command) -> None:
    """Every option, positional argument and subcommand of every parser of the command (all
    of srcsctl's commands, down to ``display row``) is on its page, under its command."""
    page = (man_dir / f"{command.name}.{command.section}").read_text()
    assert missing_from_page(command, page) == []


def test_an_option_the_page_lacks_is_found() -> None:
    """The check above can fail: a page without ``--lines`` (of ``srcsctl log`` and ``srcsctl
    fleet``) is caught for each command."""
    command = BY_NAME["srcsctl"]
    page = reference.man_page(command)
    assert "\\fB\\-\\-lines\\fR" in page
    assert missing_from_page(command, page.replace("\\fB\\-\\-lines\\fR", "")) == [
        "srcsctl log --lines",
        "srcsctl fleet --lines",
    ]


@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_each_page_has_the_sections_a_reader_looks_for(man_dir: Path, command: Command) -> None:
    """NAME, SYNOPSIS, DESCRIPTION, EXIT STATUS, FILES and SEE ALSO in man-pages(7) order,
    the package's version in the header, and the section the page is installed in."""
    page = (man_dir / f"{command.name}.{command.section}").read_text()
    header = page.split("\n", 1)[0]
    assert header.startswith(f'.TH {_roff(command.name.upper())} "{command.section}" ')
    assert f'"srcs\\-supervisord {_roff(__version__)}"' in header
    order = [".SH NAME", ".SH SYNOPSIS", ".SH DESCRIPTION", ".SH EXIT STATUS", ".SH FILES"]
    order.append(".SH SEE ALSO")
    positions = [page.index(heading) for heading in order]
    assert positions == sorted(positions)
    assert "\\fB\\-\\-help\\fR" not in page  # argparse-manpage leaves -h out on purpose


def test_the_srcsd_page_names_its_files_and_exit_78() -> None:
    """srcsd(8) lists the configs, the API socket and the stop record under FILES, and exit
    status 78 for a configuration error (SR-11.2) under EXIT STATUS."""
    page = reference.man_page(BY_NAME["srcsd"])
    files = page[page.index(".SH FILES") : page.index(".SH SEE ALSO")]
    for path in ("/etc/srcs/NAME.toml", "/run/srcsd/api.sock", "/var/lib/srcsd/stops.jsonl"):
        assert f".B {_roff(path)}" in files
    status = page[page.index(".SH EXIT STATUS") : page.index(".SH FILES")]
    assert ".B 78\na configuration error" in status


def test_a_page_does_not_depend_on_the_terminal_or_the_day(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The same page whatever ``COLUMNS`` the build ran with (argparse wraps to it), and
    dated by ``SOURCE_DATE_EPOCH``: a reproducible build."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "86400")
    monkeypatch.setenv("COLUMNS", "40")
    narrow = reference.man_page(BY_NAME["srcsctl"])
    monkeypatch.setenv("COLUMNS", "300")
    wide = reference.man_page(BY_NAME["srcsctl"])
    assert narrow == wide
    assert '"1970\\-01\\-02"' in narrow.split("\n", 1)[0]


@pytest.mark.skipif(MAN is None, reason="needs man-db and groff")
@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_man_renders_each_page_without_a_warning(man_dir: Path, command: Command) -> None:
    """``man -l --warnings`` renders the page with nothing on stderr (groff's warnings go
    there), with the program's name and its exit statuses in the text."""
    assert MAN is not None
    result = subprocess.run(
        [MAN, "-l", "--warnings", str(man_dir / f"{command.name}.{command.section}")],
        capture_output=True,
        text=True,
        env={**os.environ, "MANWIDTH": "80", "MANPAGER": "cat", "PAGER": "cat"},
        timeout=60,
        check=False,
    )
    assert (result.returncode, result.stderr) == (0, "")
    assert "EXIT STATUS" in result.stdout
    assert f"{command.name.upper()}({command.section})" in result.stdout


@pytest.mark.skipif(MAN is None, reason="needs man-db and groff")
def test_the_warning_check_sees_a_broken_page(tmp_path: Path) -> None:
    """The check above can fail: a page with an unknown request is reported on stderr."""
    assert MAN is not None
    page = tmp_path / "broken.1"
    page.write_text(".TH BROKEN 1\n.SH NAME\nbroken \\- a test\n.NOSUCHMACRO\n")
    result = subprocess.run(
        [MAN, "-l", "--warnings", str(page)],
        capture_output=True,
        text=True,
        env={**os.environ, "MANWIDTH": "80", "MANPAGER": "cat", "PAGER": "cat"},
        timeout=60,
        check=False,
    )
    assert "NOSUCHMACRO" in result.stderr


@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_bash_accepts_each_completion_file(completion_dir: Path, command: Command) -> None:
    """``bash -n`` parses the file, and sourcing it registers a completion for the command."""
    path = completion_dir / command.name
    subprocess.run([BASH, "-n", str(path)], check=True, timeout=30)
    result = subprocess.run(
        [
            BASH,
            "--norc",
            "--noprofile",
            "-c",
            f'source "$1" && complete -p {command.name}',
            "-",
            path,
        ],
        capture_output=True,
        text=True,
        timeout=30,
        check=True,
    )
    assert f" {command.name}\n" in result.stdout


COMPLETE_EACH_LINE = r"""
source "$1"
fn=$(complete -p "$2" | sed -E 's/.* -F ([^ ]+) .*/\1/')
# The completion function sets a global "line" of its own: the loop's variable is named apart.
while IFS= read -r parser_path; do
    for word in - ""; do
        read -ra COMP_WORDS <<< "$parser_path"
        COMP_WORDS+=("$word")
        COMP_CWORD=$(( ${#COMP_WORDS[@]} - 1 ))
        COMP_LINE="$parser_path $word"
        COMP_POINT=${#COMP_LINE}
        COMPREPLY=()
        "$fn" "$2" "$word" "${COMP_WORDS[COMP_CWORD-1]}" 2>/dev/null
        printf '%s\t%s\n' "$parser_path" "${COMPREPLY[*]}"
    done
done
"""


@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_bash_completes_every_option_and_subcommand_of_every_parser(
    completion_dir: Path, command: Command
) -> None:
    """In a real bash, completing ``PATH -`` offers every option of the parser at PATH
    (``srcsctl``, ``srcsctl log``, ``srcsctl display row``, ...) and completing an empty word
    after PATH offers its subcommands."""
    parsers = dict(reference.walk(command.build()))
    script = str(completion_dir / command.name)
    result = subprocess.run(
        [BASH, "--norc", "--noprofile", "-c", COMPLETE_EACH_LINE, "-", script, command.name],
        input="".join(f"{path}\n" for path in parsers),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    offered: dict[str, set[str]] = {path: set() for path in parsers}
    for line in result.stdout.splitlines():
        path, _, words = line.partition("\t")
        offered[path] |= set(words.split())
    missing = {
        path: sorted(set(_options(parser, with_help=True) + _subcommands(parser)) - offered[path])
        for path, parser in parsers.items()
    }
    assert {path: gone for path, gone in missing.items() if gone} == {}


@pytest.mark.parametrize("command", COMMANDS, ids=ids)
def test_zsh_completion_names_every_option(completion_dir: Path, command: Command) -> None:
    """The zsh file starts with ``#compdef NAME`` (zsh reads it) and names every option and
    subcommand of every parser (zsh itself is not installed here to run it)."""
    text = (completion_dir / "zsh" / f"_{command.name}").read_text()
    assert text.startswith(f"#compdef {command.name}\n")
    for path, parser in reference.walk(command.build()):
        for word in _options(parser, with_help=True) + _subcommands(parser):
            assert word in text, f"{path} {word}"


def _read_until(fd: int, token: bytes, deadline: float) -> bytes:
    seen = b""
    while token not in seen and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                chunk = os.read(fd, 4096)
            except OSError:  # the shell has gone: its side of the pty is closed
                break
            seen += chunk
    return seen


@pytest.mark.skipif(not BASH_COMPLETION.exists(), reason="needs Debian's bash-completion")
def test_an_interactive_bash_completes_srcsctl_sta_to_status(
    tmp_path: Path, completion_dir: Path
) -> None:
    """An interactive bash on a terminal with bash-completion loaded, the files installed in
    a completions directory under their command's name: typing ``srcsctl sta`` and TAB
    gives ``srcsctl status``, bash-completion finding the file by that name."""
    installed = tmp_path / "bash-completion" / "completions"
    installed.mkdir(parents=True)
    for command in COMMANDS:
        shutil.copy(completion_dir / command.name, installed / command.name)
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": str(tmp_path),
        "TERM": "dumb",
        "INPUTRC": "/dev/null",
        "PS1": "$ ",
        "BASH_COMPLETION_USER_DIR": str(tmp_path / "bash-completion"),
    }
    controller, terminal = pty.openpty()
    shell = subprocess.Popen(
        [BASH, "--norc", "--noprofile", "-i"],
        stdin=terminal,
        stdout=terminal,
        stderr=terminal,
        env=env,
        start_new_session=True,
    )
    os.close(terminal)
    try:
        deadline = time.monotonic() + 30
        os.write(controller, f'source {BASH_COMPLETION} && echo "LOAD""ED"\n'.encode())
        loaded = _read_until(controller, b"LOADED", deadline)
        assert b"LOADED" in loaded
        # The prompt may come in the same read as LOADED: wait only if it has not.
        if b"$ " not in loaded.split(b"LOADED", 1)[1]:
            _read_until(controller, b"$ ", deadline)
        os.write(controller, b"srcsctl sta\t")
        screen = _read_until(controller, b"srcsctl status", deadline)
        assert b"srcsctl status" in screen, screen
    finally:
        os.killpg(shell.pid, signal.SIGKILL)
        shell.wait(10)
        os.close(controller)


COMPLETE_ROBOTS = r"""
source "$1"
fn=$(complete -p srcsctl | sed -E 's/.* -F ([^ ]+) .*/\1/')
while IFS= read -r typed; do
    read -ra COMP_WORDS <<< "$typed"
    [ "${typed: -1}" = " " ] && COMP_WORDS+=("")
    COMP_CWORD=$(( ${#COMP_WORDS[@]} - 1 ))
    COMP_LINE="$typed"
    COMP_POINT=${#COMP_LINE}
    COMPREPLY=()
    "$fn" srcsctl "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD-1]}" 2>/dev/null
    printf '%s\n' "${COMPREPLY[*]}"
done
"""


@pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("unshare") is None, reason="needs root and unshare"
)
def test_bash_completes_robot_names_from_the_installed_configs(
    tmp_path: Path, completion_dir: Path
) -> None:
    """SR-0.2: ``-R``/``--robot`` completes with the robots of ``/etc/srcs/*.toml`` as they
    are when TAB is pressed (a robot added later is offered), at the top level and after a
    command; other files there are not robots. /etc/srcs is given in a mount namespace of the
    test's own (an overlay on /etc that goes away with it): this machine's /etc is untouched."""
    upper, work = tmp_path / "upper", tmp_path / "work"
    (upper / "srcs").mkdir(parents=True)
    work.mkdir()
    for name in ("robot-a.toml", "mower-3.toml", "notes.txt"):
        (upper / "srcs" / name).write_text("")
    mount = f"mount -t overlay overlay -o lowerdir=/etc,upperdir={upper},workdir={work} /etc"
    typed = [
        "srcsctl -R ",
        "srcsctl status --robot ",
        "srcsctl wait-ready -R ro",
        "srcsctl log -R ",
    ]
    bash = [BASH, "--norc", "--noprofile", "-c", COMPLETE_ROBOTS, "-"]
    result = subprocess.run(
        in_private_mount(mount, upper, [*bash, str(completion_dir / "srcsctl")]),
        input="".join(f"{line}\n" for line in typed),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    offered = [sorted(line.split()) for line in result.stdout.splitlines()]
    both = ["mower-3", "robot-a"]
    assert offered == [both, both, ["robot-a"], both], result.stdout
